"""Recorded runs in the field-data format: one folder per scenario.

    <scenario>/scenario.yaml        name, group, duration, initial_pose {x, y, theta}
    <scenario>/steering_inputs.csv  time,velocity,delta_f (the controller's recorded outputs)
    <scenario>/gps_position.csv     time,x,y (recorded fixes; dropouts are missing rows)
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, PositiveFloat, ValidationError

from .errors import DseError

STEERING_FILE = "steering_inputs.csv"
GPS_FILE = "gps_position.csv"
INFO_FILE = "scenario.yaml"

# The scenario fields a multi-model can bind FMU variables to.
ScenarioField = Literal[
    "steering_inputs", "gps_position", "duration",
    "initial_pose.x", "initial_pose.y", "initial_pose.theta",
]


class Pose(BaseModel):
    model_config = ConfigDict(extra="forbid")
    x: float
    y: float
    theta: float


class ScenarioInfo(BaseModel):
    """The contents of scenario.yaml."""

    model_config = ConfigDict(extra="forbid")
    name: str
    group: str
    duration: PositiveFloat
    initial_pose: Pose


@dataclass(frozen=True)
class Track:
    """Recorded GPS fixes: time [s], x [m], y [m]."""

    time: np.ndarray
    x: np.ndarray
    y: np.ndarray


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
        columns = read_csv_columns(self.gps_position, ("time", "x", "y"))
        return Track(*columns)

    @cached_property
    def control_period(self) -> float:
        """The steering log's sampling period: the default communication step."""
        (time,) = read_csv_columns(self.steering_inputs, ("time",))
        steps = np.diff(time)
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


def read_csv_columns(path: Path, names: tuple[str, ...]) -> list[np.ndarray]:
    """Named numeric columns of a headed CSV; errors name the file and line."""
    try:
        lines = path.read_text().splitlines()
    except OSError as e:
        raise DseError(f"cannot read {path}: {e.strerror}") from None
    if not lines:
        raise DseError(f"{path}: the file is empty")
    header = [h.strip() for h in lines[0].split(",")]
    missing = [n for n in names if n not in header]
    if missing:
        raise DseError(f"{path} line 1: no column {', '.join(missing)} (header: {lines[0]!r})")
    index = [header.index(n) for n in names]
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.split(",")
        try:
            if len(fields) != len(header):
                raise ValueError
            rows.append([float(fields[i]) for i in index])
        except ValueError:
            raise DseError(f"{path} line {number}: expected {len(header)} numbers, got {line!r}") from None
    data = np.array(rows, dtype=float).reshape(-1, len(names))
    return [data[:, i].copy() for i in range(len(names))]


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
    except (ValidationError, yaml.YAMLError) as e:
        raise DseError(f"{info_path}: {e}") from None
    return Scenario(directory.resolve(), info)
