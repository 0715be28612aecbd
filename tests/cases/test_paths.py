"""The path kind (dse_runner/cases/paths.py): the four reference paths, path-following objectives on
hand-made trajectories whose answers are known, bad files, and one run of the real vehicle FMU."""

from __future__ import annotations

import importlib.util
import math
import re
import shutil

import numpy as np
import pytest
import yaml
from conftest import REPO

from dse_runner import DseError
from dse_runner.cases import paths
from dse_runner.simulation import objectives as objs
from dse_runner.simulation.scenario import load_scenario
from dse_runner.simulation.trajectory import Trajectory

PATHS = REPO / "scenarios" / "robotti-paths"
NAMES = ("straight_offset", "lateral_step", "headland_turn", "curved_row")


def trajectory(time, x, y, theta=None, delta_f=None) -> Trajectory:
    """A vehicle's recorded outputs; theta defaults to the direction of travel."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if theta is None:
        theta = np.unwrap(np.arctan2(np.gradient(y), np.gradient(x)))
    delta_f = np.zeros_like(x) if delta_f is None else delta_f
    return Trajectory(
        np.asarray(time, float),
        ("vehicle.x", "vehicle.y", "vehicle.theta", "ctrl.delta_f"),
        np.column_stack([x, y, theta, delta_f]),
    )


def scores(traj: Trajectory, scenario) -> dict[str, float]:
    return objs.evaluate(objs.normalise(list(paths.PathKind.default_objectives)), traj, scenario)


def on_path(path: paths.Polyline, arc: np.ndarray) -> np.ndarray:
    return np.column_stack(
        [np.interp(arc, path.arc, path.points[:, 0]), np.interp(arc, path.arc, path.points[:, 1])]
    )


# ---- the four reference paths ------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_the_kind_reads_each_reference_path(name):
    scenario = load_scenario(PATHS / name)  # recognised by its path.csv, not taken for field data
    assert scenario.kind == "path" and scenario.name == name
    assert scenario.files["path"] == (PATHS / name / "path.csv").resolve()
    assert scenario.stop_time == scenario.fields["duration"] and scenario.start_time == 0
    bound = {"duration", "initial_pose.x", "initial_pose.y", "initial_pose.theta", "target_speed"}
    assert bound <= set(scenario.fields)
    path = paths.path_of(scenario)
    assert len(path.points) <= 500
    assert np.count_nonzero(np.diff(path.arc) > 0.2501) == (
        name == "lateral_step"
    )  # the step's sideways jump
    assert 1.0 <= scenario.fields["target_speed"] <= 1.6
    assert path.speed[0] > 0 and path.speed[-1] == 0  # drive off at once, stop at the end
    assert scenario.fields["duration"] > path.length / scenario.fields["target_speed"]
    start = np.array([scenario.fields["initial_pose.x"], scenario.fields["initial_pose.y"]])
    offset = 1.0 if name == "straight_offset" else 0.0
    assert np.linalg.norm(start - path.points[0]) == pytest.approx(offset, abs=1e-3)
    assert abs(scenario.fields["initial_pose.theta"] - path.heading[0]) < 0.01  # heading along the row


def test_the_headland_turn_fits_the_steering_limit_and_the_step_is_1_m_to_the_left():
    headland = paths.path_of(load_scenario(PATHS / "headland_turn"))
    turning = np.abs(np.angle(np.exp(1j * np.diff(headland.heading))))
    turn = turning / np.diff(headland.arc)[1:]  # curvature [1/m]
    assert 1 / turn.max() == pytest.approx(6.0, rel=0.01) and math.atan(1.8 * turn.max()) < 0.35
    step = paths.step_of(load_scenario(PATHS / "lateral_step"))
    assert (step.at, step.size, step.end) == pytest.approx((30.0, 1.0, 30.0))


def test_make_paths_writes_the_committed_files(tmp_path):
    spec = importlib.util.spec_from_file_location("make_paths", PATHS / "make_paths.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.HERE = tmp_path
    for name in NAMES:
        getattr(module, name)()
        for file in ("path.csv", "scenario.yaml"):
            assert (tmp_path / name / file).read_bytes() == (PATHS / name / file).read_bytes(), (
                f"{name}/{file}"
            )


# ---- objectives with closed-form answers ---------------------------------------------------------


@pytest.mark.parametrize("d", [0.0, 0.4, -1.0])  # negative: to the right
def test_parallel_to_a_straight_path_at_offset_d(d):
    scenario = load_scenario(PATHS / "straight_offset")
    path = paths.path_of(scenario)
    heading = path.heading[0]
    arc = np.linspace(5.0, 50.0, 901)
    xy = on_path(path, arc) + d * np.array([-math.sin(heading), math.cos(heading)])
    got = scores(trajectory(arc / 1.5, xy[:, 0], xy[:, 1], np.full(arc.size, heading)), scenario)
    # the file's coordinates are rounded to 0.1 mm, so the row is straight to 0.05 mm
    assert got == pytest.approx(
        {
            "path_error_mean": abs(d),
            "path_error_max": abs(d),
            "heading_error": 0.0,
            "steering_effort": 0.0,
            "overshoot": 0.0,
            "settling_distance": 0.0,
        },
        abs=1e-3,
    )


def test_heading_error_is_the_time_mean_of_the_wrapped_difference():
    scenario = load_scenario(PATHS / "straight_offset")
    heading = paths.path_of(scenario).heading[0]
    time = np.linspace(0, 10, 101)
    xy = on_path(paths.path_of(scenario), 1.5 * time)
    theta = heading + 0.1 + 2 * math.pi * (time > 5)  # 0.1 rad off, then the same a turn later
    got = paths.heading_error(trajectory(time, xy[:, 0], xy[:, 1], theta), scenario)
    assert got == pytest.approx(0.1, abs=1e-3)


def test_steering_effort_is_the_integral_of_the_steering_rate():
    scenario = load_scenario(PATHS / "straight_offset")
    time = np.linspace(0, 12, 2401)
    delta_f = 0.2 * np.sin(2 * math.pi * time / 4)  # three periods: 4 x 0.2 rad each
    xy = on_path(paths.path_of(scenario), 1.5 * time)
    assert paths.steering_effort(
        trajectory(time, xy[:, 0], xy[:, 1], delta_f=delta_f), scenario
    ) == pytest.approx(3 * 4 * 0.2, rel=1e-6)


def test_a_u_turn_on_the_path_has_no_error():
    scenario = load_scenario(PATHS / "headland_turn")
    path = paths.path_of(scenario)
    arc = np.linspace(0, path.length, 2000)
    xy = on_path(path, arc)
    theta = path.heading[np.clip(np.searchsorted(path.arc, arc, "right") - 1, 0, len(path.heading) - 1)]
    got = scores(trajectory(arc / 1.2, xy[:, 0], xy[:, 1], np.unwrap(theta)), scenario)
    assert got["path_error_max"] < 1e-9 and got["heading_error"] < 1e-9
    projection = paths.follow(trajectory(arc / 1.2, xy[:, 0], xy[:, 1]), scenario)
    assert projection.arc == pytest.approx(arc, abs=1e-9)


@pytest.mark.parametrize("d", [0.5, -2.0])  # outside the left turn, then inside it
def test_a_u_turn_parallel_to_the_path_at_offset_d(d):
    """The exact headland (rows and a 6 m half circle) offset by d to the right: the error is d all
    along, to within the chords' 1.3 mm sag, and the match moves only forwards."""
    t = np.linspace(0, 1, 3001)
    s = t * (60 + 6 * math.pi)
    row1, bend = s < 30, (s >= 30) & (s <= 30 + 6 * math.pi)  # the rest is the row back
    angle = (s - 30) / 6
    x = np.where(row1, s, np.where(bend, 30 + (6 + d) * np.sin(angle), 30 - (s - 30 - 6 * math.pi)))
    y = np.where(row1, -d, np.where(bend, 6 - (6 + d) * np.cos(angle), 12 + d))
    scenario = load_scenario(PATHS / "headland_turn")
    traj = trajectory(60 * t, x, y)
    got = scores(traj, scenario)
    assert got["path_error_mean"] == pytest.approx(abs(d), abs=2e-3)
    assert got["path_error_max"] == pytest.approx(abs(d), abs=2e-3)
    assert np.all(np.diff(paths.follow(traj, scenario).arc) >= 0)


def test_the_match_never_jumps_to_the_next_leg(tmp_path):
    """A hairpin whose legs lie 2 m apart; the vehicle drifts 1.4 m off the first leg towards the
    second, which is nearer then: the error is still measured to the first leg."""
    folder = tmp_path / "hairpin"
    folder.mkdir()
    s = np.linspace(0, math.pi, 13)[1:-1]
    points = (
        [(x, 0.0) for x in np.arange(0, 20.25, 0.25)]
        + [(20 + np.sin(a), 1 - np.cos(a)) for a in s]
        + [(x, 2.0) for x in np.arange(20, -0.25, -0.25)]
    )
    (folder / "path.csv").write_text("x,y,speed\n" + "".join(f"{x},{y},1\n" for x, y in points))
    (folder / "scenario.yaml").write_text(
        "name: hairpin\ngroup: g\nduration: 60\ninitial_pose: {x: 0, y: 0, theta: 0}\n"
    )
    scenario = load_scenario(folder)
    x = np.linspace(0, 15, 301)
    y = np.minimum(x / 5, 1.4)  # off the first leg by 1.4 m, 0.6 m from the second
    got = scores(trajectory(x, x, y), scenario)
    assert got["path_error_max"] == pytest.approx(1.4)
    assert paths.follow(trajectory(x, x, y), scenario).arc.max() < 16


def naive_projection(path: paths.Polyline, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The definition, sample by sample: the closest point in the window after the previous one."""
    arcs, distances = [], []
    for k, p in enumerate(xy):
        lo = 0.0 if k == 0 else arcs[-1]
        hi = path.length if k == 0 else lo + paths.LOOKAHEAD + np.linalg.norm(p - xy[k - 1])
        start, end = path.arc[:-1], path.arc[1:]
        low, high = np.maximum(start, lo), np.minimum(end, hi)
        arc = np.clip(start + np.sum((p - path.points[:-1]) * path.direction, 1), low, high)
        distance = np.linalg.norm(p - path.points[:-1] - (arc - start)[:, None] * path.direction, axis=1)
        distance[low > high] = np.inf
        best = int(np.argmin(distance))
        arcs.append(arc[best])
        distances.append(distance[best])
    return np.array(arcs), np.array(distances)


@pytest.mark.parametrize("jitter", [0.0, 0.05, 0.4])
def test_the_block_search_is_the_sample_by_sample_search(jitter):
    """Weaving, stopping, going backwards, jittering: the vectorised search gives the definition's answer."""
    path = paths.path_of(load_scenario(PATHS / "headland_turn"))
    rng = np.random.default_rng(7)
    arc = np.concatenate(
        [
            np.linspace(0, 40, 500),
            np.full(100, 40.0),
            np.linspace(40, 35, 100),
            np.linspace(35, path.length + 3, 700),
        ]
    )
    xy = on_path(path, arc) + 0.8 * np.sin(arc / 4)[:, None] + rng.normal(0, jitter, (arc.size, 2))
    projection = paths.project(path, xy)
    expected_arc, expected_distance = naive_projection(path, xy)
    assert projection.arc == pytest.approx(expected_arc, abs=1e-9)
    assert projection.distance == pytest.approx(expected_distance, abs=1e-9)


def step_response(scenario, knots_x, knots_y, speed=1.5) -> Trajectory:
    x = np.arange(0, 60.0001, 0.01)
    return trajectory(x / speed, x, np.interp(x, knots_x, knots_y))


def test_a_step_response_with_known_overshoot_and_settling_distance():
    """Up the 1 m step from x = 30 to 34, 0.2 m past the new line, back onto it by x = 38: within
    0.1 m of it from x = 36 on."""
    scenario = load_scenario(PATHS / "lateral_step")
    got = scores(step_response(scenario, [0, 30, 34, 38, 60], [0, 0, 1.2, 1.0, 1.0]), scenario)
    assert got["overshoot"] == pytest.approx(0.2, abs=1e-9)
    assert got["settling_distance"] == pytest.approx(6.0, abs=0.02)


def test_a_step_to_the_right(tmp_path):
    folder = tmp_path / "right_step"
    shutil.copytree(PATHS / "lateral_step", folder)
    text = (folder / "path.csv").read_text().splitlines()
    flipped = [text[0]] + [f"{x},{-float(y):.4f},{v}" for x, y, v in (line.split(",") for line in text[1:])]
    (folder / "path.csv").write_text("\n".join(flipped) + "\n")
    scenario = load_scenario(folder)
    assert paths.step_of(scenario).size == pytest.approx(-1.0)
    got = scores(step_response(scenario, [0, 30, 34, 38, 60], [0, 0, -1.2, -1.0, -1.0]), scenario)
    assert got["overshoot"] == pytest.approx(0.2, abs=1e-9)
    assert got["settling_distance"] == pytest.approx(6.0, abs=0.02)


@pytest.mark.parametrize(
    "knots_x, knots_y, overshoot, settling",
    [
        ([0, 30, 36, 60], [0, 0, 1.0, 1.0], 0.0, 6.0 * 0.9),  # no overshoot: within 0.1 m from y = 0.9
        ([0, 60], [0, 0], 0.0, 30.0),  # ignores the step: never settles
        ([0, 30, 34, 60], [0, 0, 1.3, 1.3], 0.3, 30.0),  # stays 0.3 m beyond: never settles
    ],
)
def test_step_responses(knots_x, knots_y, overshoot, settling):
    scenario = load_scenario(PATHS / "lateral_step")
    got = scores(step_response(scenario, knots_x, knots_y), scenario)
    assert (got["overshoot"], got["settling_distance"]) == pytest.approx((overshoot, settling), abs=0.02)


def test_a_run_that_stops_before_the_step_never_settles():
    scenario = load_scenario(PATHS / "lateral_step")
    x = np.linspace(0, 20, 201)
    got = scores(trajectory(x, x, np.zeros_like(x)), scenario)
    assert (got["overshoot"], got["settling_distance"]) == (0.0, 30.0)


# ---- which outputs ------------------------------------------------------------------------------


def test_the_pose_and_steering_may_be_named(tmp_path):
    scenario = load_scenario(
        PATHS / "straight_offset",
        options={"position": {"x": "car.px", "y": "car.py"}, "heading": "car.yaw", "steering": "ctrl.steer"},
    )
    path = paths.path_of(scenario)
    arc = np.linspace(0, 50, 101)
    xy = on_path(path, arc)
    names = (
        "car.px",
        "car.py",
        "car.yaw",
        "ctrl.steer",
        "other.x",
        "other.y",
        "other.theta",
        "a.delta_f",
        "b.delta_f",
    )
    values = np.column_stack(
        [xy[:, 0], xy[:, 1] + 0.5, np.full(arc.size, path.heading[0]), np.linspace(0, 1, 101)]
        + [np.zeros(arc.size)] * 5
    )
    got = scores(Trajectory(arc, names, values), scenario)
    assert got["path_error_max"] == pytest.approx(0.5 * math.cos(path.heading[0]), abs=1e-3)
    assert got["steering_effort"] == pytest.approx(1.0)


@pytest.mark.parametrize(
    "names, message",
    [
        (
            ("a.x", "a.y", "a.theta", "b.x", "b.y", "b.theta", "c.delta_f"),
            r"instances a, b have all three of x, y and theta",
        ),
        (("a.x", "a.y", "c.delta_f"), r"no instance has all three of x, y and theta; say it in space\.yaml"),
    ],
)
def test_an_ambiguous_pose_asks_for_the_option(names, message):
    scenario = load_scenario(PATHS / "straight_offset")
    with pytest.raises(DseError, match=message):
        paths.path_error_mean(Trajectory(np.arange(3.0), names, np.zeros((3, len(names)))), scenario)


def test_an_ambiguous_steering_angle_asks_for_the_option():
    scenario = load_scenario(PATHS / "straight_offset")
    names = ("v.x", "v.y", "v.theta", "a.delta_f", "b.delta_f")
    with pytest.raises(
        DseError, match=r"a\.delta_f, b\.delta_f are all named delta_f; say it in space\.yaml"
    ):
        paths.steering_effort(Trajectory(np.arange(3.0), names, np.zeros((3, 5))), scenario)


# ---- bad files ----------------------------------------------------------------------------------


@pytest.fixture
def path_copy(tmp_path):
    target = tmp_path / "straight_offset"
    shutil.copytree(PATHS / "straight_offset", target)
    return target


@pytest.mark.parametrize(
    "content, message",
    [
        ("x,y,v\n0,0,1\n1,0,1\n", r"path\.csv line 1: no column speed \(header: 'x,y,v'\)"),
        ("x,y,speed\n0,0,1\n1,nan,1\n", r"path\.csv line 3, column y: 'nan' is not a finite number"),
        ("x,y,speed\n0,0,1\n1,,1\n", r"path\.csv line 3, column y: is empty"),
        ("x,y,speed\n0,0,1\n", r"path\.csv: a path needs at least 2 waypoints, it has 1"),
        ("x,y,speed\n", r"path\.csv: a path needs at least 2 waypoints, it has 0"),
        (
            "x,y,speed\n0,0,1\n1,0,1\n\n1,0,1\n2,0,1\n",
            r"path\.csv line 5: waypoint \(1, 0\) repeats the previous one",
        ),
        ("x,y,speed\n0,0,1\n1,0,-1\n", r"path\.csv line 3, column speed: -1 is negative"),
        ("x,y,speed\n0,0,0\n1,0,0\n", r"path\.csv: every target speed is 0"),
        ("x,y,speed\n0,0,1\n1,0\n", r"path\.csv line 3: expected 3 fields"),
    ],
)
def test_a_bad_path_file_is_named(path_copy, content, message):
    (path_copy / "path.csv").write_text(content)
    with pytest.raises(DseError, match=re.escape(f"{path_copy}/") + message):
        load_scenario(path_copy)


@pytest.mark.parametrize(
    "line, message",
    [
        ("duration: -5", r"scenario\.yaml: duration: Input should be greater than 0"),
        ("step_at: 70", r"scenario\.yaml: step_at: 70 m is not inside the path \(0 to 60 m\)"),
        (
            "step_at: 30",
            r"scenario\.yaml: step_at: no straight piece parallel to the row before 30 m and offset",
        ),
        (
            "initial_pose: {x: 0, y: .nan, theta: 0}",
            r"scenario\.yaml: initial_pose\.y: Input should be a finite number",
        ),
        ("colour: red", r"scenario\.yaml: colour: Extra inputs are not permitted"),
    ],
)
def test_a_bad_scenario_yaml_is_named(path_copy, line, message):
    info = yaml.safe_load((path_copy / "scenario.yaml").read_text())
    info.update(yaml.safe_load(line))
    (path_copy / "scenario.yaml").write_text(yaml.safe_dump(info))
    with pytest.raises(DseError, match=message):
        load_scenario(path_copy)


def test_a_missing_path_file_is_named(path_copy):
    (path_copy / "path.csv").unlink()
    with pytest.raises(DseError, match=re.escape(f"scenario {path_copy}: missing path.csv")):
        load_scenario(path_copy, "path")


def test_a_bad_option_is_named(path_copy):
    with pytest.raises(DseError, match=r"scenario .*: postion: Extra inputs are not permitted"):
        load_scenario(path_copy, options={"postion": {"x": "v.x", "y": "v.y"}})


def test_path_objectives_on_another_kind_of_scenario_say_so(tmp_path):
    (tmp_path / "scenario.yaml").write_text("name: plain\n")
    traj = trajectory([0.0, 1.0], [0.0, 1.0], [0.0, 0.0])
    with pytest.raises(DseError, match=r"scenario plain is a signals scenario, not a path to follow"):
        paths.path_error_mean(traj, load_scenario(tmp_path))


# ---- the real vehicle ---------------------------------------------------------------------------


def test_the_vehicle_fmu_driving_straight_from_the_offset_start(tmp_path):
    """No controller FMU yet: the replay controller drives the vehicle straight at 1.5 m/s from the
    path's initial pose, 1 m beside the row, so it stays 1 m beside it and never steers."""
    from dse_runner.simulation.run import simulate

    log = tmp_path / "straight.csv"
    log.write_text("time,velocity,delta_f\n0,1.5,0\n")
    multimodel = tmp_path / "multimodel.yaml"
    multimodel.write_text(
        yaml.safe_dump(
            {
                "fmus": {
                    "controller": "bundled:fmus/replay_controller",
                    "vehicle": "bundled:fmus/robotti_vehicle",
                },
                "connections": {
                    "controller.velocity": ["vehicle.velocity"],
                    "controller.delta_f": ["vehicle.delta_f"],
                },
                "parameters": {"controller.file": str(log)},
                "scenario": {
                    "vehicle.x0": "initial_pose.x",
                    "vehicle.y0": "initial_pose.y",
                    "vehicle.theta0": "initial_pose.theta",
                },
                "step": 0.05,
            }
        )
    )
    result = simulate(multimodel, PATHS / "straight_offset", stop_time=20)
    assert result.objectives == pytest.approx(
        {
            "path_error_mean": 1.0,
            "path_error_max": 1.0,
            "heading_error": 0.0,
            "steering_effort": 0.0,
            "overshoot": 0.0,
            "settling_distance": 0.0,
        },
        abs=1e-3,
    )
