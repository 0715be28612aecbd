"""Kinematics: the vehicle's speed, course, yaw rate and acceleration, estimated from its GPS fixes alone.

Differencing fixes amplifies their noise and breaks at every dropout, and interpolating across
an outage invents motion. Instead each quantity is a weighted least-squares polynomial fitted to
the fixes in a window around each fix, on their real (irregular) times, with tricube weights: a
straight line over ``VELOCITY_WINDOW`` for velocity, a parabola over ``ACCELERATION_WINDOW`` for
acceleration. A window must hold at least ``MIN_SHARE`` of the fixes it would hold without
dropouts and ``MIN_SIDE`` on each side of its centre, otherwise the estimate there is NaN: an
outage splits a run into separate stretches rather than being bridged.

Every estimate is a linear operator on the fixes (:func:`derivative_operator`), so the same smoothing
can be applied to a model's signal (:func:`smoothed_like`): a recorded yaw rate is then compared
with a model's yaw rate seen through the same window, and neither is sharper than the other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.integrate import cumulative_trapezoid

VELOCITY_WINDOW = 1.0  # s, a straight line: speed and course
ACCELERATION_WINDOW = 2.0  # s, a parabola: acceleration, hence yaw rate
MIN_SHARE = 0.6  # of the fixes a window would hold without dropouts
MIN_SIDE = 3  # fixes on each side of the window's centre
MIN_SPEED = 0.8  # m/s: below this the course, and the yaw rate from it, is mostly noise


def tricube(u: np.ndarray) -> np.ndarray:
    """(1 − |u|³)³ on |u| < 1: smooth weights that fall to zero at the window's edge."""
    return np.clip(1.0 - np.abs(u) ** 3, 0.0, None) ** 3


def derivative_operator(time: np.ndarray, window: float, degree: int, order: int) -> np.ndarray:
    """The matrix D (n, n): D @ values is the ``order``-th derivative at each fix of the weighted
    polynomial of ``degree`` fitted over ``window`` seconds centred there. Rows are NaN where the window
    has too few fixes (``MIN_SHARE``, ``MIN_SIDE``). The windows' fits are made once per run's fix times
    and kept (:func:`_windows`): a diagnosis asks for the same runs' operators at every reference point
    it observes, and the fits, one small solve per fix, cost far more than laying them out."""
    time = np.asarray(time, float)
    n = time.size
    out = np.full((n, n), np.nan)
    for i, start, coefficients in _windows(time.tobytes(), window, degree):
        out[i, :] = 0.0
        out[i, start : start + coefficients.shape[1]] = coefficients[order]
    return out


@lru_cache(maxsize=64)
def _windows(fix_times: bytes, window: float, degree: int) -> tuple[tuple[int, int, np.ndarray], ...]:
    """Per fix whose window holds enough fixes: (its row, the window's first fix, the (degree + 1, m)
    coefficients that give each derivative there from the window's m values). Kept by the fix times' bytes:
    a run's are some kilobytes, and its windows' coefficients a few dozen numbers per fix."""
    time = np.frombuffer(fix_times, float)
    n = time.size
    if n < 2 * MIN_SIDE + 1:
        return ()
    period = float(np.median(np.diff(time)))
    expected = window / period if period > 0 else math.inf
    half = window / 2
    lo = np.searchsorted(time, time - half, side="left")
    hi = np.searchsorted(time, time + half, side="right")
    factorial = np.array([math.factorial(k) for k in range(degree + 1)], float)
    scale = factorial / half ** np.arange(degree + 1)
    out = []
    for i in range(n):
        dt = time[lo[i] : hi[i]] - time[i]
        before, after = int(np.sum(dt < 0)), int(np.sum(dt > 0))
        if dt.size < MIN_SHARE * expected or before < MIN_SIDE or after < MIN_SIDE:
            continue
        w = tricube(dt / (half * (1 + 1e-9)))
        design = np.vander(dt / half, degree + 1, increasing=True)  # scaled for conditioning
        weighted = design * w[:, None]
        hat = np.linalg.solve(design.T @ weighted, weighted.T)  # (degree + 1, m): coefficients per value
        coefficients = hat * scale[:, None]
        coefficients.setflags(write=False)
        out.append((i, int(lo[i]), coefficients))
    return tuple(out)


@dataclass(frozen=True)
class Kinematics:
    """Estimates at each fix time; NaN where a window is too thin. ``yaw_rate`` is also NaN below
    ``MIN_SPEED``."""

    time: np.ndarray
    speed: np.ndarray  # m/s
    course: np.ndarray  # rad, direction of travel (of the antenna), unwrapped
    yaw_rate: np.ndarray  # rad/s, rate of change of the course
    acceleration: np.ndarray  # m/s², along the direction of travel


def gps_kinematics(time: np.ndarray, x: np.ndarray, y: np.ndarray) -> Kinematics:
    """Speed, course, yaw rate r = (ẋÿ − ẏẍ)/v² and acceleration a = (ẋẍ + ẏÿ)/v from fixes."""
    time, x, y = (np.asarray(a, float) for a in (time, x, y))
    velocity = derivative_operator(time, VELOCITY_WINDOW, 1, 1)
    second = derivative_operator(time, ACCELERATION_WINDOW, 2, 2)
    vx, vy = velocity @ x, velocity @ y
    ax, ay = second @ x, second @ y
    speed = np.hypot(vx, vy)
    course = np.arctan2(vy, vx)
    finite = np.isfinite(course)
    if finite.any():
        course[finite] = np.unwrap(course[finite])
    with np.errstate(invalid="ignore", divide="ignore"):
        yaw_rate = np.where(speed >= MIN_SPEED, (vx * ay - vy * ax) / speed**2, np.nan)
        acceleration = np.where(speed > 0, (vx * ax + vy * ay) / speed, np.nan)
    return Kinematics(time, speed, course, yaw_rate, acceleration)


def smoothed_like(
    operator: np.ndarray, order: int, time: np.ndarray, signal: np.ndarray, at: np.ndarray
) -> np.ndarray:
    """A model's ``signal`` (on its own ``time`` grid) seen as GPS would see it: integrated ``order``
    times, sampled at the fix times ``at`` and differentiated back by ``operator`` (the
    :func:`derivative_operator` of that order). Speed is order 1 (from positions by the velocity
    operator), yaw rate order 2 (from positions by the acceleration operator)."""
    values = np.asarray(signal, float)
    for _ in range(order):
        values = cumulative_trapezoid(values, time, initial=0.0)
    return operator @ np.interp(at, time, values)
