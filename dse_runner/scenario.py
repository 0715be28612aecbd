"""Recorded runs in the field-data format: one folder per scenario.

    <scenario>/scenario.yaml        name, group, duration, initial_pose {x, y, theta}
    <scenario>/steering_inputs.csv  time,velocity,delta_f (the controller's recorded outputs)
    <scenario>/gps_position.csv     time,x,y (recorded fixes; dropouts are missing rows)

Recordings are never silently wrong (docs/recordings.md): every value must be
a finite number, except that a GPS fix whose x or y is empty or NaN is a
*dropout*, skipped like a missing row and counted. Anything else (text, an
infinite value, a missing time, a time that does not increase) is an error
naming the file, the line and the column. Both files are checked when the
scenario is loaded, before any FMU reads them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, PositiveFloat, ValidationError

from .errors import DseError, format_syntax_error, format_validation_error

STEERING_FILE = "steering_inputs.csv"
GPS_FILE = "gps_position.csv"
INFO_FILE = "scenario.yaml"

# The scenario fields a multi-model can bind FMU variables to.
ScenarioField = Literal[
    "steering_inputs", "gps_position", "duration",
    "initial_pose.x", "initial_pose.y", "initial_pose.theta",
]


Finite = ConfigDict(extra="forbid", allow_inf_nan=False)


class Pose(BaseModel):
    model_config = Finite
    x: float
    y: float
    theta: float


class ScenarioInfo(BaseModel):
    """The contents of scenario.yaml."""

    model_config = Finite
    name: str
    group: str
    duration: PositiveFloat
    initial_pose: Pose


@dataclass(frozen=True)
class Track:
    """Recorded GPS fixes: time [s], x [m], y [m]; ``dropouts`` fixes were skipped (empty or NaN)."""

    time: np.ndarray
    x: np.ndarray
    y: np.ndarray
    dropouts: int = 0


@dataclass(frozen=True)
class Scenario:
    directory: Path
    info: ScenarioInfo

    @property
    def name(self) -> str:
        return self.info.name

    @property
    def group(self) -> str:
        return self.info.group

    @property
    def steering_inputs(self) -> Path:
        return self.directory / STEERING_FILE

    @property
    def gps_position(self) -> Path:
        return self.directory / GPS_FILE

    @cached_property
    def gps(self) -> Track:
        table = read_table(self.gps_position, ("time", "x", "y"), may_drop=("x", "y"))
        if not table.columns[0].size:
            raise DseError(f"{self.gps_position}: no GPS fix (every row is empty or a dropout)")
        return Track(*table.columns, dropouts=len(table.dropped))

    @cached_property
    def steering(self) -> list[np.ndarray]:
        """The steering log's time, velocity and delta_f columns, every value checked."""
        return read_table(self.steering_inputs, ("time", "velocity", "delta_f")).columns

    @cached_property
    def control_period(self) -> float:
        """The steering log's sampling period: the default communication step."""
        steps = np.diff(self.steering[0])
        if steps.size == 0:
            raise DseError(f"{self.steering_inputs}: needs at least two rows to tell its period")
        return float(f"{np.median(steps):.12g}")  # 0.05, not 0.04999999999999982

    def value_of(self, name: ScenarioField) -> float | str:
        """The value a multi-model binds to an FMU variable."""
        if name == "steering_inputs":
            return str(self.steering_inputs)
        if name == "gps_position":
            return str(self.gps_position)
        if name == "duration":
            return self.info.duration
        return getattr(self.info.initial_pose, name.removeprefix("initial_pose."))


@dataclass(frozen=True)
class Table:
    """Named columns read from a recording, and the lines skipped as dropouts."""

    columns: list[np.ndarray]
    dropped: list[int]


def is_dropout_text(text: str) -> bool:
    """How a missing measurement is written: nothing, or NaN in any case and sign (printf writes -nan)."""
    return text == "" or text.lstrip("+-").lower() == "nan"


def read_table(path: Path, names: tuple[str, ...], may_drop: tuple[str, ...] = ()) -> Table:
    """Named numeric columns of a headed CSV whose first column is time.

    Every value must be a finite number; a row where a ``may_drop`` column is empty or NaN is
    skipped and its line counted as a dropout (its time, and its other ``may_drop`` values unless
    they are missing too, are still checked). Errors name the file, the line and the column."""
    try:
        lines = path.read_text().splitlines()
    except OSError as e:
        raise DseError(f"cannot read {path}: {e.strerror}") from None
    except UnicodeDecodeError:
        raise DseError(f"{path}: not a text file") from None
    if not lines:
        raise DseError(f"{path}: the file is empty")
    header = [h.strip() for h in lines[0].split(",")]
    missing = [n for n in names if n not in header]
    if missing:
        raise DseError(f"{path} line 1: no column {', '.join(missing)} (header: {lines[0]!r})")
    index = [header.index(n) for n in names]
    rows, times, dropped = [], [], []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.split(",")
        if len(fields) != len(header):
            raise DseError(f"{path} line {number}: expected {len(header)} fields, got {line!r}")
        texts = {name: fields[i].strip() for name, i in zip(names, index)}
        gaps = {n for n in may_drop if is_dropout_text(texts[n])}
        values = [math.nan if name in gaps else _number(path, number, name, text) for name, text in texts.items()]
        times.append((values[0], number))
        if gaps:
            dropped.append(number)
        else:
            rows.append(values)
    _check_increasing(path, names[0], times)
    data = np.array(rows, dtype=float).reshape(-1, len(names))
    return Table([data[:, i].copy() for i in range(len(names))], dropped)


def _number(path: Path, line: int, column: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is None or not np.isfinite(value):
        what = "is empty" if not text else f"{text!r} is not a finite number"
        raise DseError(f"{path} line {line}, column {column}: {what}")
    return value


def _check_increasing(path: Path, column: str, times: list[tuple[float, int]]) -> None:
    """Times (of every row, dropouts included) must increase: interpolation and the step loop rely on it."""
    for (previous, _), (time, line) in zip(times, times[1:]):
        if not time > previous:
            raise DseError(f"{path} line {line}, column {column}: {time:g} does not increase on the "
                           f"previous row's {previous:g}")


def dropouts(scenarios: list[Scenario]) -> dict[str, int]:
    """GPS fixes skipped as dropouts, per scenario that has any: what the commands report."""
    return {s.name: s.gps.dropouts for s in scenarios if s.gps.dropouts}


def load_scenario(directory: str | Path) -> Scenario:
    directory = Path(directory)
    info_path = directory / INFO_FILE
    if not directory.is_dir():
        raise DseError(f"scenario folder not found: {directory}")
    for required in (info_path, directory / STEERING_FILE, directory / GPS_FILE):
        if not required.is_file():
            raise DseError(f"scenario {directory}: missing {required.name}")
    try:
        info = ScenarioInfo.model_validate(yaml.safe_load(info_path.read_text()))
    except ValidationError as e:
        raise DseError(format_validation_error(str(info_path), e)) from None
    except yaml.YAMLError as e:
        raise DseError(format_syntax_error(str(info_path), "YAML", e)) from None
    scenario = Scenario(directory.resolve(), info)
    scenario.steering, scenario.gps  # read and check both recordings now, before any FMU reads them
    return scenario
