"""An FMU that asks to stop early (FMI 2.0: fmi2DoStep's fmi2Discard with fmi2Terminated; FMI 3.0:
fmi3DoStep's terminateSimulation; model exchange: the event update's): the run is kept up to that time,
as FMPy's simulate_fmu keeps it, through both loops, and the command says where it stopped.

The FMUs are our own, like the Reference FMUs' Stair (which asks to stop at t = 9): tests/fmus/stair2 (FMI 2.0
co-simulation), stair3 (FMI 3.0) and stair_me (FMI 2.0 model exchange), each asking to stop at its parameter
stop_at."""

from __future__ import annotations

import json
from pathlib import Path

import fmpy
import numpy as np
import pytest
from conftest import REPO, dse_runner, strict_loads

from dse_runner.simulation.build import build_fmu
from dse_runner.simulation.run import simulate
from dse_runner.simulation.trajectory import Stop

FMUS = REPO / "tests" / "fmus"
STAIRS = ("stair2", "stair3", "stair_me")
TYPES3 = FMUS / "types3"


def fmpy_result(name: str, stop_at: float) -> np.ndarray:
    """FMPy's own simulate_fmu on the same FMU and experiment: the reference."""
    return fmpy.simulate_fmu(
        str(build_fmu(FMUS / name)), stop_time=10.0, output_interval=0.2, start_values={"stop_at": stop_at}
    )


@pytest.mark.parametrize("loop", ["native", "python"])
@pytest.mark.parametrize("stop_at", [9.0, 8.9])  # on a communication point, and between two
@pytest.mark.parametrize("name", STAIRS)
def test_the_run_is_kept_up_to_the_stop_as_fmpy_keeps_it(name, stop_at, loop):
    reference = fmpy_result(name, stop_at)
    result = simulate(FMUS / name, values={"stop_at": stop_at}, stop_time=10.0, step=0.2, loop=loop)
    trajectory = result.trajectory
    assert len(trajectory.time) == len(reference) == 46
    assert np.allclose(trajectory.time, reference["time"], rtol=0, atol=1e-12)
    for signal in ("ramp", "counter"):
        assert np.allclose(trajectory.column(f"{name}.{signal}"), reference[signal], rtol=0, atol=1e-9), (
            signal
        )
    # FMI 2 stops where fmi2LastSuccessfulTime says, FMI 3 (no early return) at the communication point
    expected = 9.0 if name == "stair3" else stop_at
    assert trajectory.stopped == Stop(name, pytest.approx(expected)) and trajectory.end == pytest.approx(
        expected
    )
    assert trajectory.stopped.message == f"the FMU asked to stop at t = {expected:g}"


@pytest.mark.parametrize("name", STAIRS)
def test_a_run_that_ends_before_the_stop_is_whole_and_an_instance_runs_again_after_a_stop(name):
    stopped = simulate(FMUS / name, stop_time=10.0, step=0.2)  # at stop_at = 9
    whole = simulate(FMUS / name, values={"stop_at": 20.0}, stop_time=10.0, step=0.2)  # the reset instance
    assert stopped.trajectory.stopped is not None and whole.trajectory.stopped is None
    assert len(whole.trajectory.time) == 51 and whole.trajectory.end == 10.0
    assert whole.trajectory.final()[f"{name}.counter"] == 11.0


def test_objectives_are_over_the_span_the_run_reached():
    result = simulate(
        FMUS / "stair2",
        stop_time=10.0,
        step=0.5,
        objectives={
            "mean": {"signal": "counter", "reduce": "mean"},
            "last": {"signal": "ramp", "reduce": "final"},
        },
    )
    assert result.objectives["last"] == 9.0
    time, counter = result.trajectory.time, result.trajectory.column("stair2.counter")
    assert result.objectives["mean"] == pytest.approx(np.trapezoid(counter, time) / 9.0)


def write_multimodel(folder: Path, fmus: dict, parameters: dict | None = None) -> Path:
    path = folder / "multimodel.json"
    spec = {"fmus": {k: str(v) for k, v in fmus.items()}, "connections": {}, "parameters": parameters or {}}
    path.write_text(json.dumps(spec))
    return path


@pytest.mark.parametrize(
    "fmus",
    [
        {"a": FMUS / "stair2", "b": FMUS / "stair2"},  # FMI 2 Discard, in the C loop of several float64 units
        {"a": FMUS / "stair3", "b": TYPES3},  # FMI 3 terminateSimulation, in the C loop with strings
    ],
    ids=["fmi2-units", "fmi3-strings"],
)
def test_in_a_multimodel_both_loops_stop_alike(tmp_path, fmus):
    model = write_multimodel(tmp_path, fmus, {"b.stop_at": 20.0} if fmus["b"] != TYPES3 else {})
    python, ours = (simulate(model, stop_time=10.0, step=0.2, loop=loop) for loop in ("python", "native"))
    for result in (python, ours):
        assert result.trajectory.stopped == Stop("a", 9.0) and len(result.trajectory.time) == 46
    assert np.array_equal(python.trajectory.time, ours.trajectory.time)
    assert python.trajectory.values.tobytes() == ours.trajectory.values.tobytes()
    assert python.trajectory.texts == ours.trajectory.texts
    assert all(len(texts) == 46 for texts in ours.trajectory.texts.values())


def test_a_run_in_a_fresh_process_keeps_its_stop():
    result = simulate(FMUS / "stair3", stop_time=10.0, step=0.2, fresh_process=True)
    assert result.trajectory.stopped == Stop("stair3", 9.0) and len(result.trajectory.time) == 46


def test_a_stop_in_initialization_is_still_a_failure():
    from dse_runner.errors import DseError

    with pytest.raises(DseError, match="requested termination at t=0"):
        simulate(FMUS / "stair_me", values={"stop_at": 0.0}, stop_time=10.0, step=0.2)


@pytest.mark.parametrize("name", ["stair2", "stair3"])
def test_simulate_says_where_the_fmu_stopped_in_text_and_json(name):
    text = dse_runner("simulate", FMUS / name, "--stop-time", "10", "--step", "0.2")
    assert text.returncode == 0, text.stderr
    assert (
        f"{name}: the FMU asked to stop at t = 9 (of 10 s): the results and objectives are up to t = 9"
        in (text.stdout)
    )
    done = dse_runner("simulate", FMUS / name, "--stop-time", "10", "--step", "0.2", "--json")
    assert done.returncode == 0, done.stderr
    report = strict_loads(done.stdout)
    assert report["stopped"] == {"instance": name, "time": 9.0, "message": "the FMU asked to stop at t = 9"}
    assert (report["stop_time"], report["end_time"], report["final"][f"{name}.counter"]) == (10.0, 9.0, 10.0)


def test_simulate_json_of_a_whole_run_says_no_stop():
    done = dse_runner("simulate", FMUS / "stair2", "--stop-time", "5", "--step", "0.5", "--json")
    report = strict_loads(done.stdout)
    assert report["stopped"] is None and report["end_time"] == 5.0
