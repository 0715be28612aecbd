"""The path scenario kind: a reference path for a closed-loop controller to follow, and objectives
that score how well the vehicle followed it (docs/paths.md).

One folder per path::

    <path>/scenario.yaml   name, group, duration [s], initial_pose {x, y, theta}, optional step_at [m]
    <path>/path.csv        x,y,speed: waypoints in order [m, m, m/s]; the path is the polyline through them

It becomes a general :class:`~dse_runner.simulation.scenario.Scenario`: the stop time is the
duration, and the fields a multi-model binds are ``path`` (the CSV, which the controller reads),
``duration``, ``initial_pose.x|y|theta``, ``target_speed`` (the largest target speed) and, where
given, ``step_at``. There is no recording: the objectives compare the simulated pose with the path
itself, not with measurements.

Each sample of the simulated position is matched with its closest point on the path, searched
only from the previous sample's closest point onwards, up to LOOKAHEAD metres of path beyond it
(plus the distance the vehicle moved): progress along the path never goes back, so the error on
the way out of a U-turn is never measured to the way back, and the cost is that of a short window
per sample, computed for a block of samples at a time with numpy.

The simulated pose is the outputs named by the scenario options ``position: {x: .., y: ..}`` and
``heading: ..`` (default: the position's instance's ``theta``), or else the only instance with
outputs ``x``, ``y`` and ``theta``; the steering angle is the option ``steering: ..``, or else the
only output named ``delta_f``.

This module is a plug-in: pyproject.toml registers the kind in the entry-point group
``dse_runner.scenarios`` and the objectives in ``dse_runner.objectives``. The core never imports it.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, NonNegativeFloat

from ..errors import DseError
from ..simulation.scenario import INFO_FILE, Scenario, read_table
from ..simulation.variables import split_ref
from ..yamlfile import read_yaml
from .runinfo import XY, Position, RunInfo, TrackKind, open_folder

PATH_FILE = "path.csv"
KIND = "path"
LOOKAHEAD = 5.0  # m of path searched beyond the previous closest point (plus the distance moved)
MAX_BLOCK = 512  # samples matched in one numpy block at most
PARALLEL = math.cos(math.radians(1.0))  # a lateral step's new line is parallel to the old within 1 degree ...
MAX_JUMP = 5.0  # ... and starts within 5 m of path after step_at ...
MIN_OFFSET = 0.01  # ... and lies more than 1 cm to the side
SETTLE_FRACTION = 0.1  # settled: within 10% of the step size of the new line


class PathInfo(RunInfo):
    """The contents of a path's scenario.yaml: a run's, and where a lateral step starts."""

    name: str = Field(pattern=r"^[A-Za-z0-9_.-]+$")
    step_at: NonNegativeFloat | None = None  # arc length [m] where a lateral step starts


class PathOptions(BaseModel):
    """What a space may say about path scenarios: ``{path: paths/*, position: {x, y}, heading, steering}``."""

    model_config = ConfigDict(extra="forbid")
    position: Position | None = None
    heading: str | None = None
    steering: str | None = None


# ---- the path ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Polyline:
    """A path as the objectives use it: waypoints, their target speeds and arc lengths."""

    points: np.ndarray  # (n, 2) x, y [m]
    speed: np.ndarray  # (n,) target speed [m/s]
    arc: np.ndarray  # (n,) arc length from the first waypoint [m], strictly increasing
    direction: np.ndarray  # (n - 1, 2) unit vector of each segment

    @property
    def length(self) -> float:
        return float(self.arc[-1])

    @property
    def heading(self) -> np.ndarray:
        """Each segment's direction [rad], counter-clockwise from the x axis (as theta is)."""
        return np.arctan2(self.direction[:, 1], self.direction[:, 0])

    def point_at(self, arc: float) -> np.ndarray:
        return np.array(
            [np.interp(arc, self.arc, self.points[:, 0]), np.interp(arc, self.arc, self.points[:, 1])]
        )


def read_path(path: Path) -> Polyline:
    """Read and check a path.csv: finite numbers, at least two waypoints, no waypoint repeated
    (a segment of length 0 has no direction), no negative speed, some speed above 0."""
    table = read_table(path, ("x", "y", "speed"), ordered=False)
    x, y, speed = table.columns
    if x.size < 2:
        raise DseError(f"{path}: a path needs at least 2 waypoints, it has {x.size}")
    negative = np.flatnonzero(speed < 0)
    if negative.size:
        k = negative[0]
        raise DseError(
            f"{path} line {table.lines[k]}, column speed: {speed[k]:g} is negative "
            "(a target speed is at least 0)"
        )
    if not np.any(speed > 0):
        raise DseError(f"{path}: every target speed is 0, so the path is never driven")
    points = np.column_stack([x, y])
    steps = np.diff(points, axis=0)
    lengths = np.hypot(steps[:, 0], steps[:, 1])
    repeated = np.flatnonzero(lengths == 0)
    if repeated.size:
        k = repeated[0] + 1
        raise DseError(
            f"{path} line {table.lines[k]}: waypoint ({x[k]:g}, {y[k]:g}) repeats the previous one"
        )
    return Polyline(points, speed, np.concatenate([[0.0], np.cumsum(lengths)]), steps / lengths[:, None])


def polyline(path: Path) -> Polyline:
    """A path file, read once per process while it is unchanged (every objective of a run reads it)."""
    stat = Path(path).stat()
    return _read_cached(str(path), stat.st_mtime_ns, stat.st_size)


@lru_cache(maxsize=16)
def _read_cached(path: str, mtime_ns: int, size: int) -> Polyline:
    return read_path(Path(path))


@dataclass(frozen=True)
class Step:
    """A lateral step: the row before ``at`` continues as a parallel line ``size`` metres to its side."""

    at: float  # arc length where the old line ends [m]
    origin: np.ndarray  # the path point at ``at``
    direction: np.ndarray  # unit vector along both lines
    size: float  # offset of the new line from the old one [m], positive to the left
    end: float  # distance along the row from ``origin`` to the path's last waypoint [m]

    def along(self, xy: np.ndarray) -> np.ndarray:
        """Distance along the row past the step [m]."""
        return (xy - self.origin) @ self.direction

    def lateral(self, xy: np.ndarray) -> np.ndarray:
        """Signed offset from the new line [m], positive to its left."""
        rel = xy - self.origin
        return self.direction[0] * rel[:, 1] - self.direction[1] * rel[:, 0] - self.size


def lateral_step(path: Polyline, at: float, where: str) -> Step:
    """The step at arc length ``at``: the new line is the first segment starting within MAX_JUMP of
    path after ``at`` that is parallel to the segment before ``at`` and offset from it."""
    if not 0 < at < path.length:
        raise DseError(f"{where}: step_at: {at:g} m is not inside the path (0 to {path.length:g} m)")
    segment = min(max(int(np.searchsorted(path.arc, at, "left")) - 1, 0), len(path.direction) - 1)
    before = path.direction[segment]
    origin = path.point_at(at)
    later = np.flatnonzero((path.arc[:-1] >= at) & (path.arc[:-1] <= at + MAX_JUMP))
    rel = path.points[later] - origin
    offsets = before[0] * rel[:, 1] - before[1] * rel[:, 0]
    parallel = (path.direction[later] @ before >= PARALLEL) & (np.abs(offsets) > MIN_OFFSET)
    if not parallel.any():
        raise DseError(
            f"{where}: step_at: no straight piece parallel to the row before {at:g} m and offset "
            f"from it starts within {MAX_JUMP:g} m of path after it"
        )
    size = float(offsets[np.argmax(parallel)])
    return Step(at, origin, before, size, float((path.points[-1] - origin) @ before))


# ---- the kind ----------------------------------------------------------------------------------


def read_info(path: Path) -> PathInfo:
    return read_yaml(path, PathInfo, "scenario file")


def load_path(folder: str | Path, options: Mapping[str, Any] | None = None) -> Scenario:
    """Read and check a path folder (the path and any step now, before any FMU reads the file)."""
    files, settings = open_folder(folder, (INFO_FILE, PATH_FILE), options, PathOptions)
    info_file, path_file = files[INFO_FILE], files[PATH_FILE]
    info = read_info(info_file)
    path = read_path(path_file)
    step = {}
    if info.step_at is not None:
        lateral_step(path, info.step_at, str(info_file))
        step = {"step_at": info.step_at}
    return Scenario(
        name=info.name,
        group=info.group,
        kind=KIND,
        fields={
            **info.fields,
            "target_speed": float(path.speed.max()),
            **step,
        },
        files={"path": path_file},
        start_time=0.0,
        stop_time=info.duration,
        sources=(info_file, path_file),
        options=settings.model_dump(exclude_none=True),
    )


class PathKind(TrackKind):
    """The kind, as ``dse_runner.simulation.scenario`` finds it."""

    name = KIND
    default_objectives = (
        "path_error_mean",
        "path_error_max",
        "heading_error",
        "steering_effort",
        "overshoot",
        "settling_distance",
    )
    reference_style = ("-", {"lw": 1.0, "color": "0.45", "label": "path"})
    title_error = ("path_error_mean", "mean path error")

    def detect(self, folder: Path) -> bool:
        return (folder / PATH_FILE).is_file()

    def load(self, folder: Path, options: Mapping[str, Any] | None = None) -> Scenario:
        return load_path(folder, options)

    def tracks(self, result) -> tuple[XY, XY]:
        points = path_of(result.scenario).points
        return (points[:, 0], points[:, 1]), simulated_xy(result.trajectory, result.scenario)


PATH_KIND = PathKind()


def path_of(scenario: Scenario) -> Polyline:
    if scenario.kind != KIND or "path" not in scenario.files:
        raise DseError(f"scenario {scenario.name} is a {scenario.kind} scenario, not a path to follow")
    return polyline(scenario.files["path"])


def step_of(scenario: Scenario) -> Step | None:
    """The scenario's lateral step, if its scenario.yaml declares ``step_at``."""
    at = scenario.fields.get("step_at")
    return None if at is None else lateral_step(path_of(scenario), float(at), f"scenario {scenario.name}")


# ---- matching the simulated position with the path ---------------------------------------------


@dataclass(frozen=True)
class Projection:
    """Each sample's closest point on the path: its arc length [m], its segment, the distance [m]."""

    arc: np.ndarray
    segment: np.ndarray
    distance: np.ndarray


def _closest(path: Polyline, xy: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """For each row of ``xy``, the closest path point whose arc length lies in [lo, hi] of that row:
    (arc, segment, distance). One numpy pass over the segments the windows overlap."""
    last_segment = len(path.direction) - 1
    first = min(max(int(np.searchsorted(path.arc, lo.min(), "right")) - 1, 0), last_segment)
    last = min(max(int(np.searchsorted(path.arc, hi.max(), "right")) - 1, first), last_segment)
    start, end = path.arc[first : last + 1], path.arc[first + 1 : last + 2]
    origin, direction = path.points[first : last + 1], path.direction[first : last + 1]
    dx = xy[:, :1] - origin[:, 0]
    dy = xy[:, 1:] - origin[:, 1]
    low, high = np.maximum(start, lo[:, None]), np.minimum(end, hi[:, None])
    arc = np.clip(start + dx * direction[:, 0] + dy * direction[:, 1], low, high)
    offset = arc - start
    distance = np.hypot(dx - offset * direction[:, 0], dy - offset * direction[:, 1])
    distance[low > high] = np.inf  # segments outside the row's window
    best = np.argmin(distance, axis=1)
    rows = np.arange(len(xy))
    return arc[rows, best], first + best, distance[rows, best]


def project(path: Polyline, xy: np.ndarray, lookahead: float = LOOKAHEAD) -> Projection:
    """Match each sample with the closest path point at or after the previous sample's, at most
    ``lookahead`` plus the distance moved since that sample further along the path (the first
    sample: anywhere on the path).

    Samples are matched a block at a time against the union of their windows; a block's answers
    are kept as long as each lies in its own sample's window (then it is that window's closest
    point too), and the first that does not is matched alone. So the result is exactly the
    sample-by-sample search, at a few numpy calls per ``lookahead`` metres driven."""
    count = len(xy)
    arc, segment, distance = np.empty(count), np.empty(count, dtype=np.intp), np.empty(count)
    moved = np.concatenate([[0.0], np.hypot(*np.diff(xy, axis=0).T)])

    def keep(k: int, found) -> None:
        n = len(found[0])
        arc[k : k + n], segment[k : k + n], distance[k : k + n] = found

    keep(0, _closest(path, xy[:1], np.zeros(1), np.full(1, path.length)))
    k = 1
    while k < count:
        origin = arc[k - 1]
        size = max(1, int(np.searchsorted(np.cumsum(moved[k : k + MAX_BLOCK]), lookahead, "right")))
        block = slice(k, k + size)
        reach = origin + 2 * lookahead + moved[block].max()
        found = _closest(path, xy[block], np.full(size, origin), np.full(size, reach))
        previous = np.concatenate([[origin], found[0][:-1]])
        fits = (
            (found[0] >= previous)
            & (found[0] <= previous + lookahead + moved[block])
            & (previous - origin <= lookahead)
        )
        good = size if fits.all() else int(np.argmin(fits))
        keep(k, tuple(a[:good] for a in found))
        k += good
        if good < size:  # sample k alone, in its own window
            lo = arc[k - 1]
            keep(k, _closest(path, xy[k : k + 1], np.full(1, lo), np.full(1, lo + lookahead + moved[k])))
            k += 1
    return Projection(arc, segment, distance)


# ---- which outputs are the pose and the steering ------------------------------------------------


def pose_of(names, scenario: Scenario) -> tuple[str, str, str]:
    """The simulated x, y and heading among recorded ``names``: the scenario's options, or the only
    instance with outputs x, y and theta."""
    given, heading = scenario.options.get("position"), scenario.options.get("heading")
    if given:
        return given["x"], given["y"], heading or f"{given['x'].rpartition('.')[0]}.theta"
    names = set(names)
    instances = {split_ref(n)[0] for n in names if "." in n}
    candidates = [i for i in sorted(instances) if {f"{i}.x", f"{i}.y", f"{i}.theta"} <= names]
    if len(candidates) != 1:
        found = f"instances {', '.join(candidates)} have all" if candidates else "no instance has all"
        raise DseError(
            f"scenario {scenario.name}: which outputs are the pose that follows the path? {found} "
            "three of x, y and theta; say it in space.yaml: scenarios: [{path: ..., "
            "position: {x: .., y: ..}, heading: ..}]"
        )
    return f"{candidates[0]}.x", f"{candidates[0]}.y", heading or f"{candidates[0]}.theta"


def steering_of(names, scenario: Scenario) -> str:
    """The steering angle among recorded ``names``: the option ``steering``, or the only delta_f."""
    if scenario.options.get("steering"):
        return scenario.options["steering"]
    found = [n for n in names if n.rpartition(".")[2] == "delta_f"]
    if len(found) != 1:
        which = f"{', '.join(found)} are all" if found else "no output is"
        raise DseError(
            f"scenario {scenario.name}: which output is the steering angle? {which} named "
            "delta_f; say it in space.yaml: scenarios: [{path: ..., steering: ..}]"
        )
    return found[0]


def simulated_xy(trajectory, scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    x_ref, y_ref, _ = pose_of(trajectory.names, scenario)
    return trajectory.column(x_ref), trajectory.column(y_ref)


_followed: tuple[weakref.ref, tuple, Projection] | None = None  # the last run matched, for its objectives


def follow(trajectory, scenario: Scenario) -> Projection:
    """The simulated position matched with the path, computed once per run for all its objectives."""
    global _followed
    x_ref, y_ref, _ = pose_of(trajectory.names, scenario)
    path = path_of(scenario)
    key = (str(scenario.files["path"]), x_ref, y_ref)
    last = _followed
    if last is not None and last[0]() is trajectory and last[1] == key:
        return last[2]
    projection = project(path, np.column_stack([trajectory.column(x_ref), trajectory.column(y_ref)]))
    _followed = (weakref.ref(trajectory), key, projection)
    return projection


# ---- objectives --------------------------------------------------------------------------------


def _time_mean(time: np.ndarray, values: np.ndarray) -> float:
    """Trapezoidal time average over the run, as ``reduce: mean`` computes it (one sample: its value)."""
    span = float(time[-1] - time[0])
    return float(np.trapezoid(values, time) / span) if span > 0 else float(values[0])


def path_error_mean(trajectory, scenario: Scenario) -> float:
    """Time-mean distance from the simulated position to the path [m]."""
    return _time_mean(trajectory.time, follow(trajectory, scenario).distance)


def path_error_max(trajectory, scenario: Scenario) -> float:
    """Largest distance from the simulated position to the path [m]."""
    return float(np.max(follow(trajectory, scenario).distance))


def heading_error(trajectory, scenario: Scenario) -> float:
    """Time-mean of |heading - direction of the path at the closest point|, wrapped to [-pi, pi] [rad]."""
    projection = follow(trajectory, scenario)
    theta = trajectory.column(pose_of(trajectory.names, scenario)[2])
    difference = theta - path_of(scenario).heading[projection.segment]
    return _time_mean(trajectory.time, np.abs(np.angle(np.exp(1j * difference))))


def steering_effort(trajectory, scenario: Scenario) -> float:
    """Integral of |d delta_f / dt| over the run [rad]: the total steering movement, which is
    the sum of the changes between communication points (the signal is linear between them)."""
    return float(np.sum(np.abs(np.diff(trajectory.column(steering_of(trajectory.names, scenario))))))


def _past_step(trajectory, scenario: Scenario) -> tuple[Step, np.ndarray, np.ndarray] | None:
    """The step, and for each sample past it: its distance along the row and its offset from the new line."""
    step = step_of(scenario)
    if step is None:
        return None
    xy = np.column_stack(simulated_xy(trajectory, scenario))
    along = step.along(xy)
    past = along >= 0
    return step, along[past], step.lateral(xy[past])


def overshoot(trajectory, scenario: Scenario) -> float:
    """Largest excursion beyond the new line after a lateral step, on the far side from the old
    line [m]; 0 if the vehicle never crosses it, never reaches the step, or the path has no step."""
    found = _past_step(trajectory, scenario)
    if found is None or not found[2].size:
        return 0.0
    step, _, lateral = found
    return max(0.0, float(np.max(np.sign(step.size) * lateral)))


def settling_distance(trajectory, scenario: Scenario) -> float:
    """Distance along the row past a lateral step at which the vehicle enters, for good, the band of
    SETTLE_FRACTION x |step size| around the new line [m]; the row's whole length past the step if
    it never does (or never reaches it); 0 if the path has no step."""
    found = _past_step(trajectory, scenario)
    if found is None:
        return 0.0
    step, along, lateral = found
    outside = np.flatnonzero(np.abs(lateral) > SETTLE_FRACTION * abs(step.size))
    if not along.size or (outside.size and outside[-1] == along.size - 1):
        return step.end
    return max(0.0, float(along[outside[-1] + 1] if outside.size else along[0]))
