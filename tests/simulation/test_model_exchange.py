"""Model exchange: the msd FMU (me2.c) and ModelExchangeStepper against FMPy's simulateME."""

from __future__ import annotations

import inspect
import math
import zipfile
from ctypes import POINTER, c_double, cast
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import REPO
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model
from fmpy.fmi3 import FMU3Model
from fmpy.validation import validate_fmu

from dse_runner.simulation.build import build_fmu
from dse_runner.simulation.model_exchange import ModelExchangeError, ModelExchangeStepper

MSD = REPO / "jobs" / "msd" / "fmus" / "msd"
BALL = REPO / "tests" / "fmus" / "ball"  # a bounce is a state event, a kick a time event
TRUE = {"k": 14.0, "c": 0.8}  # not the defaults, so setting parameters is tested too
STEP, STOP = 0.01, 5.0


@pytest.fixture(scope="module")
def msd(tmp_path_factory):
    """The built msd FMU, its description and an extracted copy to instantiate from."""
    path = build_fmu(MSD)
    return SimpleNamespace(
        path=str(path),
        md=read_model_description(str(path)),
        unzipped=extract(str(path), str(tmp_path_factory.mktemp("msd"))),
    )


def instantiate(fmu, name="msd"):
    model = FMU2Model(
        guid=fmu.md.guid,
        unzipDirectory=fmu.unzipped,
        modelIdentifier=fmu.md.modelExchange.modelIdentifier,
        instanceName=name,
    )
    model.instantiate()
    return model


def vrs(fmu) -> dict[str, int]:
    return {v.name: v.valueReference for v in fmu.md.modelVariables}


def run(fmu, model, params=TRUE, force=lambda t: None, output="x", stop=STOP, **settings):
    """The master's loop in miniature: set up, set parameters, initialize, then at every
    communication point set the input (if ``force`` gives one), step, read the output."""
    ref = vrs(fmu)
    stepper = ModelExchangeStepper(model, fmu.md, **settings)
    stepper.setup(0.0, stop)
    for name, value in params.items():
        model.setReal([ref[name]], [value])
    stepper.enter_initialization(0.0, stop)
    stepper.exit_initialization()
    values = [model.getReal([ref[output]])[0]]
    for i in range(round(stop / STEP)):
        if (f := force(i * STEP)) is not None:
            model.setReal([ref["F"]], [f])
        stepper.do_step(i * STEP, STEP)
        values.append(model.getReal([ref[output]])[0])
    stepper.terminate()
    return np.array(values)


def exact(t, m=1.0, k=TRUE["k"], c=TRUE["c"], x0=0.1):
    """The underdamped oscillator released at rest from x0."""
    decay = c / (2 * m)
    omega = math.sqrt(k / m - decay**2)
    return np.exp(-decay * t) * x0 * (np.cos(omega * t) + decay / omega * np.sin(omega * t))


def euler(dt, n, m=1.0, k=TRUE["k"], c=TRUE["c"], x0=0.1):
    """Forward Euler by hand: x at every step."""
    x, v, out = x0, 0.0, [x0]
    for _ in range(n):
        x, v = x + dt * v, v + dt * (-k * x - c * v) / m
        out.append(x)
    return np.array(out)


# ---- the FMU ---------------------------------------------------------------


def test_msd_is_a_valid_me_fmu_that_fmpy_simulates(msd):
    assert validate_fmu(msd.path) == []
    with zipfile.ZipFile(msd.path) as z:
        assert {"binaries/linux64/msd.so", "sources/me2.c", "sources/me2.h"} <= set(z.namelist())
    assert msd.md.coSimulation is None and msd.md.numberOfContinuousStates == 2
    for solver in ("CVode", "Euler"):
        result = simulate_fmu(msd.path, solver=solver, output=["x", "v"])
        assert result["time"][-1] == pytest.approx(10.0) and np.isfinite(result["x"]).all()
        assert result["x"][0] == pytest.approx(0.1) and abs(result["x"][-1]) < 0.02  # defaults: damped


def test_reset_restores_start_values_and_runs_again_identically(msd):
    model = instantiate(msd)
    first = run(msd, model, force=lambda t: 1.0 if t >= 1.0 else 0.0)
    model.reset()
    ref = vrs(msd)
    assert model.getReal([ref["k"], ref["c"], ref["F"], ref["x"]]) == [10.0, 0.5, 0.0, 0.1]
    again = run(msd, model, force=lambda t: 1.0 if t >= 1.0 else 0.0)
    model.freeInstance()
    assert np.array_equal(first, again)


def test_calls_outside_their_mode_fail(msd, capsys):
    model = instantiate(msd)
    with pytest.raises(FMICallException, match="fmi2SetContinuousStates"):
        model.setContinuousStates(cast((c_double * 2)(), POINTER(c_double)), 2)
    assert "fmi2SetContinuousStates is not allowed in instantiated" in "".join(
        capsys.readouterr()
    )  # FMPy prints on stdout, ours on stderr
    model.freeInstance()


# ---- the stepper against FMPy ----------------------------------------------


def test_cvode_agrees_with_fmpy_and_the_exact_solution(msd):
    model = instantiate(msd)
    ours = run(msd, model, tolerance=1e-6)
    model.freeInstance()
    theirs = simulate_fmu(
        msd.path,
        solver="CVode",
        stop_time=STOP,
        output_interval=STEP,
        relative_tolerance=1e-6,
        start_values=TRUE,
        output=["x"],
    )
    assert len(ours) == len(theirs)
    amplitude = 0.1
    assert np.abs(ours - theirs["x"]).max() < 1e-4 * amplitude
    assert np.abs(ours - exact(theirs["time"])).max() < 1e-3 * amplitude


def test_euler_agrees_with_fmpy_and_by_hand(msd):
    model = instantiate(msd)
    ours = run(msd, model, solver="euler")  # one Euler step per communication step
    model.reset()
    fine = run(msd, model, solver="euler", euler_step=0.001)
    model.freeInstance()
    theirs = simulate_fmu(
        msd.path,
        solver="Euler",
        stop_time=STOP,
        step_size=STEP,
        output_interval=STEP,
        start_values=TRUE,
        output=["x"],
    )
    n = round(STOP / STEP)
    assert np.abs(ours - theirs["x"]).max() < 1e-9
    assert np.abs(ours - euler(STEP, n)).max() < 1e-9
    assert np.abs(fine - euler(0.001, 10 * n)[::10]).max() < 1e-9


def test_input_changes_restart_the_solver_like_fmpy_input_events(msd):
    """F = 2 N from t = 1 s to t = 3 s, set by the loop between steps; FMPy gets the same
    step signal and treats its jumps as input events."""
    model = instantiate(msd)
    ours = run(msd, model, force=lambda t: 2.0 if 1.0 <= t + 1e-9 < 3.0 else 0.0, tolerance=1e-6)
    model.freeInstance()
    signal = np.array(
        [(0.0, 0.0), (1.0, 0.0), (1.0, 2.0), (3.0, 2.0), (3.0, 0.0), (STOP, 0.0)],
        dtype=[("time", float), ("F", float)],
    )
    theirs = simulate_fmu(
        msd.path,
        solver="CVode",
        stop_time=STOP,
        output_interval=STEP,
        relative_tolerance=1e-6,
        start_values=TRUE,
        input=signal,
        output=["x"],
        record_events=False,
    )
    assert np.abs(ours - theirs["x"]).max() < 1e-5
    assert ours[100:300].mean() > 0.1  # the force moved the mass (to oscillate about F / k = 0.14 m)


# ---- events: a bouncing ball (tests/fmus/ball) -------------------------------


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    path = build_fmu(BALL)
    return SimpleNamespace(
        path=str(path),
        md=read_model_description(str(path)),
        unzipped=extract(str(path), str(tmp_path_factory.mktemp("ball"))),
    )


def test_state_and_time_events_agree_with_fmpy(ball):
    assert validate_fmu(ball.path) == []
    model = FMU2Model(
        guid=ball.md.guid, unzipDirectory=ball.unzipped, modelIdentifier="ball", instanceName="ball"
    )
    model.instantiate()
    ours = run(ball, model, params={}, output="h", stop=2.0, tolerance=1e-6)
    model.freeInstance()
    theirs = simulate_fmu(
        ball.path,
        solver="CVode",
        stop_time=2.0,
        output_interval=STEP,
        relative_tolerance=1e-6,
        output=["h"],
        record_events=False,
    )
    assert np.abs(ours - theirs["h"]).max() < 1e-6
    bounce = round(math.sqrt(2 / 9.81) / STEP)  # at 0.45 s, before the kick at 0.9 s
    assert ours[bounce + 5] > ours[bounce]  # it bounced
    assert ours.max() > 1.1  # and the kick sent it higher than it fell from


# ---- failures ----------------------------------------------------------------


def test_a_bad_parameter_fails_initialization_with_the_fmus_reason(msd, capsys):
    model = instantiate(msd)
    with pytest.raises(
        ModelExchangeError,
        match=r"^exiting initialization mode at t=0: "
        r"fmi2ExitInitializationMode failed",
    ):
        run(msd, model, params={"m": 0.0})
    assert "mass m must be finite and > 0, got 0" in "".join(
        capsys.readouterr()
    )  # FMPy prints on stdout, ours on stderr
    model.freeInstance()


def test_derivatives_blowing_up_inside_cvode_name_the_fmu_error_and_time(msd, capsys):
    model = instantiate(msd)
    with pytest.raises(
        ModelExchangeError,
        match=r"^fmi2GetDerivatives failed with status 3 \(error\) "
        r"while integrating from t=0\.\d+ to t=0\.\d+$",
    ):
        run(msd, model, params={"k": -1e6})  # grows as exp(1000 t) until der(v) overflows
    assert "der(v) is inf at t=0.6" in "".join(capsys.readouterr())  # FMPy prints on stdout, ours on stderr
    model.freeInstance()


def test_a_non_finite_input_fails_the_step_it_is_set_for(msd):
    model = instantiate(msd)
    with pytest.raises(ModelExchangeError, match=r"at t=1: fmi2GetReal failed"):
        run(msd, model, solver="euler", force=lambda t: math.nan if t >= 1.0 else None)
    model.freeInstance()


def test_bad_settings_are_refused(msd):
    with pytest.raises(ModelExchangeError, match="unknown ME solver 'rk4'"):
        ModelExchangeStepper(None, msd.md, solver="rk4")
    stepper = ModelExchangeStepper(None, msd.md)
    with pytest.raises(ModelExchangeError, match="before exit_initialization"):
        stepper.do_step(0.0, STEP)


# ---- FMI 3.0: the stepper's FMI 3 calls, on a stand-in ------------------------


class FakeMsd3:
    """The msd in Python behind FMPy's FMU3Model method names, to count the stepper's FMI 3 calls
    (a real FMI 3.0 ME FMU runs in tests/simulation/test_fmi3_me.py)."""

    def __init__(self, k, c):
        self.k, self.c, self.x, self.time, self.calls = k, c, [0.1, 0.0], 0.0, []

    def enterInitializationMode(self, tolerance=None, startTime=0.0, stopTime=None):
        self.calls.append("enterInitializationMode")

    def exitInitializationMode(self):
        self.calls.append("exitInitializationMode")

    def updateDiscreteStates(self):
        self.calls.append("updateDiscreteStates")
        return False, False, False, False, False, 0.0

    def enterContinuousTimeMode(self):
        self.calls.append("enterContinuousTimeMode")

    def enterEventMode(self):
        self.calls.append("enterEventMode")

    def completedIntegratorStep(self, noSetFMUStatePriorToCurrentPoint=True):
        return False, False

    def setTime(self, time):
        self.time = time

    def setContinuousStates(self, continuousStates, nContinuousStates):
        self.x = [continuousStates[i] for i in range(nContinuousStates)]

    def getContinuousStates(self, continuousStates, nContinuousStates):
        for i in range(nContinuousStates):
            continuousStates[i] = self.x[i]

    def getContinuousStateDerivatives(self, derivatives, nContinuousStates):
        x, v = self.x
        derivatives[0], derivatives[1] = v, (0.0 - self.k * x - self.c * v) / 1.0

    def getNominalsOfContinuousStates(self, nominals, nContinuousStates):
        for i in range(nContinuousStates):
            nominals[i] = 1.0

    def getEventIndicators(self, eventIndicators, nEventIndicators):
        pass

    def getFloat64(self, vr, nValues=None):
        return [0.0] * len(vr)

    def terminate(self):
        self.calls.append("terminate")


def test_fmi3_path_drives_fmpys_fmu3model_calls(msd):
    for name, method in inspect.getmembers(FakeMsd3, inspect.isfunction):
        if name != "__init__":
            assert list(inspect.signature(method).parameters) == list(
                inspect.signature(getattr(FMU3Model, name)).parameters
            ), name
    description = SimpleNamespace(
        fmiVersion="3.0",
        modelName="msd3",
        numberOfContinuousStates=2,
        numberOfEventIndicators=0,
        modelExchange=SimpleNamespace(needsCompletedIntegratorStep=True),
        modelVariables=[SimpleNamespace(name="F", causality="input", type="Float64", valueReference=5)],
    )
    fake = FakeMsd3(**TRUE)
    stepper = ModelExchangeStepper(fake, description, tolerance=1e-6)
    stepper.setup(0.0, STOP)
    stepper.enter_initialization(0.0, STOP)
    stepper.exit_initialization()
    xs = [fake.x[0]]
    for i in range(round(STOP / STEP)):
        stepper.do_step(i * STEP, STEP)
        xs.append(fake.x[0])
    stepper.terminate()
    assert (
        fake.calls[:4]
        == [
            "enterInitializationMode",
            "exitInitializationMode",
            "updateDiscreteStates",
            "enterContinuousTimeMode",
        ]
        and fake.calls[-1] == "terminate"
    )
    model = instantiate(msd)
    fmi2 = run(msd, model, tolerance=1e-6)
    model.freeInstance()
    assert np.abs(np.array(xs) - fmi2).max() < 1e-9


def test_a_state_with_an_exact_start_value_is_set_as_fmi_allows_and_calibrates_like_a_parameter(tmp_path):
    """The Reference FMUs' VanDerPol declares its states x0, x1 as outputs with exact start values: FMI
    lets an importer set those before initialisation, so --set, values files and a space's
    parameters take them (an unknown initial state is calibrated like any parameter). The run starts
    there: against scipy from (0.5, 0)."""
    import yaml
    from scipy.integrate import solve_ivp

    from dse_runner.errors import DseError
    from dse_runner.simulation.run import simulate
    from dse_runner.sweeps.spec import load_space

    vdp = REPO / "tests" / "fmus" / "vdp_me"
    run = simulate(vdp, None, {"x0": 0.5}, stop_time=2.0, step=0.1, interface="me")
    expected = solve_ivp(
        lambda t, s: [s[1], (1 - s[0] ** 2) * s[1] - s[0]],
        (0.0, 2.0),
        [0.5, 0.0],
        t_eval=run.time,
        rtol=1e-10,
        atol=1e-12,
    ).y
    assert run.trajectory.column("vdp_me.x0")[0] == 0.5
    assert (
        np.max(np.abs(run.trajectory.column("vdp_me.x0") - expected[0])) < 1e-3
    )  # CVode at its default tolerance
    spec = {
        "name": "start",
        "multimodel": {"fmus": {"vdp": str(vdp)}, "instances": {"vdp": {"interface": "me"}}},
        "experiment": {"stop_time": 2.0, "step": 0.1},
        "parameters": {"vdp.x0": {"low": -1.0, "high": 1.0}, "vdp.mu": [1.0]},
        "objectives": {"x_end": {"signal": "vdp.x0", "reduce": "final"}},
        "search": {"strategy": "random"},
        "output": str(tmp_path / "out"),
    }
    (tmp_path / "space.yaml").write_text(yaml.safe_dump(spec))
    assert load_space(tmp_path / "space.yaml").parameters["vdp.x0"] == [-1.0, 1.0]
    with pytest.raises(
        DseError,
        match=r"'vdp_me.der\(x0\)' is a local, not a parameter or input, and its start "
        r"value is not exact or approx",
    ):
        simulate(vdp, None, {"der(x0)": 0.5}, stop_time=1.0, step=0.1, interface="me")
