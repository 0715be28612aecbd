"""The field-data scenario kind: recorded runs as the paper's robots log them, and the GPS objectives.

One folder per run (docs/robotti-model.md)::

    <run>/scenario.yaml        name, group, duration, initial_pose {x, y, theta}
    <run>/steering_inputs.csv  time,velocity,delta_f (the controller's recorded outputs)
    <run>/gps_position.csv     time,x,y (recorded fixes; dropouts are missing rows)

It becomes a general :class:`~dse_runner.simulation.scenario.Scenario`: the stop time is
the duration, the natural step is the steering log's period, the recording is
the GPS fixes (columns ``x`` and ``y``), and the fields a multi-model binds
are ``steering_inputs`` and ``gps_position`` (files) and ``duration`` and
``initial_pose.x|y|theta``. A GPS fix whose x or y is empty or NaN is a
dropout, skipped like a missing row and counted (docs/recordings.md).

The objectives compare the simulated position with the fixes: for each fix,
the distance to the simulated position at the fix's time, interpolated
linearly between communication points. Their mean is the paper's Equation 1.
The simulated position is the outputs named by the scenario option
``position: {x: vehicle.x, y: vehicle.y}``, or else the only instance with
outputs ``x`` and ``y``.

This module is a plug-in: pyproject.toml registers the kind in the
entry-point group ``dse_runner.scenarios`` and the objectives in
``dse_runner.objectives``. The core never imports it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict

from ..errors import DseError
from ..simulation.scenario import INFO_FILE, Recording, Scenario, read_table
from ..simulation.variables import split_ref
from ..yamlfile import read_yaml
from .runinfo import XY, Position, RunInfo, TrackKind, open_folder

STEERING_FILE = "steering_inputs.csv"
GPS_FILE = "gps_position.csv"
KIND = "field_data"


class FieldDataOptions(BaseModel):
    """What a space may say about field-data scenarios: ``{path: runs/*, position: {x: .., y: ..}}``."""

    model_config = ConfigDict(extra="forbid")
    position: Position | None = None


@dataclass(frozen=True)
class Track:
    """Recorded GPS fixes: time [s], x [m], y [m]; ``dropouts`` fixes were skipped (empty or NaN)."""

    time: np.ndarray
    x: np.ndarray
    y: np.ndarray
    dropouts: int = 0


def gps(scenario: Scenario) -> Track:
    """The GPS fixes of a field-data scenario."""
    if scenario.kind != KIND or scenario.recorded is None:
        raise DseError(
            f"scenario {scenario.name} is a {scenario.kind} scenario, not recorded field data with GPS fixes"
        )
    recorded = scenario.recorded
    return Track(recorded.time, recorded.columns["x"], recorded.columns["y"], recorded.missing)


def _control_period(path: Path, time: np.ndarray) -> float:
    steps = np.diff(time)
    if steps.size == 0:
        raise DseError(f"{path}: needs at least two rows to tell its period")
    return float(f"{np.median(steps):.12g}")  # 0.05, not 0.04999999999999982


def read_info(path: Path) -> RunInfo:
    return read_yaml(path, RunInfo, "scenario file")


def load_run(folder: str | Path, options: Mapping[str, Any] | None = None) -> Scenario:
    """Read and check a run's three files (both recordings now, before any FMU reads them)."""
    paths, settings = open_folder(folder, (INFO_FILE, STEERING_FILE, GPS_FILE), options, FieldDataOptions)
    info = read_info(paths[INFO_FILE])
    log = read_table(paths[STEERING_FILE], ("time", "velocity", "delta_f"))
    fixes = read_table(paths[GPS_FILE], ("time", "x", "y"), may_drop=("x", "y"))
    if not fixes.columns[0].size:
        raise DseError(f"{paths[GPS_FILE]}: no GPS fix (every row is empty or a dropout)")
    recorded = Recording(
        paths[GPS_FILE], fixes.columns[0], {"x": fixes.columns[1], "y": fixes.columns[2]}, len(fixes.dropped)
    )
    return Scenario(
        name=info.name,
        group=info.group,
        kind=KIND,
        fields=info.fields,
        files={"steering_inputs": paths[STEERING_FILE], "gps_position": paths[GPS_FILE]},
        recorded=recorded,
        start_time=0.0,
        stop_time=info.duration,
        natural_step=_control_period(paths[STEERING_FILE], log.columns[0]),
        sources=tuple(paths.values()),
        options=settings.model_dump(exclude_none=True),
    )


class FieldData(TrackKind):
    """The kind, as ``dse_runner.simulation.scenario`` finds it."""

    name = KIND
    default_objectives = ("cross_track_error", "max_error", "rms_error", "final_error")
    reference_style = (".", {"ms": 2.5, "color": "0.45", "label": "recorded GPS"})
    title_error = ("cross_track_error", "mean cross-track error")

    def detect(self, folder: Path) -> bool:
        """Either recording, or a scenario.yaml with an initial pose and no CSV at all: then a missing
        file is named. A folder with other CSVs beside such a scenario.yaml is another kind's."""
        if (folder / STEERING_FILE).is_file() or (folder / GPS_FILE).is_file():
            return True
        if any(folder.glob("*.csv")):
            return False
        try:
            info = yaml.safe_load((folder / INFO_FILE).read_text())
        except (OSError, yaml.YAMLError):
            return False
        return isinstance(info, dict) and "initial_pose" in info

    def load(self, folder: Path, options: Mapping[str, Any] | None = None) -> Scenario:
        return load_run(folder, options)

    def tracks(self, result) -> tuple[XY, XY]:
        fixes = gps(result.scenario)
        return (fixes.x, fixes.y), simulated_xy(result.trajectory, result.scenario)


FIELD_DATA = FieldData()


# ---- objectives --------------------------------------------------------------------------------


def position_of(names, scenario: Scenario) -> tuple[str, str]:
    """The simulated position among recorded ``names``: the scenario's ``position`` option, or the
    only instance with outputs x and y."""
    given = scenario.options.get("position")
    if given:
        return given["x"], given["y"]
    names = set(names)
    instances = {split_ref(n)[0] for n in names if "." in n}
    candidates = [i for i in sorted(instances) if {f"{i}.x", f"{i}.y"} <= names]
    if len(candidates) != 1:
        found = f"instances {', '.join(candidates)} have both" if candidates else "no instance has both"
        raise DseError(
            f"scenario {scenario.name}: which outputs are the position compared with GPS? {found} "
            "x and y outputs; say it in space.yaml: scenarios: [{path: ..., position: {x: .., y: ..}}]"
        )
    return f"{candidates[0]}.x", f"{candidates[0]}.y"


def fix_offsets(trajectory, scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """Simulated minus recorded x and y at each GPS fix within the simulated time span."""
    fixes = gps(scenario)
    x_ref, y_ref = position_of(trajectory.names, scenario)
    x, y = trajectory.column(x_ref), trajectory.column(y_ref)
    time = trajectory.time
    inside = (fixes.time >= time[0]) & (fixes.time <= time[-1] + 1e-9)
    inside &= np.isfinite(fixes.x) & np.isfinite(fixes.y)  # a dropout (a validation view's held-out fix)
    if not inside.any():
        raise DseError(
            f"scenario {scenario.name}: no GPS fix lies within the simulated time {time[0]:g}..{time[-1]:g} s"
        )
    t = fixes.time[inside]
    return np.interp(t, time, x) - fixes.x[inside], np.interp(t, time, y) - fixes.y[inside]


def simulated_xy(trajectory, scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """The simulated position over the whole run, for plots."""
    x_ref, y_ref = position_of(trajectory.names, scenario)
    return trajectory.column(x_ref), trajectory.column(y_ref)


def fix_distances(trajectory, scenario: Scenario) -> np.ndarray:
    """Distance from each GPS fix within the simulated time span to the simulated position."""
    return np.hypot(*fix_offsets(trajectory, scenario))


def fix_residuals(trajectory, scenario: Scenario) -> np.ndarray:
    """The x offsets of every fix, then the y offsets [m]: a vector objective (least-squares fits)."""
    return np.concatenate(fix_offsets(trajectory, scenario))


fix_residuals.vector = True  # one number per fix, stored as a list; rankings cannot use it


def cross_track_error(trajectory, scenario: Scenario) -> float:
    """The paper's Equation 1: mean distance over the recorded fixes [m]."""
    return float(np.mean(fix_distances(trajectory, scenario)))


def max_error(trajectory, scenario: Scenario) -> float:
    """Largest distance to any fix [m]."""
    return float(np.max(fix_distances(trajectory, scenario)))


def rms_error(trajectory, scenario: Scenario) -> float:
    """Root mean square of the distances [m]."""
    return float(np.sqrt(np.mean(fix_distances(trajectory, scenario) ** 2)))


def final_error(trajectory, scenario: Scenario) -> float:
    """Distance at the last recorded fix [m]."""
    return float(fix_distances(trajectory, scenario)[-1])
