"""The path controller FMU driving the baseline vehicle FMU in closed loop, against closed-form expectations.

The multi-model is the Robotti's (dse_runner/bundled/robotti/multimodel.yaml) with the path controller in
place of the replay controller. Expectations come from the controller's design (its closed-loop polynomial,
its limits, its PI's integral action) and the vehicle's kinematics, not from figures of an earlier run.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import FMU_SOURCES

from dse_runner import DseError
from dse_runner.simulation.run import as_plan, simulate

STEP = 0.05  # communication step [s], the recorded runs' control period
CONNECTIONS = {
    "controller.velocity": ["vehicle.velocity"],
    "controller.delta_f": ["vehicle.delta_f"],
    "vehicle.x": ["controller.x"],
    "vehicle.y": ["controller.y"],
    "vehicle.theta": ["controller.theta"],
}
VEHICLE_MASS, VEHICLE_KV = 1500.0, 8000.0  # the baseline vehicle's defaults (docs/robotti-model.md)


def write_multimodel(folder: Path, vehicle: str = "robotti_vehicle") -> Path:
    path = folder / f"path-following-{vehicle}.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "fmus": {"controller": "bundled:fmus/path_controller", "vehicle": f"bundled:fmus/{vehicle}"},
                "connections": CONNECTIONS,
                "parameters": {"vehicle.rk4_step": 0.001},
                "step": STEP,
            }
        )
    )
    return path


@pytest.fixture(scope="module")
def plan(tmp_path_factory):
    return as_plan(write_multimodel(tmp_path_factory.mktemp("mm")))


@pytest.fixture(scope="module")
def effects_plan(tmp_path_factory):
    return as_plan(write_multimodel(tmp_path_factory.mktemp("mm"), "robotti_vehicle_effects"))


@pytest.fixture(scope="module")
def defaults():
    """The controller's parameter defaults, as its modelDescription.xml declares them."""
    from fmpy.model_description import read_model_description

    md = read_model_description(str(FMU_SOURCES / "path_controller" / "modelDescription.xml"), validate=False)
    return {
        v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter" and v.type == "Real"
    }


def write_path(folder: Path, points, name: str = "path.csv") -> Path:
    path = folder / name
    path.write_text(
        "x,y,speed\n" + "".join(f"{float(x)!r},{float(y)!r},{float(v)!r}\n" for x, y, v in points)
    )
    return path


def drive(plan, path: Path, stop: float, **values):
    """Simulates from 0 to ``stop``; ``values`` are instance.variable refs with '.' written '__'."""
    given = {"controller.file": str(path), **{k.replace("__", "."): v for k, v in values.items()}}
    return simulate(plan, values=given, stop_time=stop, step=STEP, objectives=[]).trajectory


def closed_loop(omega_c: float, lever: float, speed: float) -> tuple[float, float]:
    """Decay rate sigma [1/s] and damping ratio zeta of the steering loop on a straight row.

    With x2 the part of e' the steering does not bring about at once, the lateral model is
    e' = x2 + c u, x2' = b0 u (kinematic bicycle, small angles; b0 = v^2/L, c = v lever/L with
    lever = L/2 + lookahead), and the law b0 u = -kp e - kd (x2 + c u) gives
    (1 + r kd) s^2 + (kd + r kp) s + kp = 0 with r = c/b0 = lever/v, kp = wc^2, kd = 2 wc."""
    r, kp, kd = lever / speed, omega_c**2, 2.0 * omega_c
    a, b, c = 1.0 + r * kd, kd + r * kp, kp
    omega_n = math.sqrt(c / a)
    zeta = b / (2.0 * a * omega_n)
    sigma = min(-root.real for root in np.roots([a, b, c]))
    return sigma, zeta


def start_lag(p: dict) -> float:
    """Time before the loop behaves as the linear model: the drive brings the vehicle to speed
    (five time constants m/Kv) and the steering ramps to at most max_steer at max_steer_rate."""
    return 5.0 * VEHICLE_MASS / VEHICLE_KV + p["max_steer"] / p["max_steer_rate"]


# ---- 1. an offset from a straight row decays as the closed-loop poles say ------------------------


@pytest.mark.parametrize("speed", [1.0, 2.0])
def test_offset_from_a_straight_row_decays(plan, tmp_path, defaults, speed):
    offset = 1.0
    sigma, zeta = closed_loop(defaults["omega_c"], defaults["wheelbase"] / 2 + defaults["lookahead"], speed)
    assert zeta > 0.85  # the design's promise: zeta >= sqrt(3)/2 for any speed and look-ahead
    settled = start_lag(defaults) + 4.0 / sigma  # four time constants: envelope e^-4 / sqrt(1 - zeta^2)
    row = write_path(tmp_path, [(0.0, 0.0, speed), (speed * (settled + 10.0) + 20.0, 0.0, speed)])
    traj = drive(plan, row, settled + 5.0, vehicle__y0=offset, controller__k_heading=0.0)
    ct = traj.column("controller.cross_track")
    assert ct[0] == pytest.approx(offset)
    # The row is the x axis; the controller's outputs at t come from the pose it was given at t - step.
    assert np.allclose(ct[1:], traj.column("vehicle.y")[:-1], atol=1e-12)
    # It never moves away from the row by more than a trace, and overshoots at most as a second-order
    # system of this damping does from rest (exp(-zeta pi / sqrt(1 - zeta^2))), plus 2% of the offset.
    assert ct.max() <= offset * 1.001
    overshoot = math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta**2)) if zeta < 1 else 0.0
    assert -ct.min() <= offset * (overshoot + 0.02)
    late = traj.time >= settled
    assert late.sum() > 50
    assert np.abs(ct[late]).max() < 0.05 * offset


# ---- 2. the steering limits hold ----------------------------------------------------------------


@pytest.mark.parametrize("max_steer, max_steer_rate", [(0.05, 0.3), (0.3, 0.02)])
def test_steering_stays_within_its_angle_and_rate_limits(plan, tmp_path, max_steer, max_steer_rate):
    row = write_path(tmp_path, [(0.0, 0.0, 1.0), (100.0, 0.0, 1.0)])
    traj = drive(
        plan,
        row,
        20.0,
        vehicle__y0=4.0,
        controller__max_steer=max_steer,
        controller__max_steer_rate=max_steer_rate,
    )
    delta = traj.column("controller.delta_f")
    rate = np.diff(delta) / np.diff(traj.time)
    assert np.abs(delta).max() <= max_steer * (1 + 1e-12)
    assert np.abs(rate).max() <= max_steer_rate * (1 + 1e-9)
    # The limits are reached, so the checks above are not vacuous...
    assert np.abs(delta).max() == pytest.approx(max_steer, rel=1e-9) or np.abs(rate).max() == pytest.approx(
        max_steer_rate, rel=1e-9
    )
    # ...and the reported steering rate is the one applied.
    assert np.allclose(traj.column("controller.steering_rate")[1:], rate, atol=1e-9)


# ---- 3. sign conventions ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "heading, side",
    [(0.0, +1), (0.0, -1), (math.pi, +1), (math.pi, -1)],
    ids=["east-left", "east-right", "west-left", "west-right"],
)
def test_a_vehicle_left_of_the_row_is_steered_right(plan, tmp_path, heading, side):
    """side +1: the vehicle starts 1 m to the LEFT of the row in the direction of travel."""
    direction = math.cos(heading)  # +1 east, -1 west
    start = (0.0, 0.0) if direction > 0 else (100.0, 0.0)
    row = write_path(tmp_path, [(*start, 1.0), (start[0] + 100.0 * direction, 0.0, 1.0)])
    y0 = side * direction  # left of an eastward row is +y, of a westward row -y
    traj = drive(plan, row, 3.0, vehicle__x0=start[0], vehicle__y0=y0, vehicle__theta0=heading)
    ct, delta = traj.column("controller.cross_track"), traj.column("controller.delta_f")
    assert ct[0] == pytest.approx(side)  # positive = left of the path in the direction of travel
    first = np.flatnonzero(delta)[0]
    assert np.sign(delta[first]) == side  # left -> positive delta_f -> a right turn
    # The vehicle's kinematics: a right turn is clockwise (yaw rate < 0), and it brings the vehicle
    # towards the row.
    moving = (traj.time > 0.5) & (traj.time < 1.5)
    assert np.all(np.sign(traj.column("vehicle.yaw_rate")[moving]) == -side)
    assert np.sign(traj.column("controller.heading_error")[moving][-1]) == -side
    assert abs(ct[-1]) < abs(ct[0])


# ---- 4. speed control ---------------------------------------------------------------------------


def test_speed_reaches_the_paths_target(plan, tmp_path):
    target = 1.5
    row = write_path(tmp_path, [(0.0, 0.0, target), (200.0, 0.0, target)])
    traj = drive(plan, row, 15.0)
    late = traj.time >= 10.0
    ground = np.hypot(traj.column("vehicle.vx"), traj.column("vehicle.vy"))
    assert np.abs(ground[late] - target).max() < 0.01 * target
    assert np.abs(traj.column("controller.speed_estimate")[late] - target).max() < 0.01 * target
    assert np.all(traj.column("controller.target_speed") == target)


@pytest.mark.parametrize("ki_v", [0.0, None])
def test_speed_pi_removes_the_offset_of_wheel_slip(effects_plan, tmp_path, defaults, ki_v):
    """On slipping soil the ground speed is (1 - slip) times the commanded wheel speed. A P controller
    around the target settles at v = (1 - s)(1 + kp) T / (1 + (1 - s) kp); the integral removes that."""
    target, slip, kp = 1.5, 0.2, defaults["kp_v"]
    row = write_path(tmp_path, [(0.0, 0.0, target), (200.0, 0.0, target)])
    values = {"vehicle__wheel_slip": slip}
    if ki_v is not None:
        values["controller__ki_v"] = ki_v
    traj = drive(effects_plan, row, 40.0, **values)
    late = traj.time >= 30.0
    ground = traj.column("vehicle.vx")[late]
    expected = target if ki_v is None else (1 - slip) * (1 + kp) * target / (1 + (1 - slip) * kp)
    assert np.abs(ground - expected).max() < 0.005 * target
    assert expected < 0.9 * target or ki_v is None  # the P-only case does fall short


def test_target_speed_is_linear_in_arc_length_and_the_vehicle_stops_past_the_end(plan, tmp_path):
    length = 12.0
    path = write_path(tmp_path, [(0.0, 0.0, 1.0), (length / 2, 0.0, 1.5), (length, 0.0, 0.5)])
    traj = drive(plan, path, 25.0)
    progress, target = traj.column("controller.progress"), traj.column("controller.target_speed")
    velocity, x = traj.column("controller.velocity"), traj.column("vehicle.x")
    on_path = x < length
    expected = np.interp(progress[on_path], [0.0, length / 2, length], [1.0, 1.5, 0.5])
    assert np.allclose(target[on_path], expected, atol=1e-12)
    assert np.all(np.diff(progress) >= 0.0)
    # Once the controller is given a pose past the last waypoint its command is 0, for good (it is given
    # the pose at t - step), and the vehicle comes to rest.
    past = np.flatnonzero(x > length)[0]
    assert np.all(velocity[past + 1 :] == 0.0) and velocity[past] > 0.0
    assert progress[-1] == pytest.approx(length)
    assert abs(traj.column("vehicle.vx")[-1]) < 1e-3
    assert x[-1] - length < 0.5


# ---- 5. a bad path file -------------------------------------------------------------------------


BAD_PATHS = [
    ("missing", None, "cannot open {path}"),
    ("bad header", "x,y,velocity\n0,0,1\n5,0,1\n", "{path} line 1: header has no 'speed' column"),
    ("not a number", "x,y,speed\n0,0,1\n5,abc,1\n", "{path} line 3: field 2 is not a number"),
    ("one point", "x,y,speed\n0,0,1\n", "{path} line 2: the path needs at least 2 waypoints"),
    (
        "repeated point",
        "x,y,speed\n0,0,1\n5,0,1\n5,0,2\n",
        "{path} line 4: waypoint (5, 0) equals the previous one (line 3)",
    ),
    ("too few fields", "x,y,speed\n0,0,1\n5,0\n", "{path} line 3: expected 3 fields, got 2"),
    ("negative speed", "speed,x,y\n1,0,0\n-1,5,0\n", "{path} line 3: speed -1 is negative"),
]


@pytest.mark.parametrize("text, message", [b[1:] for b in BAD_PATHS], ids=[b[0] for b in BAD_PATHS])
def test_a_bad_path_file_fails_naming_the_file_and_line(plan, tmp_path, text, message):
    path = tmp_path / "bad path.csv"
    if text is not None:
        path.write_text(text)
    with pytest.raises(DseError, match=re.escape(message.format(path=path))):
        drive(plan, path, 1.0)


def test_a_bad_parameter_fails_naming_it(plan, tmp_path):
    row = write_path(tmp_path, [(0.0, 0.0, 1.0), (10.0, 0.0, 1.0)])
    with pytest.raises(DseError, match=r"parameter omega_c must be > 0, got -1"):
        drive(plan, row, 1.0, controller__omega_c=-1.0)


# ---- the rest: curves, folds, disturbances, instances -------------------------------------------


def u_turn(radius: float, row: float, speed: float, spacing: float = 0.25):
    """Out along y = 0, a left half circle, back along y = 2 radius: a path that folds back."""
    out = [(x, 0.0, speed) for x in np.arange(0.0, row, spacing)]
    turn = [
        (row + radius * math.sin(a), radius - radius * math.cos(a), speed)
        for a in np.arange(0.0, math.pi, spacing / radius)
    ]
    back = [(x, 2 * radius, speed) for x in np.arange(row, -1e-9, -spacing)]
    return out + turn + back


def test_a_u_turn_is_followed_and_the_closest_point_keeps_to_its_branch(plan, tmp_path, defaults):
    radius, row = 7.0, 15.0  # wider than the tightest turn, wheelbase / tan(max_steer) = 4.9 m
    points = u_turn(radius, row, 1.0)
    length = float(np.sum(np.hypot(*np.diff(np.array(points)[:, :2], axis=0).T)))
    traj = drive(plan, write_path(tmp_path, points), length + 12.0)
    progress, ct = traj.column("controller.progress"), traj.column("controller.cross_track")
    assert np.all(np.diff(progress) >= 0.0) and progress[-1] == pytest.approx(length)
    # The branches are 2 radius apart; a jump to the other one would show as |ct| near that.
    assert np.abs(ct).max() < 0.5
    # Mid-turn the look-ahead point (lever = L/2 + lookahead ahead of the rear axle) is on the circle,
    # so the reference point (L/2 ahead) runs inside it: R - sqrt(R^2 - lever^2 + (L/2)^2).
    half, lever = defaults["wheelbase"] / 2, defaults["wheelbase"] / 2 + defaults["lookahead"]
    inside = radius - math.sqrt(radius**2 - lever**2 + half**2)
    middle = np.argmin(np.abs(progress - (row + math.pi * radius / 2)))
    assert ct[middle] == pytest.approx(inside, abs=0.03)


def test_the_closest_point_keeps_to_its_branch_where_a_later_one_is_nearer(plan, tmp_path):
    """A row out along y = 0, a turn, the row back along y = 1.6. The vehicle starts 0.9 m left of the
    first row, so 0.7 m from the way back: it belongs to the first row all the same, at the start (found
    by following the path from its beginning) and while it steers in (the search looks only a few metres
    ahead along the path); a nearest-point search over the whole path would take the way back."""
    spacing = 1.6
    out = [(float(x), 0.0, 1.0) for x in range(21)]  # waypoints every metre: the search moves on
    points = out + [(25.0, spacing / 2, 1.0)] + [(x, spacing, 1.0) for x, _, _ in reversed(out)]
    traj = drive(plan, write_path(tmp_path, points), 5.0, vehicle__y0=0.9)
    ct, progress = traj.column("controller.cross_track"), traj.column("controller.progress")
    assert ct[0] == pytest.approx(0.9) and progress[0] == pytest.approx(0.0)
    assert np.allclose(ct[1:], traj.column("vehicle.y")[:-1], atol=1e-12)  # offsets from y = 0 throughout
    assert np.allclose(progress[1:], traj.column("vehicle.x")[:-1], atol=1e-12)
    assert np.sum(traj.column("vehicle.y")[1:] > spacing / 2) >= 5  # nearer the way back for a while


def test_a_constant_steering_offset_is_rejected(effects_plan, tmp_path, defaults):
    """The extended-state observer estimates a steering offset as part of the total disturbance and
    the control cancels it: no steady cross-track error, and the steady command undoes the offset."""
    offset = 0.03  # rad, positive = right
    row = write_path(tmp_path, [(0.0, 0.0, 1.0), (200.0, 0.0, 1.0)])
    sigma, _ = closed_loop(defaults["omega_c"], defaults["wheelbase"] / 2 + defaults["lookahead"], 1.0)
    settled = start_lag(defaults) + 8.0 / sigma
    traj = drive(effects_plan, row, settled + 5.0, vehicle__steering_offset=offset)
    late = traj.time >= settled
    assert np.abs(traj.column("controller.cross_track")[late]).max() < 0.01
    assert np.abs(traj.column("controller.delta_f")[late] + offset).max() < 0.1 * offset


def test_runs_repeat_exactly_and_instances_share_nothing(tmp_path, plan):
    row = write_path(tmp_path, [(0.0, 0.0, 1.0), (100.0, 0.0, 1.0)])
    near = drive(plan, row, 10.0, vehicle__y0=0.5)
    drive(plan, row, 10.0, vehicle__y0=-2.0, controller__omega_c=1.0)
    assert np.array_equal(near.values, drive(plan, row, 10.0, vehicle__y0=0.5).values)
    far = drive(plan, row, 10.0, vehicle__y0=-2.0)

    # Two controller-vehicle pairs in one co-simulation run as each does alone.
    def renamed(ref: str, pair: str) -> str:
        return ref.replace("controller.", f"{pair}_ctrl.").replace("vehicle.", f"{pair}_veh.")

    pairs = {"fmus": {}, "connections": {}, "step": STEP}
    for name in ("a", "b"):
        pairs["fmus"].update(
            {f"{name}_ctrl": "bundled:fmus/path_controller", f"{name}_veh": "bundled:fmus/robotti_vehicle"}
        )
        for source, targets in CONNECTIONS.items():
            pairs["connections"][renamed(source, name)] = [renamed(t, name) for t in targets]
    mm = tmp_path / "pairs.yaml"
    mm.write_text(yaml.safe_dump(pairs))
    both = simulate(
        mm,
        values={
            "a_ctrl.file": str(row),
            "b_ctrl.file": str(row),
            "a_veh.y0": 0.5,
            "b_veh.y0": -2.0,
            "a_veh.rk4_step": 0.001,
            "b_veh.rk4_step": 0.001,
        },
        stop_time=10.0,
        step=STEP,
        objectives=[],
    ).trajectory
    for name, alone in (("a", near), ("b", far)):
        for signal in ("controller.delta_f", "controller.cross_track", "vehicle.y"):
            assert np.array_equal(both.column(renamed(signal, name)), alone.column(signal)), signal


def test_start_values_match_the_c_defaults_and_every_parameter_has_a_unit(plan):
    from dse_runner.simulation import fmu as fmus

    loaded = fmus.load(plan.fmu_paths["controller"])
    instance = fmus.acquire("controller", loaded)
    for variable in loaded.description.modelVariables:
        if variable.type == "Real" and variable.start is not None:
            (value,) = instance.slave.getReal([variable.valueReference])
            assert value == pytest.approx(float(variable.start)), variable.name
        if variable.causality in ("parameter", "output"):
            assert re.search(r"\[[^]]+\]", variable.description or ""), f"{variable.name} has no unit"
