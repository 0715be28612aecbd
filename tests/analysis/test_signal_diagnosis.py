"""Diagnosis for any model: the signal-effect library names a concealed effect from recordings alone."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from dse_runner.analysis.diagnose.signal_library import diagnose_space
from dse_runner.errors import DseError
from dse_runner.simulation.run import simulate
from dse_runner.simulation.scenario import Scenario

# name: (force on, force off, force [N], released from x0 [m]). A run released from rest and pushed later
from dse_runner.simulation.trajectory import Series

# cannot tell a late force from a late sensor (its response merely starts later); one released away from
# rest can: the sensor delays the release as well, the force does not.
PUSHES = {
    "early": (1.0, 3.0, 2.0, 0.05),
    "long": (0.5, 5.0, 1.0, 0.0),
    "late": (3.0, 4.0, 3.0, -0.05),
    "twice": (1.0, 2.0, -2.0, 0.1),
}
STOP, STEP = 8.0, 0.02


def _force(start: float, stop: float, size: float, x0: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, STOP, 0.05)
    return t, np.where((t >= start) & (t < stop), size, 0.0)


def _recorded_study(folder, truth: dict[str, float], noise: float, seed: int):
    """Runs of a mass-spring-damper pushed by logged forces, recorded with ``truth`` concealed in them
    (k, c and any signal effect), plus white noise; and a space that calibrates k and c on them."""
    from conftest import REPO

    model = REPO / "jobs" / "msd" / "multimodel.yaml"
    rng = np.random.default_rng(seed)
    scenarios = []
    for name, push in PUSHES.items():
        t, force = _force(*push)
        np.savetxt(
            folder / f"{name}-force.csv",
            np.column_stack([t, force]),
            delimiter=",",
            header="time,F",
            comments="",
        )
        run = simulate(
            model,
            Scenario(name, inputs={"msd.F": Series(t, force, "hold")}, stop_time=STOP, step=STEP),
            {"msd.x0": push[3], **truth},
        )
        x = run.outputs["msd.x"][::5] + rng.normal(0.0, noise, run.time[::5].size)
        np.savetxt(
            folder / f"{name}-x.csv",
            np.column_stack([run.time[::5], x]),
            delimiter=",",
            header="time,x",
            comments="",
        )
        scenarios.append(
            {
                "name": name,
                "inputs": {"msd.F": {"csv": f"{name}-force.csv", "interpolation": "hold"}},
                "parameters": {"msd.x0": push[3]},
                "recorded": f"{name}-x.csv",
            }
        )
    spec = {
        "name": "msd-pushed",
        "multimodel": str(model),
        "experiment": {"stop_time": STOP, "step": STEP},
        "scenarios": scenarios,
        "parameters": {"msd.k": {"start": 8, "stop": 16, "step": 2}, "msd.c": [0.4, 0.8, 1.2]},
        "objectives": {"position": {"signal": "msd.x", "recorded": "x", "metric": "rmse"}},
        "output": str(folder / "out"),
        "cluster": {"n_workers": 2},
    }
    (folder / "space.yaml").write_text(yaml.safe_dump(spec))
    return folder / "space.yaml"


@pytest.mark.slow
def test_a_concealed_actuator_delay_is_named_and_sized(tmp_path, dask_scheduler):
    space = _recorded_study(tmp_path, {"msd.k": 12.5, "msd.c": 0.7, "input_delay(msd.F)": 0.35}, 0.002, 1)
    found = diagnose_space(space, address=dask_scheduler).to_json()
    assert found["verdict"] == "explained", found
    (effect,) = found["effects"]
    assert (effect["id"], effect["target"]) == ("input_delay", "msd.F")
    low, high = effect["interval"]["delay"]  # at least one communication step either side: its resolution
    assert low <= 0.35 <= high and high - low < 0.1 and effect["resolution"] == STEP
    assert found["held_out_after"] < 2.0 < found["held_out_before"]


@pytest.mark.slow
def test_a_model_that_misses_nothing_claims_nothing(tmp_path, dask_scheduler):
    space = _recorded_study(tmp_path, {"msd.k": 12.5, "msd.c": 0.7}, 0.002, 2)
    found = diagnose_space(space, address=dask_scheduler).to_json()
    assert found["verdict"] == "none", found
    assert [e["id"] for e in found["effects"]] == ["none"]


@pytest.mark.slow
def test_the_command_gives_strict_json_and_resumes_from_the_store(tmp_path, dask_scheduler):
    from conftest import dse_runner, strict_loads

    space = _recorded_study(tmp_path, {"msd.k": 12.5, "msd.c": 0.7, "output_offset(msd.x)": 0.01}, 0.002, 3)
    first = dse_runner(
        "diagnose", "--space", space, "--out", tmp_path / "diag", "--scheduler", dask_scheduler, "--json"
    )
    assert first.returncode == 0, first.stderr
    found = strict_loads(first.stdout)
    assert [(e["id"], e["target"]) for e in found["effects"]] == [("output_offset", "msd.x")]
    written = sorted((tmp_path / "diag").rglob("*.parquet"))  # each chunk of simulations writes a file
    assert written
    again = dse_runner(
        "diagnose", "--space", space, "--out", tmp_path / "diag", "--scheduler", dask_scheduler, "--json"
    )
    assert strict_loads(again.stdout) == found
    assert sorted((tmp_path / "diag").rglob("*.parquet")) == written  # nothing simulated again


def test_a_space_that_compares_nothing_is_told_what_diagnosis_needs(tmp_path):
    space = _recorded_study(tmp_path, {"msd.k": 12.5, "msd.c": 0.7}, 0.002, 4)
    spec = yaml.safe_load(space.read_text())
    spec["objectives"] = {"x_max": {"signal": "msd.x", "reduce": "max"}}
    space.write_text(yaml.safe_dump(spec))
    with pytest.raises(DseError, match=r"diagnosis compares signals with recordings: give an objective"):
        diagnose_space(space)
