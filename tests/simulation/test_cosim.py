"""Our master against libcosim, and the master's own guarantees."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import FMU_SOURCES, SCENARIOS, all_scenarios

from dse_runner import DseError
from dse_runner.cases.fielddata import position_of, simulated_xy
from dse_runner.simulation.crosscheck import run_libcosim
from dse_runner.simulation.run import simulate
from dse_runner.simulation.scenario import load_scenario

CALIBRATED = {"vehicle.mass": 1000.0, "vehicle.cAlphaF": 38000.0, "vehicle.mu": 0.3}


@pytest.mark.parametrize("name", all_scenarios())
def test_agrees_with_libcosim(plan, name):
    scenario = load_scenario(SCENARIOS / name)
    ours = simulate(plan, scenario, CALIBRATED)
    theirs = run_libcosim(plan, ours.values, scenario.stop_time, ours.step)
    at = np.searchsorted(ours.trajectory.time, theirs.time - 1e-9)
    assert np.abs(ours.trajectory.time[at] - theirs.time).max() < 1e-9
    assert len(theirs.time) >= len(ours.trajectory.time) - 2  # all but the start and a partial last step
    for column in ("vehicle.x", "vehicle.y"):
        gap = np.abs(ours.trajectory.column(column)[at] - theirs.column(column))
        assert gap.max() < 1e-9, f"{column} differs by {gap.max():.3g} m"
    moved = np.hypot(*(c[-1] - c[0] for c in simulated_xy(ours.trajectory, scenario)))
    assert moved > 5.0  # the comparison is over a real drive, not a vehicle at rest


def test_reused_instances_give_identical_runs(plan):
    """Instances are reset between runs: overrides do not leak into the next run."""
    first = simulate(plan, SCENARIOS / "sin2")
    simulate(plan, SCENARIOS / "turn_ramp1", {"vehicle.mass": 3000.0, "vehicle.mu": 0.7})
    again = simulate(plan, SCENARIOS / "sin2")
    assert np.array_equal(first.trajectory.values, again.trajectory.values)


def test_parameters_change_the_result(plan):
    base = simulate(plan, SCENARIOS / "sin1")
    heavy = simulate(plan, SCENARIOS / "sin1", {"vehicle.mass": 3000.0, "vehicle.mu": 0.3})
    assert heavy.objectives["cross_track_error"] != base.objectives["cross_track_error"]


def test_default_step_is_the_control_log_period(plan):
    result = simulate(plan, SCENARIOS / "speed_step1")
    assert result.step == pytest.approx(0.05)
    assert result.scenario.natural_step == pytest.approx(0.05)
    assert result.trajectory.time[-1] == pytest.approx(result.scenario.stop_time)
    assert np.all(np.diff(result.trajectory.time) <= 0.05 + 1e-12)


def test_replayed_commands_are_held_from_their_row_time(plan):
    """The controller's outputs at each communication point are the log's rows, zero-order held."""
    scenario = load_scenario(SCENARIOS / "turn_ramp1")
    result = simulate(plan, scenario, step=0.025)  # two communication points per log row
    log = np.loadtxt(scenario.files["steering_inputs"], delimiter=",", skiprows=1)
    row = np.searchsorted(log[:, 0], result.trajectory.time + 1e-9, side="right") - 1
    assert np.array_equal(result.trajectory.column("controller.delta_f"), log[row, 2])
    assert np.array_equal(result.trajectory.column("controller.velocity"), log[row, 1])


def test_into_cps_mm_json_gives_the_same_result(tmp_path, plan):
    mm = {
        "fmus": {
            "{ctrl}": str(FMU_SOURCES / "replay_controller"),
            "{veh}": str(FMU_SOURCES / "robotti_vehicle"),
        },
        "connections": {
            "{ctrl}.controller.velocity": ["{veh}.vehicle.velocity"],
            "{ctrl}.controller.delta_f": ["{veh}.vehicle.delta_f"],
            "{veh}.vehicle.x": ["{ctrl}.controller.x"],
        },
        "parameters": {"{veh}.vehicle.mass": 1800},
        "scenario": {"controller.file": "steering_inputs", "vehicle.theta0": "initial_pose.theta"},
    }
    path = tmp_path / "mm.json"
    path.write_text(json.dumps(mm))
    from_json = simulate(path, SCENARIOS / "sin3")
    from_yaml = simulate(plan, SCENARIOS / "sin3", {"vehicle.mass": 1800})
    # the position compared with GPS: the only instance with outputs x and y, found without being named
    assert position_of(from_json.trajectory.names, from_json.scenario) == ("vehicle.x", "vehicle.y")
    assert np.allclose(
        simulated_xy(from_json.trajectory, from_json.scenario),
        simulated_xy(from_yaml.trajectory, from_yaml.scenario),
        atol=1e-12,
    )
    assert from_json.objectives == pytest.approx(from_yaml.objectives, abs=1e-12)


def test_instances_are_created_once_per_process_and_reused(plan):
    from dse_runner.simulation import fmu as fmus

    simulate(plan, SCENARIOS / "sin1")
    before = {key: id(instance) for key, instance in fmus._INSTANCES.items()}
    extracted = dict(fmus._LOADED)
    simulate(plan, SCENARIOS / "speed_ramp2", CALIBRATED)
    assert {key: id(instance) for key, instance in fmus._INSTANCES.items()} == before
    assert fmus._LOADED == extracted


def test_three_fmus_two_instances_of_one(tmp_path, plan):
    """One controller drives two vehicles, a light and a heavy one, in the same co-simulation."""
    fmus_dir = FMU_SOURCES
    mm = {
        "fmus": {
            "controller": str(fmus_dir / "replay_controller"),
            "light": str(fmus_dir / "robotti_vehicle"),
            "heavy": str(fmus_dir / "robotti_vehicle"),
        },
        "connections": {
            "controller.velocity": ["light.velocity", "heavy.velocity"],
            "controller.delta_f": ["light.delta_f", "heavy.delta_f"],
        },
        "parameters": {"light.mass": 1000, "heavy.mass": 3000, "light.mu": 0.3, "heavy.mu": 0.3},
        "scenario": {"controller.file": "steering_inputs"},
    }
    path = tmp_path / "three.yaml"
    path.write_text(json.dumps(mm))  # JSON is YAML
    with pytest.raises(DseError, match="which outputs are the position.*instances heavy, light have both"):
        simulate(path, SCENARIOS / "sin1")  # two vehicles: the GPS position must be named
    tracked = load_scenario(SCENARIOS / "sin1", options={"position": {"x": "heavy.x", "y": "heavy.y"}})
    both = simulate(path, tracked)
    for name, mass in (("light", 1000.0), ("heavy", 3000.0)):
        alone = simulate(
            plan, SCENARIOS / "sin1", {"vehicle.mass": mass, "vehicle.mu": 0.3, "vehicle.theta0": 0.0}
        )
        for axis in ("x", "y"):
            assert np.allclose(
                both.trajectory.column(f"{name}.{axis}"),
                alone.trajectory.column(f"vehicle.{axis}"),
                atol=1e-12,
            )
        if name == "heavy":  # the objectives compare the named position
            assert both.objectives == pytest.approx(alone.objectives, abs=1e-9)
    assert not np.allclose(both.trajectory.column("light.x"), both.trajectory.column("heavy.x"))
