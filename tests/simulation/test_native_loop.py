"""The native step loop (native_loop.c) against the Python loop, its reference: bit-identical
trajectories on every kind of plan the master co-simulates, the same messages where a run stops,
and the Python loop with a one-line notice where no compiler can build it."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np
import pytest
from conftest import MULTIMODEL, REPO, SCENARIOS, all_scenarios, sleeper_multimodel

from dse_runner.errors import DseError
from dse_runner.simulation import cosim, native
from dse_runner.simulation.build import build_fmu
from dse_runner.simulation.multimodel import MultiModel
from dse_runner.simulation.run import as_plan, simulate
from dse_runner.simulation.scenario import load_scenario

TYPES2, TYPES3 = REPO / "tests" / "fmus" / "types2", REPO / "tests" / "fmus" / "types3"
WATERTANK = REPO / "jobs" / "watertank" / "fmus"
VANDERPOL = REPO / "benchmarks" / "fmus" / "vanderpol"
CLIFF = REPO / "tests" / "fmus" / "cliff"
BLOWUP = REPO / "tests" / "fmus" / "blowup"


def both(model, *args, **kwargs):
    """The same simulation through each loop."""
    return [simulate(model, *args, loop=loop, **kwargs) for loop in ("python", "native")]


def assert_identical(python, ours) -> None:
    a, b = python.trajectory, ours.trajectory
    assert a.names == b.names and np.array_equal(a.time, b.time)
    assert a.values.tobytes() == b.values.tobytes()  # bit for bit, NaN or not
    assert a.texts == b.texts
    assert python.objectives == ours.objectives


def failures(model, *args, **kwargs) -> list[str]:
    messages = []
    for loop in ("python", "native"):
        with pytest.raises(DseError) as caught:
            simulate(model, *args, loop=loop, **kwargs)
        messages.append(str(caught.value))
    return messages


def write_multimodel(folder: Path, fmus: dict, connections: dict) -> Path:
    path = folder / "multimodel.json"
    path.write_text(json.dumps({"fmus": {k: str(v) for k, v in fmus.items()}, "connections": connections}))
    return path


@pytest.mark.parametrize("scenario", all_scenarios())
def test_robotti_runs_are_bit_identical(scenario):
    assert_identical(
        *both(MULTIMODEL, SCENARIOS / scenario, {"vehicle.mass": 2000.0, "vehicle.cAlphaF": 29000})
    )


def test_a_boolean_driving_a_real_is_bit_identical(tmp_path):
    path = write_multimodel(
        tmp_path,
        {"tank": WATERTANK / "tank", "controller": WATERTANK / "controller"},
        {"tank.level": ["controller.level"], "controller.valve": ["tank.valvecontrol"]},
    )
    runs = both(path, values={"controller.maxlevel": 1.8}, stop_time=60, step=0.1)
    assert_identical(*runs)
    assert np.count_nonzero(np.diff(runs[1].trajectory.column("controller.valve"))) > 2  # it switched


def test_every_type_conversion_and_string_is_bit_identical(tmp_path):
    """FMI 2 and FMI 3 instances with every type: rounding, thresholds, widening, enumerations, strings."""
    path = write_multimodel(
        tmp_path,
        {"a": TYPES2, "b": TYPES2, "c": TYPES3},
        {
            "a.real_out": [
                {"input": "b.int_in", "round": True},
                {"input": "b.bool_in", "threshold": 1.5},
                {"input": "c.uint16_in", "round": True},
            ],
            "a.bool_out": ["c.bool_in"],
            "a.int_out": ["c.float64_in", "c.float32_in"],
            "c.int64_out": ["b.real_in"],
            "a.enum_out": ["c.int32_in"],
            "a.string_out": ["b.string_in"],
            "c.string_out": ["a.string_in"],
        },
    )
    values = {"a.real_in": 1.3, "a.real_gain": 1.0, "c.int64_in": 5, "c.string_in": "y"}
    python, ours = both(path, values=values, stop_time=3.0, step=0.125)
    assert_identical(python, ours)
    assert ours.trajectory.texts["b.string_out"][-1].startswith("y")  # strings went round the loop
    assert len(set(ours.trajectory.texts["a.string_out"])) > 1


def test_input_signals_from_a_scenario_are_bit_identical(tmp_path):
    (tmp_path / "inputs.csv").write_text("time,real_in,int_in\n0,0.5,1\n0.3,2.25,4\n0.7,-1.5,9\n1,3,2\n")
    scenario = tmp_path / "signals"
    scenario.mkdir()
    (scenario / "scenario.yaml").write_text(
        "name: signals\ninputs:\n  types2.real_in: {csv: ../inputs.csv}\n"
        "  types2.int_in: {csv: ../inputs.csv, interpolation: hold}\n"
    )
    fmu = tmp_path / "types2.fmu"
    shutil.copyfile(build_fmu(TYPES2), fmu)
    python, ours = both(fmu, scenario, stop_time=1.0, step=0.05)
    assert_identical(python, ours)
    assert len(np.unique(ours.trajectory.column("types2.int_out"))) > 3


def test_a_cheap_fmu_is_bit_identical():
    fmu = build_fmu(VANDERPOL)
    plan = as_plan(fmu)
    assert_identical(
        *both(
            plan,
            values={"vanderpol.mu": 1.5}
            if "vanderpol" in plan.variables
            else {f"{next(iter(plan.variables))}.mu": 1.5},
        )
    )


def test_a_repeated_simulation_notices_objectives_or_an_experiment_changed_in_place():
    """simulate() keeps what it worked out for a plan, scenario, objectives and experiment across calls
    (a sweep's runs); the same objects changed in place between calls must not give stale results."""
    from dse_runner.simulation.experiment import Experiment
    from dse_runner.simulation.objectives import Reduce

    plan = as_plan(build_fmu(VANDERPOL))
    x0 = f"{next(iter(plan.variables))}.x0"
    objectives = {"top": Reduce(signal=x0, reduce="max")}
    experiment = Experiment(stop_time=1.0, step=0.01)
    assert simulate(plan, objectives=objectives, experiment=experiment).times.stop == 1.0
    experiment.stop_time = 20.0
    assert simulate(plan, objectives=objectives, experiment=experiment).times.stop == 20.0
    objectives["top"] = Reduce(signal=x0, reduce="min")
    third = simulate(plan, objectives=objectives, experiment=experiment)
    assert third.objectives["top"] == pytest.approx(float(third.trajectory.column(x0).min()))


def test_a_pythonfmu_export_is_bit_identical(tmp_path):
    pytest.importorskip("pythonfmu")
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        pytest.skip("PythonFMU's binary needs a Python built with a shared libpython")
    from pythonfmu_models import build_pythonfmu

    assert_identical(*both(build_pythonfmu(tmp_path), stop_time=1.0, step=0.1))


def test_an_fmu_error_in_a_step_gives_the_same_message(tmp_path):
    messages = failures(build_fmu(CLIFF), values={"a": 9.0}, stop_time=1.0, step=0.1)
    assert messages[0] == messages[1] and "fmi2DoStep failed at t=0" in messages[1]
    assert "is over the cliff" in messages[1]  # what the FMU logged


def test_an_fmu_refusing_to_initialise_gives_the_same_message_and_the_next_run_works():
    """The C call also sets the units up; a refusal there is worded as FMPy words it, and the instance
    it left half set up is replaced for the next run."""
    messages = failures(MULTIMODEL, SCENARIOS / "sin1", {"vehicle.mass": 0.0})
    assert messages[0] == messages[1]
    assert messages[1] == (
        "vehicle (robotti_vehicle): fmi2ExitInitializationMode failed with status 3 (error): "
        "parameter mass must be > 0, got 0"
    )
    assert_identical(*both(MULTIMODEL, SCENARIOS / "sin1", {"vehicle.mass": 1000.0}))


def test_a_rounded_value_that_stops_fitting_mid_run_gives_the_same_message(tmp_path):
    path = write_multimodel(
        tmp_path, {"a": TYPES2, "b": TYPES2}, {"a.real_out": [{"input": "b.int_in", "round": True}]}
    )
    messages = failures(
        path, values={"a.real_in": 2147483646.0, "a.real_gain": 1.0}, stop_time=3.0, step=0.25
    )
    assert messages[0] == messages[1]
    assert re.fullmatch(
        r"b\.int_in is fed 2\.14748e\+09, which rounded does not fit an Integer at t=1\.5", messages[1]
    )


def test_a_diverging_simulation_gives_the_same_message(tmp_path):
    """Two gains of 10 in a loop (real_out = 10 real_in + t) overflow to infinity after about 300 steps, with
    no FMU error."""
    path = write_multimodel(
        tmp_path, {"a": TYPES2, "b": TYPES2}, {"a.real_out": ["b.real_in"], "b.real_out": ["a.real_in"]}
    )
    messages = failures(path, values={"a.real_gain": 10.0, "b.real_gain": 10.0}, stop_time=400.0, step=0.5)
    assert messages[0] == messages[1]
    assert re.fullmatch(r"[ab]\.real_out became non-finite at t=\S+: the simulation diverged", messages[1])
    assert not messages[1].endswith("t=0: the simulation diverged")  # in the loop, not at the start


def test_one_fmu_that_diverges_without_an_error_gives_the_same_message():
    """One FMU alone runs the C loop's single-unit path, which checks rows finite in blocks: it must
    still name the first non-finite point (y = exp(1000 t) overflows at t = 0.71)."""
    messages = failures(build_fmu(BLOWUP), stop_time=2.0, step=0.01)
    assert messages[0] == messages[1]
    assert re.fullmatch(r"\S+\.y became non-finite at t=0\.71: the simulation diverged", messages[1])


def test_fmus_feeding_nothing_to_each_other_diverge_with_the_same_message(tmp_path):
    path = write_multimodel(tmp_path, {"a": BLOWUP, "b": BLOWUP}, {})
    messages = failures(path, values={"a.rate": 10.0, "b.rate": 1000.0}, stop_time=2.0, step=0.01)
    assert messages[0] == messages[1] == "b.y became non-finite at t=0.71: the simulation diverged"


def test_a_slow_simulation_stops_at_its_timeout(tmp_path):
    path = sleeper_multimodel(tmp_path)
    with pytest.raises(DseError, match=r"^timeout: the simulation was stopped at t=\S+ of 84 s$"):
        simulate(path, SCENARIOS / "sin1", values={"sleeper.pause": 0.002}, timeout=0.3, loop="native")


def test_the_loop_is_chosen_by_argument_or_environment(monkeypatch):
    ran = []
    original = cosim._step_loop
    monkeypatch.setattr(cosim, "_step_loop", lambda *a: ran.append("python") or original(*a))
    simulate(MULTIMODEL, SCENARIOS / "sin1")
    assert ran == []  # native by default
    monkeypatch.setenv("DSE_RUNNER_LOOP", "python")
    simulate(MULTIMODEL, SCENARIOS / "sin1")
    assert ran == ["python"]
    monkeypatch.setenv("DSE_RUNNER_LOOP", "fast")
    with pytest.raises(DseError, match=r"loop 'fast': expected one of native, python \(DSE_RUNNER_LOOP\)"):
        simulate(MULTIMODEL, SCENARIOS / "sin1")


@pytest.mark.parametrize(
    ("env", "notice"),
    [
        (
            {"CC": "/nonexistent/cc"},
            (
                r"warning: the native co-simulation loop could not be built \(.*\): the master "
                r"runs its Python loop"
            ),
        ),
        (
            {"PATH": "/nonexistent"},
            (
                r"warning: no C compiler \(cc\) found: the co-simulation master runs its Python "
                r"loop, .*"
            ),
        ),
    ],
)
@pytest.mark.slow  # builds and runs in fresh processes without a compiler
def test_without_a_compiler_the_python_loop_runs_after_one_notice(tmp_path, env, notice):
    fmu = tmp_path / "vanderpol.fmu"
    shutil.copyfile(build_fmu(VANDERPOL), fmu)
    run = {**os.environ, "DSE_RUNNER_CACHE": str(tmp_path / "cache")}
    run.pop("CC", None)
    command = [sys.executable, "-m", "dse_runner", "simulate", str(fmu), "--set", "mu=1.5", "--json"]
    without = subprocess.run(command, env={**run, **env}, capture_output=True, text=True, check=False)
    assert without.returncode == 0, without.stderr
    lines = without.stderr.strip().splitlines()
    assert len(lines) == 1 and re.fullmatch(notice, lines[0]), without.stderr
    assert not list((tmp_path / "cache").glob("native/*.so"))
    built = subprocess.run(command, env=run, capture_output=True, text=True, check=False)
    assert built.returncode == 0 and built.stderr == "" and list((tmp_path / "cache").glob("native/*.so"))
    assert json.loads(without.stdout)["final"] == json.loads(built.stdout)["final"]


MSD = REPO / "jobs" / "msd" / "multimodel.yaml"  # the msd (model exchange) under CVode at 1e-6
BALL = (
    REPO / "tests" / "fmus" / "ball"
)  # model exchange with a state event (bounces) and a time event (a kick)
MSD3 = REPO / "tests" / "fmus" / "msd3"  # FMI 3.0 model exchange


def python_loop_runs(monkeypatch) -> list:
    """Calls of the Python loop from now on (the native loop runs when this stays empty)."""
    ran = []
    original = cosim._step_loop
    monkeypatch.setattr(cosim, "_step_loop", lambda *a: ran.append(True) or original(*a))
    return ran


def named(source: Path, folder: Path) -> Path:
    """The FMU built from ``source``, as ``<folder>/<name>.fmu``: its instance is named for it."""
    fmu = folder / f"{source.name}.fmu"
    shutil.copyfile(build_fmu(source), fmu)
    return fmu


def force_scenario(folder: Path, target: str = "msd.F", log: str = "0,0\n1,2\n2.5,-1\n3,0.5\n4,0\n") -> Path:
    """A force log (time,F rows) with steps, held between its samples: each change is an input event for the
    solver."""
    (folder / "force.csv").write_text("time,F\n" + log)
    scenario = folder / "pushed"
    scenario.mkdir()
    (scenario / "scenario.yaml").write_text(
        f"name: pushed\ninputs:\n  {target}: {{csv: ../force.csv, interpolation: hold}}\n"
    )
    return scenario


def test_model_exchange_integrated_in_c_is_bit_identical(tmp_path, monkeypatch):
    """native_me.c against FMPy's CVodeSolver in the Python loop: input events, state and time events,
    FMI 3.0, and a model-exchange instance fed by a co-simulation one."""
    ran = python_loop_runs(monkeypatch)
    pushed = both(MSD, force_scenario(tmp_path), {"msd.k": 14.0}, stop_time=5.0, step=0.05)
    bounced = both(named(BALL, tmp_path), stop_time=2.0, step=0.01)
    (tmp_path / "fmi3").mkdir()
    fmi3 = both(
        named(MSD3, tmp_path),
        force_scenario(tmp_path / "fmi3", "msd3.F"),
        {"msd3.k": 14.0, "msd3.c": 0.8},
        stop_time=5.0,
        step=0.01,
    )
    mixed = tmp_path / "mixed.json"
    mixed.write_text(
        json.dumps(
            {
                "fmus": {"source": str(TYPES2), "msd": str(REPO / "jobs" / "msd" / "fmus" / "msd")},
                "connections": {"source.real_out": ["msd.F"]},
                "instances": {"msd": {"interface": "me", "tolerance": 1e-6}},
            }
        )
    )
    fed = both(mixed, values={"source.real_in": 0.5, "source.real_gain": 1.0}, stop_time=3.0, step=0.1)
    for python, ours in (pushed, bounced, fmi3, fed):
        assert_identical(python, ours)
    assert ran == [True] * 4  # once per pair: the Python loop ran the references only
    assert np.ptp(pushed[1].trajectory.column("msd.x")[40:]) > 0.1  # the force moved the mass
    h = bounced[1].trajectory.column("ball.h")
    assert h.min() < 0.05 and h.max() > 1.1  # it bounced, and the kick sent it higher than it fell from
    assert np.ptp(fed[1].trajectory.column("msd.x")) > 0.01


def test_derivative_terms_added_in_c_are_bit_identical(tmp_path):
    """Terms on states and on an input, through every function, added in the right-hand
    side in C as Corrector.add adds them; a second run of the same terms (a fit's next
    point) takes its own coefficients."""
    pushed = force_scenario(tmp_path)
    names = [
        "derivative_term(msd.der(v), x^3)",
        "derivative_term(msd.der(v), F*tanh(v/0.1))",
        "derivative_term(msd.der(x), sin(x/0.5)*abs(v)^2*cos(v))",
    ]
    runs = [
        both(MSD, pushed, {"msd.k": 14.0, **dict(zip(names, coefficients))}, stop_time=5.0, step=0.05)
        for coefficients in ([-40.0, 0.3, 0.05], [-20.0, 0.6, -0.05])
    ]
    for python, ours in runs:
        assert_identical(python, ours)
    assert not np.array_equal(runs[0][1].trajectory.values, runs[1][1].trajectory.values)


def test_forward_euler_keeps_the_python_loop(monkeypatch):
    """FMPy's forward Euler is integrated in Python: a plan with it runs the Python loop."""
    ran = python_loop_runs(monkeypatch)
    euler = MultiModel(
        fmus={"msd": str(REPO / "jobs" / "msd" / "fmus" / "msd")},
        instances={"msd": {"interface": "me", "solver": "euler"}},
    )
    simulate(euler, stop_time=1.0, step=0.05, loop="native")
    assert ran == [True]
    simulate(MSD, stop_time=1.0, step=0.05, loop="native")
    assert ran == [True] and native.library() is not None


def test_model_exchange_failing_inside_cvode_gives_the_same_message(tmp_path):
    """An FMU that fails inside CVode's right-hand side (the ball falling up at 1.7e308 m/s² overflows its
    derivatives) and one that fails reading back a changed input (a force of 1.7e308 N): both loops say which
    call failed, and when."""
    messages = failures(named(BALL, tmp_path), values={"ball.g": -1.7e308}, stop_time=3.0, step=0.05)
    assert messages[0] == messages[1]
    assert (
        messages[1] == "fmi2GetDerivatives failed with status 3 (error) while integrating from t=0 to t=0.05"
    )
    messages = failures(
        MSD, force_scenario(tmp_path, log="0,0\n1,1.7e308\n"), {"msd.m": 0.5}, stop_time=2.0, step=0.05
    )
    assert (
        messages[0]
        == messages[1]
        == "handling an input change at t=1: fmi2GetReal failed with status 3 (error)"
    )


def test_sign_sqrt_and_fitted_widths_added_in_c_are_bit_identical(tmp_path):
    """sign and the signed sqrt, of states and of an input that is exactly 0 at times, and a term whose width
    a companion derivative_width gives, in C as in Corrector.add; the next run's other width (a fit's next
    point, on the same plan and scenario objects, so that the native loop keeps its layouts) is its own, and
    a width run again is the same run."""
    plan, pushed = as_plan(MSD), load_scenario(force_scenario(tmp_path))
    tanh = "derivative_term(msd.der(v), tanh(v/0.05))"
    width = "derivative_width(msd.der(v), tanh(v/0.05))"
    fixed = {
        "msd.k": 14.0,
        "derivative_term(msd.der(v), sign(x))": -0.4,
        "derivative_term(msd.der(v), sign(F)*sqrt(x/0.2))": 0.3,
        "derivative_term(msd.der(x), sqrt(v)^3)": -0.05,
        tanh: -0.3,
    }
    runs = [both(plan, pushed, {**fixed, width: w}, stop_time=5.0, step=0.05) for w in (0.01, 0.2, 0.01)]
    for python, ours in runs:
        assert_identical(python, ours)
    assert not np.array_equal(runs[0][1].trajectory.values, runs[1][1].trajectory.values)
    assert runs[0][1].trajectory.values.tobytes() == runs[2][1].trajectory.values.tobytes()
    assert "derivative_term(msd.der(v), tanh(v/0.2))" in runs[1][1].values  # the term as it was run
