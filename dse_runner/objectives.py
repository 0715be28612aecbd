"""Objectives: how far a simulated track is from the recorded GPS fixes.

Every objective is a function ``(trajectory, scenario) -> float``. The
built-in ones all start from the same distances: for each recorded fix, the
Euclidean distance to the simulated position at the fix's time, linearly
interpolated between communication points. The paper's Equation 1 (its
"mean cross-track error") is their mean. Users add their own objectives by
import path, ``"package.module:function"``, with the same signature.

A vector objective returns one number per fix instead: ``fix_residuals``
keeps what least-squares fitting (fit.py) needs, and is stored as a list
column; rankings use only scalar objectives.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

import numpy as np

from .cosim import Trajectory
from .errors import DseError
from .scenario import Scenario

Objective = Callable[[Trajectory, Scenario], float]


def fix_offsets(trajectory: Trajectory, scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """Simulated minus recorded x and y at each GPS fix within the simulated time span."""
    gps = scenario.gps
    x, y = trajectory.xy()
    time = trajectory.time
    inside = (gps.time >= time[0]) & (gps.time <= time[-1] + 1e-9)
    if not inside.any():
        raise DseError(f"scenario {scenario.name}: no GPS fix lies within the simulated time "
                       f"{time[0]:g}..{time[-1]:g} s")
    t = gps.time[inside]
    return np.interp(t, time, x) - gps.x[inside], np.interp(t, time, y) - gps.y[inside]


def fix_distances(trajectory: Trajectory, scenario: Scenario) -> np.ndarray:
    """Distance from each GPS fix within the simulated time span to the simulated position."""
    return np.hypot(*fix_offsets(trajectory, scenario))


def fix_residuals(trajectory: Trajectory, scenario: Scenario) -> np.ndarray:
    """The x offsets of every fix, then the y offsets [m]: a vector objective."""
    return np.concatenate(fix_offsets(trajectory, scenario))


def cross_track_error(trajectory: Trajectory, scenario: Scenario) -> float:
    """The paper's Equation 1: mean distance over the recorded fixes [m]."""
    return float(np.mean(fix_distances(trajectory, scenario)))


def max_error(trajectory: Trajectory, scenario: Scenario) -> float:
    """Largest distance to any fix [m]."""
    return float(np.max(fix_distances(trajectory, scenario)))


def rms_error(trajectory: Trajectory, scenario: Scenario) -> float:
    """Root mean square of the distances [m]."""
    return float(np.sqrt(np.mean(fix_distances(trajectory, scenario) ** 2)))


def final_error(trajectory: Trajectory, scenario: Scenario) -> float:
    """Distance at the last recorded fix [m]."""
    return float(fix_distances(trajectory, scenario)[-1])


BUILTIN: dict[str, Objective] = {
    "cross_track_error": cross_track_error,
    "max_error": max_error,
    "rms_error": rms_error,
    "final_error": final_error,
}
DEFAULT = tuple(BUILTIN)
VECTOR: dict[str, Objective] = {"fix_residuals": fix_residuals}


def is_vector(name: str) -> bool:
    return name in VECTOR


def resolve(name: str) -> Objective:
    """A built-in objective's name, or ``module:function`` for a user's own."""
    if name in BUILTIN or name in VECTOR:
        return BUILTIN.get(name) or VECTOR[name]
    module_name, colon, function_name = name.partition(":")
    if not colon:
        raise DseError(f"unknown objective {name!r}: use one of {', '.join([*BUILTIN, *VECTOR])} "
                       "or an import path 'module:function'")
    try:
        module = importlib.import_module(module_name)
    except ImportError as e:
        raise DseError(f"objective {name!r}: cannot import {module_name!r}: {e}") from None
    function = getattr(module, function_name, None)
    if not callable(function):
        raise DseError(f"objective {name!r}: {module_name} has no function {function_name!r}")
    return function


def evaluate(names: tuple[str, ...], trajectory: Trajectory, scenario: Scenario) -> dict[str, float | list[float]]:
    """Every objective's value; a value that is not a finite number is an error naming the objective,
    so a NaN never reaches a result row with an ok status."""
    results: dict[str, float | list[float]] = {}
    for name in names:
        value = resolve(name)(trajectory, scenario)
        try:
            number = np.asarray(value, dtype=float) if is_vector(name) else float(value)
        except (TypeError, ValueError):
            raise DseError(f"objective {name!r} returned {value!r}, not a number") from None
        if not np.all(np.isfinite(number)):
            raise DseError(f"objective {name!r} is not a finite number on scenario {scenario.name} "
                           f"({value!r:.80})")
        results[name] = number.tolist() if is_vector(name) else number
    return results
