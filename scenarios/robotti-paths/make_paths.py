"""Write the reference paths of this folder: one folder per path, path.csv and scenario.yaml.

    python3 scenarios/robotti-paths/make_paths.py

The paths are built from straight pieces and circular arcs (and a sine), with waypoints at most
SPACING apart, so that curves are followed closely; each ends at target speed 0, reached over the
last STOP_RAMP metres, so that a controller knows where to stop. A duration is the time to drive
the path at its target speeds (each at least MIN_SPEED, the end ramp's 0 included) times 1.2,
plus 10 s, rounded up to 5 s. Conventions as in docs/robotti-model.md: theta counter-clockwise from
the x axis; positive delta_f turns right. Running it again writes the same bytes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SPACING = 0.25  # m between waypoints, at most
STOP_RAMP = 2.0  # m over which the target speed falls to 0 at the end
MIN_SPEED = 0.5  # m/s: the slowest speed a duration assumes


def straight(start: np.ndarray, heading: float, length: float) -> np.ndarray:
    """Points from ``start`` (excluded) along ``heading`` [rad] for ``length`` metres."""
    n = math.ceil(length / SPACING - 1e-9)
    s = np.linspace(0, length, n + 1)[1:]
    return start + np.outer(s, [math.cos(heading), math.sin(heading)])


def arc(start: np.ndarray, heading: float, radius: float, angle: float) -> np.ndarray:
    """Points from ``start`` (excluded) on a circle of ``radius`` turning ``angle`` [rad], positive
    counter-clockwise (to the left)."""
    n = math.ceil(radius * abs(angle) / SPACING - 1e-9)
    turn = math.copysign(1.0, angle)
    centre = start + radius * turn * np.array([-math.sin(heading), math.cos(heading)])
    phi = heading - turn * math.pi / 2 + np.linspace(0, angle, n + 1)[1:]
    return centre + radius * np.column_stack([np.cos(phi), np.sin(phi)])


def arc_length(points: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])


def speeds(arc: np.ndarray, knots: list[tuple[float, float]]) -> np.ndarray:
    """Target speed at each arc length: linear between (arc, speed) knots, then down to 0 over the
    last STOP_RAMP metres."""
    s, v = zip(*knots)
    speed = np.interp(arc, s, v)
    return speed * np.clip((arc[-1] - arc) / STOP_RAMP, 0.0, 1.0)


def duration(arc: np.ndarray, speed: np.ndarray) -> float:
    v = np.maximum(speed, MIN_SPEED)
    drive = float(np.sum(np.diff(arc) * 2 / (v[1:] + v[:-1])))
    return 5.0 * math.ceil((1.2 * drive + 10.0) / 5.0)


def write(
    name: str,
    group: str,
    points: np.ndarray,
    knots: list[tuple[float, float]],
    pose: tuple[float, float, float],
    step_at: float | None = None,
) -> None:
    """One folder: path.csv (x, y to 0.1 mm, speed to 1 cm/s) and scenario.yaml."""
    folder = HERE / name
    folder.mkdir(exist_ok=True)
    points = np.round(points, 4) + 0.0  # + 0.0: no "-0.0000"
    speed = np.round(speeds(arc_length(points), knots), 2) + 0.0
    rows = "".join(f"{x:.4f},{y:.4f},{v:.2f}\n" for (x, y), v in zip(points, speed))
    (folder / "path.csv").write_text("x,y,speed\n" + rows)
    x, y, theta = pose
    text = (
        f"name: {name}\ngroup: {group}\nduration: {duration(arc_length(points), speed):.1f}\n"
        f"initial_pose: {{x: {x:.4f}, y: {y:.4f}, theta: {theta:.6f}}}\n"
    )
    if step_at is not None:
        text += f"step_at: {step_at:.4f}  # m of path: the row moves sideways here (docs/paths.md)\n"
    (folder / "scenario.yaml").write_text(text)


def straight_offset() -> None:
    """A 60 m row at 30 degrees; the vehicle starts 1 m to its left (it must steer right, delta_f > 0)."""
    heading, origin = math.radians(30.0), np.zeros(2)
    points = np.vstack([origin, straight(origin, heading, 60.0)])
    left = origin + np.array([-math.sin(heading), math.cos(heading)])
    write("straight_offset", "straight", points, [(0, 1.5)], (*left, heading))


def lateral_step() -> None:
    """A row along x whose line moves 1 m to the left (y = 0 to y = 1) at 30 m, over 0.1 m of x;
    the vehicle starts on it (it must steer left, delta_f < 0, at the step)."""
    before = np.vstack([np.zeros(2), straight(np.zeros(2), 0.0, 30.0)])
    after_start = np.array([30.1, 1.0])
    points = np.vstack([before, after_start, straight(after_start, 0.0, 29.9)])
    write("lateral_step", "straight", points, [(0, 1.5)], (0.0, 0.0, 0.0), step_at=30.0)


def headland_turn() -> None:
    """A 30 m row along x, a left U-turn of radius 6 m, and the next row back, 12 m over; 1.4 m/s on
    the rows, 1.0 m/s in the turn (slowing over the 3 m before it, speeding up over the 3 m after)."""
    radius, row = 6.0, 30.0
    first = np.vstack([np.zeros(2), straight(np.zeros(2), 0.0, row)])
    turn = arc(first[-1], 0.0, radius, math.pi)
    back = straight(turn[-1], math.pi, row)
    points = np.vstack([first, turn, back])
    bend = math.pi * radius
    knots = [
        (0, 1.4),
        (row - 3, 1.4),
        (row, 1.0),
        (row + bend, 1.0),
        (row + bend + 3, 1.4),
        (2 * row + bend, 1.4),
    ]
    write("headland_turn", "headland", points, knots, (0.0, 0.0, 0.0))


def curved_row() -> None:
    """A sine-shaped row: y = 1.5 sin(2 pi x / 30) for x in 0..60 (smallest radius 15.2 m), waypoints
    equally spaced along it; the vehicle starts on it, heading along it."""
    amplitude, wavelength, length = 1.5, 30.0, 60.0
    x = np.linspace(0.0, length, 60001)
    dense = np.column_stack([x, amplitude * np.sin(2 * math.pi * x / wavelength)])
    s = arc_length(dense)
    at = np.linspace(0.0, s[-1], math.ceil(s[-1] / SPACING) + 1)
    points = np.column_stack([np.interp(at, s, dense[:, 0]), np.interp(at, s, dense[:, 1])])
    theta = math.atan(amplitude * 2 * math.pi / wavelength)
    write("curved_row", "curved", points, [(0, 1.2)], (0.0, 0.0, theta))


if __name__ == "__main__":
    straight_offset()
    lateral_step()
    headland_turn()
    curved_row()
