"""How FMUs live across runs (lifecycle.py, isolation.py): a fresh process per run gives the numbers of a
reused instance, a crash there is one error, and a reset that changes a run is caught by the probe."""

from __future__ import annotations

import time

import numpy as np
import pytest
import yaml
from conftest import MULTIMODEL, REPO, SCENARIOS

from dse_runner.simulation import isolation, lifecycle
from dse_runner.simulation.run import as_plan, simulate
from dse_runner.simulation.trajectory import CosimError

CALIBRATED = {"vehicle.mass": 1000.0, "vehicle.cAlphaF": 38000.0, "vehicle.mu": 0.3}


def in_fresh_processes(folder, source=MULTIMODEL, **more) -> str:
    data = yaml.safe_load(source.read_text())
    data["fmus"] = {
        name: (path if path.startswith("bundled:") else str((source.parent / path).resolve()))
        for name, path in data["fmus"].items()
    }
    data["instances"] = {name: {"lifecycle": "process"} for name in data["fmus"]}
    data.update(more)
    path = folder / "multimodel.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


def test_a_fresh_process_per_run_gives_the_numbers_of_a_reused_instance(tmp_path):
    fresh = as_plan(in_fresh_processes(tmp_path))
    reused = as_plan(MULTIMODEL)
    for point in (CALIBRATED, {**CALIBRATED, "vehicle.mass": 2500.0}, CALIBRATED):
        a = simulate(fresh, SCENARIOS / "sin1", point)
        b = simulate(reused, SCENARIOS / "sin1", point)
        assert a.fresh_process and not b.fresh_process
        assert np.array_equal(a.trajectory.values, b.trajectory.values)
        assert a.objectives == b.objectives
    assert "lifecycle: process" in a.lifecycle["vehicle"].reason


def test_a_crash_in_a_fresh_process_is_one_error_and_the_next_run_goes_on(tmp_path):
    multimodel = tmp_path / "crasher.yaml"
    multimodel.write_text(
        yaml.safe_dump(
            {
                "fmus": {"crasher": str(REPO / "tests" / "fmus" / "crasher")},
                "parameters": {"crasher.crash_at": 1.0},
                "instances": {"crasher": {"lifecycle": "process"}},
            }
        )
    )
    plan = as_plan(multimodel)
    with pytest.raises(CosimError, match="SIGSEGV"):
        simulate(plan, values={"crasher.k": 1.0}, stop_time=1, step=0.1)
    assert simulate(plan, values={"crasher.k": 0.0, "crasher.velocity": 2.0}, stop_time=1, step=0.1).outputs[
        "crasher.x"
    ][-1] == pytest.approx(2.0)


def test_a_run_asked_for_a_fresh_process_crashes_only_that_process(tmp_path):
    """What a sweep does with a task its workers died under: the FMU is trusted with reuse, yet this run
    goes to a process of its own, whose death is the run's error; this process goes on."""
    multimodel = tmp_path / "crasher.yaml"
    multimodel.write_text(
        yaml.safe_dump(
            {
                "fmus": {"crasher": str(REPO / "tests" / "fmus" / "crasher")},
                "parameters": {"crasher.crash_at": 1.0},
            }
        )
    )
    plan = as_plan(multimodel)
    innocent = {"crasher.k": 0.0, "crasher.velocity": 2.0}
    here = simulate(plan, values=innocent, stop_time=1, step=0.1)
    assert not here.fresh_process
    with pytest.raises(CosimError, match="SIGSEGV"):
        simulate(plan, values={"crasher.k": 1.0}, stop_time=1, step=0.1, fresh_process=True)
    alone = simulate(plan, values=innocent, stop_time=1, step=0.1, fresh_process=True)
    assert alone.fresh_process and alone.lifecycle["crasher"].mode == "process"
    assert np.array_equal(alone.trajectory.values, here.trajectory.values)


def test_a_run_hung_inside_an_fmu_call_in_a_fresh_process_is_killed_after_its_timeout(tmp_path, monkeypatch):
    """The step loop checks its timeout between steps; a step that never returns is stopped by killing the
    fresh process (here a step sleeps 10 s, and the timeout is 1 s plus a grace of 1 s)."""
    multimodel = tmp_path / "sleeper.yaml"
    multimodel.write_text(
        yaml.safe_dump(
            {
                "fmus": {"sleeper": str(REPO / "tests" / "fmus" / "sleeper")},
                "instances": {"sleeper": {"lifecycle": "process"}},
            }
        )
    )
    plan = as_plan(multimodel)
    monkeypatch.setattr(isolation, "KILL_GRACE", 1.0)
    began = time.monotonic()
    with pytest.raises(CosimError, match=r"did not end within 2 s \(hung inside an FMU call\)"):
        simulate(plan, values={"sleeper.pause": 10.0}, stop_time=1, step=0.5, timeout=1.0)
    assert time.monotonic() - began < 9  # killed at 2 s, not waited for to the first step's end at 10 s
    assert simulate(plan, values={"sleeper.velocity": 2.0}, stop_time=1, step=0.5, timeout=1.0).outputs[
        "sleeper.x"
    ][-1] == pytest.approx(2.0)


def test_the_probe_finds_a_reset_that_changes_the_next_run():
    """The 20-sim mass-spring-damper of INTO-CPS's example stays at its initial position after fmi2Reset."""
    from support.wild import WILD

    path = WILD / "mass_spring_damper/FMUs/20-Sim/MassSpringDamper1.fmu"
    if not path.is_file():
        pytest.skip(f"{path} (shared/fmus-wild) is not beside the checkout")
    runner, why = lifecycle._alone(as_plan(path))
    assert runner is not None, why
    verdict = lifecycle.probe(runner, {}, [path])
    assert verdict.mode == "process" and "differed from a fresh process" in verdict.reason


def test_the_probe_keeps_reusing_an_fmu_whose_reset_is_clean(tmp_path):
    multimodel = tmp_path / "vanderpol.yaml"
    multimodel.write_text(yaml.safe_dump({"fmus": {"v": str(REPO / "benchmarks" / "fmus" / "vanderpol")}}))
    plan = as_plan(multimodel)
    runner, why = lifecycle._alone(plan)
    assert runner is not None, why
    assert lifecycle.probe(runner, {}, list(plan.fmu_paths.values())).mode == "reset"
