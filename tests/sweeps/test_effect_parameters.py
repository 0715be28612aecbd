"""A signal effect is a parameter like any other: a sweep varies it, the store
keeps it, the ranking finds it."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from dse_runner.errors import DseError
from dse_runner.simulation.run import simulate
from dse_runner.simulation.scenario import Scenario
from dse_runner.simulation.trajectory import Series
from dse_runner.sweeps import store
from dse_runner.sweeps.rank import rank
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit

DELAY = "input_delay(msd.F)"


def _study(folder, delays, cluster) -> object:
    """The mass-spring-damper pushed by a force log, recorded as if the force had acted 0.3 s late."""
    from conftest import REPO

    t = np.arange(0.0, 8.0, 0.1)
    force = np.where((t >= 1.0) & (t < 4.0), 2.0, 0.0)
    np.savetxt(folder / "force.csv", np.column_stack([t, force]), delimiter=",", header="time,F", comments="")
    truth = simulate(
        REPO / "jobs" / "msd" / "multimodel.yaml",
        Scenario("push", inputs={"msd.F": Series(t, force, "hold")}, stop_time=8.0, step=0.02),
        {"msd.x0": 0.0, DELAY: 0.3},
    )
    np.savetxt(
        folder / "recorded.csv",
        np.column_stack([truth.time, truth.outputs["msd.x"]]),
        delimiter=",",
        header="time,x",
        comments="",
    )
    spec = {
        "name": "delay-sweep",
        "multimodel": str(REPO / "jobs" / "msd" / "multimodel.yaml"),
        "experiment": {"step": 0.02, "stop_time": 8.0},
        "scenarios": [
            {
                "name": "push",
                "inputs": {"msd.F": {"csv": "force.csv", "interpolation": "hold"}},
                "parameters": {"msd.x0": 0.0},
                "recorded": "recorded.csv",
            }
        ],
        "parameters": {DELAY: delays},
        "objectives": {"position_rmse": {"signal": "msd.x", "recorded": "x", "metric": "rmse"}},
        "output": str(folder / "out"),
        "cluster": cluster,
    }
    (folder / "space.yaml").write_text(yaml.safe_dump(spec))
    return folder / "space.yaml"


@pytest.mark.slow
def test_a_sweep_over_an_input_delay_finds_the_recorded_one(tmp_path, dask_scheduler):
    space = load_space(_study(tmp_path, [0.0, 0.1, 0.2, 0.3, 0.4, 0.5], {"address": dask_scheduler}))
    report = submit(space)
    assert report.failed == 0
    rows = store.read_results(space.output, space.name, [DELAY, "position_rmse"])
    assert sorted(rows[DELAY]) == [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]
    assert rank(space.output).best[DELAY] == 0.3


def test_an_effect_on_an_input_no_scenario_drives_fails_when_the_spec_loads(tmp_path):
    path = _study(tmp_path, [0.0, 0.1], {"n_workers": 1})
    spec = yaml.safe_load(path.read_text())
    spec["parameters"] = {"input_lag(msd.k)": [0.0, 0.1]}
    path.write_text(yaml.safe_dump(spec))
    with pytest.raises(
        DseError, match=r"parameters\.input_lag\(msd\.k\): scenario push does not drive msd\.k"
    ):
        load_space(path)
    spec["parameters"] = {DELAY: [-0.1, 0.1]}
    path.write_text(yaml.safe_dump(spec))
    with pytest.raises(DseError, match=r"parameters\.input_delay\(msd\.F\): a delay cannot be negative"):
        load_space(path)
