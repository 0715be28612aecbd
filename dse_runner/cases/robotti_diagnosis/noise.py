"""The noise floor: how close any model can come to the fixes, estimated from the recordings alone.

A diagnosis that compares held-out error with zero can never tell "explained" from "explained
down to the receiver's noise" and so cannot say honestly when its library falls short. The floor
is measured from the GPS files and the command logs only, never from a model, so it cannot be
tuned by what is being judged. Two estimators, each blind to a different failure:

* **close fixes**: for three consecutive, equally spaced fixes (no dropout between them, at most
  ``MAX_SPACING`` apart), the second difference d2 = p₊ − 2p + p₋ cancels position and speed;
  for white noise its variance is 6σ², and motion adds only a·Δt² (≤ 5 mm at 10 Hz). The median
  absolute deviation pooled over x, y and runs makes it robust to jumps. Coloured noise (a slowly
  wandering fix) is largely cancelled too, so this alone can under-estimate σ;
* **at rest**: where the commanded speed has been 0 long enough, the vehicle stands still (or
  creeps at a steady speed, held on a slope by its drive) and the spread of the fixes about a
  straight line in time *is* the noise, coloured or not. The lag-1 autocorrelation there tells
  how coloured it is. (About their mean instead, a creep counts as noise: in the blind cases on a
  slope the floor came out 6.5 times too high; about a line it is still about twice too high,
  since the creep is not yet steady where a stop begins.)

σ̂ is the larger of the available estimates. Equation 1 is a mean distance, and for isotropic
Gaussian noise of σ per axis the mean distance is σ·√(π/2) ≈ 1.25 σ: that is the floor in
cross-track units, the error a perfect model would still show.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...analysis.diagnose.noise import sigma_from_differences
from ...simulation.scenario import Scenario, read_table
from .. import fielddata

MAX_SPACING = 0.25  # s: fixes further apart than this let motion leak into second differences
SPACING_TOLERANCE = 1e-3  # s: two gaps are "equal" within this (times are logged to the ms or coarser)
REST_MIN_SECONDS = 1.5  # a zero-speed command must last this long to count as a stop
REST_SETTLE_SECONDS = 0.5  # after a moving command, the vehicle needs this long to come to rest
REST_MIN_FIXES = 10  # fewer fixes than this in a stop tell nothing about the spread
MEAN_DISTANCE = math.sqrt(math.pi / 2)  # mean distance / σ for isotropic 2-D Gaussian noise
CLOSE_FIXES, AT_REST, UNAVAILABLE = "close_fixes", "at_rest", "unavailable"


@dataclass(frozen=True)
class Estimate:
    """One estimator's answer: σ per axis [m] from ``fixes`` fixes, and per run where it had data."""

    sigma: float
    fixes: int
    per_run: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class NoiseFloor:
    """The GPS noise of a set of runs and the Equation 1 error it alone causes.

    ``sigma`` is per axis [m]; ``cross_track`` the mean distance it produces [m]; ``method`` the
    estimator that gave the larger σ (the one reported); ``fixes`` how many fixes it used;
    ``per_run`` each run's σ (the larger of its estimates); ``rho1`` the lag-1 autocorrelation of
    the fixes at rest (None without a stop), above about 0.3 the noise is coloured."""

    sigma: float
    cross_track: float
    method: str
    fixes: int
    per_run: dict[str, float] = field(default_factory=dict)
    estimates: dict[str, Estimate] = field(default_factory=dict)
    rho1: float | None = None

    @property
    def available(self) -> bool:
        return self.method != UNAVAILABLE and math.isfinite(self.cross_track) and self.cross_track > 0

    def to_json(self) -> dict[str, Any]:
        return {
            "sigma": self.sigma if self.available else None,
            "cross_track": self.cross_track if self.available else None,
            "method": self.method,
            "fixes": self.fixes,
            "per_run": self.per_run,
            "rho1": self.rho1,
            "estimates": {k: {"sigma": e.sigma, "fixes": e.fixes} for k, e in self.estimates.items()},
        }


UNKNOWN = NoiseFloor(math.nan, math.nan, UNAVAILABLE, 0)


@dataclass(frozen=True)
class RecordedRun:
    """What the estimators need from one recorded run: its fixes and its speed commands."""

    time: np.ndarray  # s, fixes (dropouts already removed)
    x: np.ndarray
    y: np.ndarray
    command_time: np.ndarray  # s, the steering log
    command_speed: np.ndarray  # m/s, the commanded speed, held until the next row


def second_differences(
    time: np.ndarray, x: np.ndarray, y: np.ndarray, max_spacing: float = MAX_SPACING
) -> np.ndarray:
    """d2 of x, then of y, at every fix whose neighbours both lie one nominal period away.

    The nominal period is the median spacing: a triple spanning a dropout has a gap of two
    periods and is skipped, because motion over the longer span would add to d2."""
    time = np.asarray(time, float)
    if time.size < 3:
        return np.empty(0)
    gaps = np.diff(time)
    period = float(np.median(gaps))
    if not 0 < period <= max_spacing:
        return np.empty(0)
    regular = np.abs(gaps - period) <= SPACING_TOLERANCE
    middle = regular[:-1] & regular[1:]  # triple (i, i+1, i+2) around fix i+1
    d2 = [
        p[2:][middle] - 2 * p[1:-1][middle] + p[:-2][middle]
        for p in (np.asarray(x, float), np.asarray(y, float))
    ]
    return np.concatenate(d2)


def sigma_from_second_differences(d2: np.ndarray) -> float:
    """σ per axis from second differences (var d2 = 6σ² for white noise)."""
    return sigma_from_differences(d2, 2)


def rest_windows(
    command_time: np.ndarray,
    command_speed: np.ndarray,
    end: float,
    min_seconds: float = REST_MIN_SECONDS,
    settle: float = REST_SETTLE_SECONDS,
) -> list[tuple[float, float]]:
    """Spans [start, stop) in which the vehicle stands still: the commanded speed is 0 for at least
    ``min_seconds``, counted from ``settle`` after the last moving command (a run starts at rest, so
    a stop at its beginning needs no settling). Commands hold until the next row; the last until ``end``."""
    t = np.asarray(command_time, float)
    still = np.asarray(command_speed, float) == 0
    windows = []
    k = 0
    while k < t.size:
        if not still[k]:
            k += 1
            continue
        first = k
        while k < t.size and still[k]:
            k += 1
        stop = t[k] if k < t.size else end
        start = t[first] if first == 0 else t[first] + settle
        if stop - t[first] >= min_seconds and stop > start:
            windows.append((float(start), float(stop)))
    return windows


def rest_deviations(
    time: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    windows: Iterable[tuple[float, float]],
    min_fixes: int = REST_MIN_FIXES,
) -> list[np.ndarray]:
    """The fixes of each stop with at least ``min_fixes``, about a straight line in time fitted to them
    (position and a steady creep): an (n, 2) array each."""
    time = np.asarray(time, float)
    out = []
    for start, stop in windows:
        inside = (time >= start) & (time < stop)
        if inside.sum() >= min_fixes:
            points = np.column_stack([np.asarray(x, float)[inside], np.asarray(y, float)[inside]])
            design = np.column_stack([np.ones(int(inside.sum())), time[inside] - time[inside].mean()])
            fitted = design @ np.linalg.lstsq(design, points, rcond=None)[0]
            out.append(points - fitted)
    return out


def sigma_at_rest(deviations: list[np.ndarray]) -> float:
    """Pooled within-stop standard deviation per axis (each stop's line costs
    two degrees of freedom an axis)."""
    squares = sum(float(np.sum(d**2)) for d in deviations)
    dof = sum(2 * (len(d) - 2) for d in deviations)
    return math.sqrt(squares / dof) if dof > 0 else math.nan


def lag1_autocorrelation(deviations: list[np.ndarray]) -> float | None:
    """Pooled lag-1 autocorrelation of the fixes at rest: white noise gives about 0."""
    num = sum(float(np.sum(d[1:] * d[:-1])) for d in deviations if len(d) > 1)
    den = sum(float(np.sum(d**2)) for d in deviations)
    return num / den if den > 0 else None


def _end(run: RecordedRun) -> float:
    """Just after the last fix or command: a stop that lasts to the end of the run keeps its last fix."""
    last = [float(a[-1]) for a in (run.time, run.command_time) if a.size]
    return max(last, default=0.0) + 1e-9


def estimate(runs: Mapping[str, RecordedRun]) -> NoiseFloor:
    """The noise floor of ``runs``: each estimator pooled over runs, σ̂ the larger of those available."""
    d2 = {name: second_differences(r.time, r.x, r.y) for name, r in runs.items()}
    rest = {
        name: rest_deviations(r.time, r.x, r.y, rest_windows(r.command_time, r.command_speed, _end(r)))
        for name, r in runs.items()
    }
    pooled = np.concatenate([v for v in d2.values()]) if d2 else np.empty(0)
    estimates: dict[str, Estimate] = {}
    if pooled.size:
        estimates[CLOSE_FIXES] = Estimate(
            sigma_from_second_differences(pooled),
            pooled.size // 2,
            {n: sigma_from_second_differences(v) for n, v in d2.items() if v.size},
        )
    all_rest = [d for stops in rest.values() for d in stops]
    if all_rest:
        estimates[AT_REST] = Estimate(
            sigma_at_rest(all_rest),
            sum(len(d) for d in all_rest),
            {n: sigma_at_rest(v) for n, v in rest.items() if v},
        )
    usable = {k: e for k, e in estimates.items() if math.isfinite(e.sigma) and e.sigma > 0}
    if not usable:
        return NoiseFloor(math.nan, math.nan, UNAVAILABLE, 0, estimates=estimates)
    method = max(usable, key=lambda k: usable[k].sigma)
    per_run = {
        n: max(e.per_run[n] for e in usable.values() if n in e.per_run)
        for n in runs
        if any(n in e.per_run for e in usable.values())
    }
    sigma = usable[method].sigma
    return NoiseFloor(
        sigma,
        sigma * MEAN_DISTANCE,
        method,
        usable[method].fixes,
        per_run,
        estimates,
        lag1_autocorrelation(all_rest),
    )


def run_of(scenario: Scenario) -> RecordedRun:
    """A field-data run's fixes and speed commands (its steering log's ``velocity`` column)."""
    track = fielddata.gps(scenario)
    log = read_table(scenario.files["steering_inputs"], ("time", "velocity"))
    return RecordedRun(track.time, track.x, track.y, log.columns[0], log.columns[1])


def estimate_noise(scenarios: Iterable[Scenario]) -> NoiseFloor:
    """The noise floor of recorded field-data runs, from their GPS files and command logs only."""
    return estimate({s.name: run_of(s) for s in scenarios})
