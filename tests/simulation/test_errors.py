"""Bad input gets a clear error that names the culprit."""

from __future__ import annotations

import pytest
import yaml
from conftest import MULTIMODEL, REPO, SCENARIOS

from dse_runner import DseError
from dse_runner.simulation.run import simulate


def write_multimodel(tmp_path, **changes):
    data = yaml.safe_load(MULTIMODEL.read_text())
    data.update(changes)
    path = tmp_path / "mm.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_missing_fmu(tmp_path):
    path = write_multimodel(
        tmp_path, fmus={"controller": "nowhere/replay.fmu", "vehicle": "bundled:fmus/robotti_vehicle"}
    )
    with pytest.raises(
        DseError,
        match=r"^instance 'controller' of the multi-model names 'nowhere/replay\.fmu': "
        r"FMU not found: .*nowhere/replay\.fmu$",
    ):
        simulate(path, SCENARIOS / "sin1")


def test_a_missing_fmu_file_given_alone_says_how_one_is_made(tmp_path):
    with pytest.raises(DseError, match=r"FMU not found: .*tank\.fmu \(`dse-runner build-fmus"):
        simulate(tmp_path / "tank.fmu")


def test_an_fmu_source_folder_is_simulated_as_its_fmu():
    """The README's Python example: C sources are built on first use and the
    instance is named after the folder."""
    tank = simulate(REPO / "jobs" / "watertank" / "fmus" / "tank", stop_time=50, values={"valvecontrol": 1.0})
    assert list(tank.outputs) == ["tank.level"] and tank.time[-1] == 50


def test_unknown_variable_in_connection(tmp_path):
    path = write_multimodel(tmp_path, connections={"controller.velocity": ["vehicle.velocty"]})
    with pytest.raises(DseError, match=r"unknown variable 'vehicle\.velocty'.*did you mean velocity"):
        simulate(path, SCENARIOS / "sin1")


def test_unknown_instance_in_connection(tmp_path):
    path = write_multimodel(tmp_path, connections={"controler.velocity": ["vehicle.velocity"]})
    with pytest.raises(
        DseError, match=r"'controler\.velocity' names instance 'controler'.*did you mean controller"
    ):
        simulate(path, SCENARIOS / "sin1")


def test_unknown_variable_in_set(plan):
    with pytest.raises(DseError, match=r"unknown variable 'vehicle\.mas'.*did you mean mass"):
        simulate(plan, SCENARIOS / "sin1", {"vehicle.mas": 1500})


def test_output_cannot_be_set(plan):
    with pytest.raises(DseError, match=r"'vehicle\.x' is an output.*cannot be set"):
        simulate(plan, SCENARIOS / "sin1", {"vehicle.x": 3})


def test_wrong_value_type(plan):
    with pytest.raises(DseError, match=r"vehicle\.mass: 'heavy' is not a valid Real"):
        simulate(plan, SCENARIOS / "sin1", {"vehicle.mass": "heavy"})


def test_bad_multimodel_key(tmp_path):
    path = write_multimodel(tmp_path, stepsize=0.1)
    with pytest.raises(DseError, match=r"mm\.yaml: stepsize: Extra inputs are not permitted"):
        simulate(path, SCENARIOS / "sin1")


def damage(scenario_dir, line_number: int, text: str):
    path = scenario_dir / "steering_inputs.csv"
    lines = path.read_text().splitlines()
    lines[line_number - 1] = text
    path.write_text("\n".join(lines) + "\n")
    return path


def test_malformed_csv_read_by_the_controller_fmu(plan, scenario_copy, tmp_path):
    """A log given straight to the FMU (not through the scenario, which checks its files on
    loading) is read by the FMU alone: its error reaches the user."""
    folder = scenario_copy("sin1")
    path = damage(folder, 7, "0.30,fast,0.0").rename(tmp_path / "steer.csv")
    with pytest.raises(
        DseError,
        match=rf"controller \(.*\): fmi2EnterInitializationMode failed.*"
        rf"{path} line 7: field 2 is not a number",
    ):
        simulate(plan, SCENARIOS / "sin1", {"controller.file": str(path)}, step=0.05)


def test_csv_without_expected_column_read_by_the_controller_fmu(plan, scenario_copy, tmp_path):
    folder = scenario_copy("sin1")
    path = damage(folder, 1, "time,speed,delta_f").rename(tmp_path / "steer.csv")
    with pytest.raises(DseError, match=rf"{path} line 1: header has no 'velocity' column"):
        simulate(plan, SCENARIOS / "sin1", {"controller.file": str(path)}, step=0.05)


def test_malformed_csv_read_when_the_scenario_loads(plan, scenario_copy):
    folder = scenario_copy("sin1")
    path = damage(folder, 9, "0.40,1.0")
    with pytest.raises(DseError, match=rf"{path} line 9: expected 3 fields"):
        simulate(plan, folder)


def test_missing_steering_file_named_by_the_fmu(plan, scenario_copy):
    folder = scenario_copy("sin1")
    with pytest.raises(DseError, match=r"cannot open /nonexistent/steer\.csv: No such file"):
        simulate(plan, folder, {"controller.file": "/nonexistent/steer.csv"}, step=0.05)


def test_missing_scenario_file(plan, scenario_copy):
    folder = scenario_copy("sin1")
    (folder / "gps_position.csv").unlink()
    with pytest.raises(DseError, match=r"missing gps_position\.csv"):
        simulate(plan, folder)


def test_diverging_fmu_is_reported_and_instance_recovers(plan):
    with pytest.raises(DseError, match=r"vehicle .*diverged"):
        simulate(
            plan,
            SCENARIOS / "sin1",
            {
                "vehicle.rk4_step": 0.05,
                "vehicle.r_gyr": 0.001,
                "vehicle.cAlphaF": 1e9,
                "vehicle.cAlphaR": 1e9,
                "vehicle.mu": 1e6,
            },
        )
    # The failed instance was replaced: the next run is normal.
    assert simulate(plan, SCENARIOS / "sin1").objectives["cross_track_error"] < 100
