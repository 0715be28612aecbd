"""Blind diagnosis of any model: recordings of the mass-spring-damper with an effect concealed in them
(jobs/msd/make_diagnosis_runs.py), diagnosed from the recordings alone; the truth is read only to judge."""

from __future__ import annotations

import importlib.util

import pytest
from conftest import REPO

from dse_runner.analysis.diagnose.signal_library import diagnose_space
from dse_runner.simulation.run import simulate
from dse_runner.simulation.values import read_values
from dse_runner.sweeps.spec import load_space

PARAMETER = {
    "force_delay": ("input_delay", "msd.F", "delay"),
    "sensor_gain": ("output_gain", "msd.x", "gain"),
    "sensor_offset": ("output_offset", "msd.x", "offset"),
}


def _generator():
    spec = importlib.util.spec_from_file_location(
        "make_diagnosis_runs", REPO / "jobs" / "msd" / "make_diagnosis_runs.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _concealed(case: str) -> dict[tuple[str, str], tuple[str, float]]:
    """(effect id, target) -> (parameter, true value) of what the case conceals."""
    return {PARAMETER[k][:2]: (PARAMETER[k][2], v) for k, v in _generator().CASES[case].items()}


def _diagnose(case: str, folder, address: str) -> dict:
    space = _generator().make(case, folder)
    return diagnose_space(space, address=address).to_json()


@pytest.mark.slow
@pytest.mark.parametrize("case", ["force-late", "sensor-gain-offset"])
def test_a_concealed_effect_or_pair_is_named_with_intervals_covering_the_truth(
    case, tmp_path, dask_scheduler
):
    found = _diagnose(case, tmp_path, dask_scheduler)
    truth = _concealed(case)
    assert found["verdict"] == "explained", found["verdict_text"]
    assert {(e["id"], e["target"]) for e in found["effects"]} == set(truth)
    for effect in found["effects"]:
        kind, value = truth[(effect["id"], effect["target"])]
        low, high = effect["interval"][kind]
        assert low <= value <= high, (effect, value)
    assert found["held_out_after"] < 2.0 < found["held_out_before"]
    located = found["case"]["located"]
    assert located["method"] and located["windows"]
    assert all(r["floors_after"] < r["floors_before"] for r in located["by_scenario"])
    if len(truth) > 1:  # a pair is found through the screen, not by fitting every pair
        pairs = found["screen"]
        assert pairs["predicted"] > len(pairs["screened"]) >= len(pairs["fitted"])
    assert (tmp_path / "out" / "diagnosis-report.md").is_file()
    page = (tmp_path / "out" / "diagnosis.html").read_text()  # the same report as one page, figures inside
    assert page.count("data:image/png;base64,") == len(found["files"]["figures"]) > 0
    _replays(found, tmp_path)


def _replays(found: dict, folder) -> None:
    """The diagnosed model's values file runs again as the diagnosed model: every scenario simulated with it
    misses its recording by about the noise."""
    space = load_space(folder / "space.yaml")
    values = read_values(found["files"]["values"])
    assert values == found["fitted"]["parameters"]
    noise = found["case"]["compared"][0]["noise"]
    for scenario in space.scenarios:
        rmse = {"rmse": {"signal": "msd.x", "recorded": "x", "metric": "rmse"}}
        result = simulate(space.plan, scenario, values=values, experiment=space.experiment, objectives=rmse)
        assert result.objectives["rmse"] < 2.0 * noise, (scenario.name, result.objectives["rmse"], noise)


@pytest.mark.slow
def test_recordings_of_a_model_that_misses_nothing_name_nothing(tmp_path, dask_scheduler):
    found = _diagnose("clean", tmp_path, dask_scheduler)
    assert found["verdict"] == "none", found["verdict_text"]
    assert [e["id"] for e in found["effects"]] == ["none"]
    assert found["held_out_before"] < 2.0


@pytest.mark.slow
def test_an_actuator_that_clips_is_named_as_its_two_bounds_not_imitated(tmp_path, dask_scheduler):
    """The force clipped to ±1.2 N before the plant sees it (made by the generator with numpy, not by the
    master's effects). Alone, neither bound explains it (the calibration absorbs a one-sided clip), so
    the answer grows from the best pair to both sides; a gain fitted to 1 on the way is not claimed (the
    noise rule), and nothing is imitated by a polynomial."""
    found = _diagnose("force-clipped", tmp_path, dask_scheduler)
    assert found["verdict"] == "explained", found["verdict_text"]
    named = {(e["id"], e["target"]): e for e in found["effects"]}
    assert set(named) == {("input_max", "msd.F"), ("input_min", "msd.F")}, found["verdict_text"]
    for effect, bound in (("input_max", 1.2), ("input_min", -1.2)):
        low, high = named[(effect, "msd.F")]["interval"][effect.split("_")[1]]
        assert low <= bound <= high
    assert found["held_out_after"] < 1.5 and found["growth"][0]["accepted"]
    _replays(found, tmp_path)
