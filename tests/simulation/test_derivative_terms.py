"""Derivative terms: the master adds a · term(states, inputs) to a model-exchange instance's state derivatives
while it integrates, changes nothing at a = 0, and refuses what it cannot do."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from conftest import REPO
from scipy.integrate import solve_ivp

from dse_runner.errors import DseError
from dse_runner.simulation.derivative_terms import parse, parse_term, split, term_name
from dse_runner.simulation.multimodel import MultiModel
from dse_runner.simulation.run import simulate
from dse_runner.simulation.scenario import Scenario
from dse_runner.simulation.trajectory import Series
from dse_runner.sweeps.spec import load_space

MSD = REPO / "jobs" / "msd" / "multimodel.yaml"
STOP, STEP = 6.0, 0.02
T = np.arange(0.0, STOP + 0.05, 0.05)
FORCE = np.where((T >= 1.0) & (T < 3.0), 2.0, -0.5)


def _scenario() -> Scenario:
    return Scenario("pushed", inputs={"msd.F": Series(T, FORCE, "hold")}, stop_time=STOP, step=STEP)


def test_a_name_reads_back_as_it_was_written():
    for text in ("x^3", "v*abs(v)", "F*tanh(v/0.05)", "1", "x^2*v", "sin(x)"):
        term = parse(f"derivative_term(msd.der(v), {text})")
        assert (term.instance, term.state, term.term.text) == ("msd", "v", text)
        assert parse(term.name) == term
    assert term_name("msd", "v", "tanh(v/0.013)") == "derivative_term(msd.der(v), tanh(v/0.013))"
    assert parse("derivative_term(der(v), x)").instance is None
    assert parse("msd.k") is None and parse("input_delay(msd.F)") is None


def test_a_term_is_the_product_of_its_factors():
    values = {"x": np.array([0.5, -2.0]), "v": np.array([0.1, -0.3])}
    assert np.allclose(
        parse_term("x^3*tanh(v/0.2)").value(values), values["x"] ** 3 * np.tanh(values["v"] / 0.2)
    )
    assert parse_term("1").value(values) == 1.0


@pytest.mark.parametrize(
    "name, message",
    [
        ("derivative_term(msd.v, x)", r"is named derivative_term\(INSTANCE.der\(STATE\), TERM\)"),
        ("derivative_term(msd.der(v), x**3)", r"cannot read the factor ''"),
        ("derivative_term(msd.der(v), exp(x))", r"cannot read the factor 'exp\(x\)'"),
        ("derivative_term(msd.der(v), tanh(v/0))", r"width .* must be a number > 0"),
    ],
)
def test_a_name_that_cannot_be_read_says_what_a_term_is(name, message):
    with pytest.raises(DseError, match=message):
        parse(name)


def test_a_coefficient_must_be_a_finite_number():
    with pytest.raises(DseError, match=r"finite number, not nan"):
        split({"derivative_term(msd.der(v), x^3)": float("nan")})
    assert split({"derivative_term(msd.der(v), x^3)": 0.0, "msd.k": 3.0}) == ({"msd.k": 3.0}, {})


@pytest.mark.parametrize("solver", ["cvode", "euler"])
def test_a_zero_coefficient_changes_nothing_bit_for_bit(solver):
    model = MultiModel(
        fmus={"msd": str(REPO / "jobs" / "msd" / "fmus" / "msd")},
        instances={"msd": {"interface": "me", "solver": solver, "tolerance": 1e-6}},
    )
    plain = simulate(model, _scenario(), {"msd.x0": 0.1})
    zero = simulate(
        model,
        _scenario(),
        {
            "msd.x0": 0.1,
            "derivative_term(msd.der(v), x^3)": 0.0,
            "derivative_term(msd.der(x), F*tanh(v/0.1))": 0.0,
        },
    )
    assert np.array_equal(plain.trajectory.values, zero.trajectory.values)


def test_the_master_integrates_the_corrected_equations():
    """m x'' = F − k x − c v + a3 x³ + af F·tanh(v/0.1) against scipy's own integration of the same."""
    a3, af, k, c = -40.0, 0.3, 10.0, 0.5
    run = simulate(
        MSD,
        _scenario(),
        {
            "msd.x0": 0.2,
            "derivative_term(msd.der(v), x^3)": a3,
            "derivative_term(msd.der(v), F*tanh(v/0.1))": af,
        },
    )

    def force(t: float) -> float:
        return float(FORCE[np.searchsorted(T, t, side="right") - 1])

    def rhs(f: float):
        return lambda t, s: [s[1], f - k * s[0] - c * s[1] + a3 * s[0] ** 3 + af * f * np.tanh(s[1] / 0.1)]

    # the master holds F over each communication step, so integrate step by step as it does
    y, xs = [0.2, 0.0], [0.2]
    for t0, t1 in zip(run.time[:-1], run.time[1:]):
        y = solve_ivp(rhs(force(t0)), (t0, t1), y, rtol=1e-10, atol=1e-12).y[:, -1]
        xs.append(y[0])
    assert np.max(np.abs(run.outputs["msd.x"] - np.array(xs))) < 2e-5  # CVode at tolerance 1e-6
    assert run.values["derivative_term(msd.der(v), x^3)"] == a3


def test_a_term_on_a_state_the_instance_lacks_names_its_states():
    with pytest.raises(DseError, match=r"instance 'msd' has no continuous state 'y' \(its states: x, v\)"):
        simulate(MSD, _scenario(), {"derivative_term(msd.der(y), x)": 1.0})
    with pytest.raises(
        DseError, match=r"'k' is not a state or real input of instance 'msd' \(a term may read x, v, F\)"
    ):
        simulate(MSD, _scenario(), {"derivative_term(msd.der(v), k*x)": 1.0})


def test_a_cosimulation_instance_is_refused_by_name():
    model = REPO / "jobs" / "watertank" / "multimodel.yaml"
    with pytest.raises(
        DseError, match=r"instance 'tank' is run as co-simulation: it integrates its own states"
    ):
        simulate(model, None, {"derivative_term(tank.der(level), level)": 0.1}, stop_time=1.0, step=0.1)


def _space(folder, parameters):
    t, x = T, np.zeros_like(T)
    np.savetxt(folder / "force.csv", np.column_stack([t, FORCE]), delimiter=",", header="time,F", comments="")
    np.savetxt(folder / "x.csv", np.column_stack([t, x]), delimiter=",", header="time,x", comments="")
    spec = {
        "name": "terms",
        "multimodel": str(MSD),
        "experiment": {"stop_time": STOP, "step": STEP},
        "scenarios": [
            {
                "name": "pushed",
                "inputs": {"msd.F": {"csv": "force.csv", "interpolation": "hold"}},
                "recorded": "x.csv",
            }
        ],
        "parameters": parameters,
        "objectives": {"position": {"signal": "msd.x", "recorded": "x", "metric": "rmse"}},
        "output": str(folder / "out"),
    }
    (folder / "space.yaml").write_text(yaml.safe_dump(spec))
    return folder / "space.yaml"


def test_a_space_sweeps_a_term_and_checks_it_when_it_loads(tmp_path):
    space = load_space(_space(tmp_path, {"derivative_term(msd.der(v), x^3)": [0.0, -20.0, -40.0]}))
    assert space.parameters["derivative_term(msd.der(v), x^3)"] == [0.0, -20.0, -40.0]
    with pytest.raises(
        DseError,
        match=r"parameters.derivative_term\(msd.der\(w\), x\^3\): instance 'msd' has no "
        r"continuous state 'w'",
    ):
        load_space(_space(tmp_path, {"derivative_term(msd.der(w), x^3)": [0.0, 1.0]}))
