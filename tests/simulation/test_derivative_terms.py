"""Derivative terms: the master adds a · term(states, inputs) to a model-exchange instance's state derivatives
while it integrates, changes nothing at a = 0, and refuses what it cannot do."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from conftest import REPO
from scipy.integrate import solve_ivp

from dse_runner.errors import DseError
from dse_runner.simulation.derivative_terms import (
    Factor,
    parse,
    parse_term,
    parse_width,
    split,
    term_name,
    width_name,
)
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
    for text in ("x^3", "v*abs(v)", "F*tanh(v/0.05)", "1", "x^2*v", "sin(x)", "sign(v)", "sqrt(x/2.5)^3"):
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
        ("derivative_term(msd.der(v), cbrt(x))", r"or abs, tanh, sin, cos, sign, sqrt of one"),
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


# ---- sign, the signed sqrt, and a width fitted by a companion parameter ------------------------------------

SPECIAL = [0.0, -0.0, 1.0, -1.0, 5e-324, -5e-324, 1e308, -1e308, math.inf, -math.inf, math.nan, 0.3, -2.0]


@pytest.mark.parametrize("function", ["sign", "sqrt"])
def test_sign_and_the_signed_sqrt_are_the_same_bits_on_a_float_and_in_an_array(function):
    """Corrector.add reads floats (the scalar path), diagnosis arrays (numpy's): both give the same bits,
    those of native_me.c (copysign(sqrt(fabs(x)), x); sign's -1, 0, +1 with NaN kept, as np.sign)."""
    xs = np.array(SPECIAL + list(np.random.default_rng(1).normal(scale=3.0, size=200)))
    factor = Factor("x", function)
    scalar = np.array([factor.value({"x": float(x)}) for x in xs])
    assert scalar.tobytes() == np.asarray(factor.value({"x": xs}), dtype=float).tobytes()
    if function == "sign":
        assert scalar.tobytes() == np.sign(xs).tobytes()
    else:
        expected = [math.copysign(math.sqrt(abs(x)), x) for x in xs]
        assert scalar.tobytes() == np.array(expected).tobytes()
        assert math.copysign(1.0, factor.value({"x": -0.0})) == -1.0  # signed even at zero
        assert factor.value({"x": -4.0}) == -2.0 and factor.value({"x": 9.0}) == 3.0


def test_a_companion_width_replaces_the_width_written_in_the_term():
    name, width = (
        "derivative_term(msd.der(v), x*tanh(v/0.05)^2)",
        "derivative_width(msd.der(v), x*tanh(v/0.05)^2)",
    )
    assert width_name("msd", "v", "x*tanh(v/0.05)^2") == width
    assert parse_width(width).term == parse(name) and parse_width(name) is None and parse(width) is None
    plain, terms = split({"msd.k": 3.0, name: -0.3, width: 0.01})
    assert plain == {"msd.k": 3.0}
    assert [t.name for t in terms] == ["derivative_term(msd.der(v), x*tanh(v/0.01)^2)"]
    assert terms == split({"derivative_term(msd.der(v), x*tanh(v/0.01)^2)": -0.3})[1]
    # spaces and the spelling of numbers aside, a companion is its term's; no width written is 1
    assert split({name: -0.3, "derivative_width(msd.der(v), x * tanh( v / 5e-2 )^2)": 0.01})[1] == terms
    assert [
        t.name
        for t in split({"derivative_term(der(v), abs(v))": 1.0, "derivative_width(der(v), abs(v))": 2.0})[1]
    ] == ["derivative_term(der(v), abs(v/2.0))"]
    # at coefficient 0 the term is not applied, so neither is its width (still checked)
    assert split({name: 0.0, width: 0.01}) == ({}, {})


W = "derivative_width(msd.der(v), "  # a companion's name, up to its term
A = "derivative_term(msd.der(v), "  # a term parameter's


@pytest.mark.parametrize(
    "values, message",
    [
        (
            {f"{A}x^3)": 1.0, f"{W}x^3)": 0.1},
            (
                r"^derivative_width\(msd.der\(v\), x\^3\): a width is that of the one factor of its term "
                r"with a function \(abs, tanh, sin, cos, sign, sqrt\), and x\^3 has none$"
            ),
        ),
        (
            {f"{W}abs(v)*tanh(x))": 0.1},
            r"^derivative_width\(msd.der\(v\), abs\(v\)\*tanh\(x\)\): .* has 2 \(abs\(v\), tanh\(x\)\)$",
        ),
        (
            {"derivative_width(msd.v, tanh(v))": 0.1},
            (
                r"^derivative_width\(msd.v, tanh\(v\)\): a derivative width is named derivative_width\("
                r"INSTANCE.der\(STATE\), TERM\), e.g. derivative_width\(msd.der\(v\), tanh\(v/0.05\)\)$"
            ),
        ),
        (
            {f"{A}tanh(v))": 1.0, f"{W}tanh(v))": 0.0},
            r"^derivative_width\(msd.der\(v\), tanh\(v\)\): a width is a finite number > 0, not 0.0$",
        ),
        (  # checked at coefficient 0 too
            {f"{A}tanh(v))": 0.0, f"{W}tanh(v))": -0.1},
            r"^derivative_width\(msd.der\(v\), tanh\(v\)\): a width is a finite number > 0, not -0.1$",
        ),
        (
            {f"{A}tanh(v))": 1.0, f"{W}tanh(v))": math.inf},
            r"^derivative_width\(msd.der\(v\), tanh\(v\)\): a derivative term's width is a finite number",
        ),
        (
            {f"{A}tanh(v/0.1))": 1.0, f"{W}tanh(v/0.2))": 0.1},
            (
                r"^derivative_width\(msd.der\(v\), tanh\(v/0.2\)\): the values have no derivative_term\("
                r"msd.der\(v\), tanh\(v/0.2\)\), whose width it fits; give the coefficient too$"
            ),
        ),
        (
            {f"{A}tanh(v/0.1))": 1.0, f"{A}tanh(v/0.2))": 2.0, f"{W}tanh(v/0.1))": 0.2},
            (
                r"^derivative_width\(msd.der\(v\), tanh\(v/0.1\)\) and derivative_term\(msd.der\(v\), "
                r"tanh\(v/0.2\)\) both make the run add derivative_term\(msd.der\(v\), tanh\(v/0.2\)\); "
                r"give it once$"
            ),
        ),
    ],
)
def test_a_companion_width_that_cannot_apply_says_why_in_one_line(values, message):
    with pytest.raises(DseError, match=message):
        split(values)


def test_a_companion_width_runs_as_the_same_width_written_in_the_term():
    """The FMU run: −0.3·tanh(v/0.05) fitted to width 0.01 is −0.3·tanh(v/0.01) bit for bit, not the
    written 0.05's run; at coefficient 0 the companion leaves the plain run as it is."""
    base = {"msd.x0": 0.2, "derivative_term(msd.der(v), x^3)": -40.0}
    tanh = "derivative_term(msd.der(v), tanh(v/0.05))"
    fitted = simulate(
        MSD, _scenario(), {**base, tanh: -0.3, "derivative_width(msd.der(v), tanh(v/0.05))": 0.01}
    )
    written = simulate(MSD, _scenario(), {**base, "derivative_term(msd.der(v), tanh(v/0.01))": -0.3})
    default = simulate(MSD, _scenario(), {**base, tanh: -0.3})
    assert fitted.trajectory.values.tobytes() == written.trajectory.values.tobytes()
    assert not np.array_equal(fitted.trajectory.values, default.trajectory.values)
    assert fitted.values["derivative_term(msd.der(v), tanh(v/0.01))"] == -0.3  # the term as it ran
    off = simulate(MSD, _scenario(), {**base, tanh: 0.0, "derivative_width(msd.der(v), tanh(v/0.05))": 0.01})
    assert off.trajectory.values.tobytes() == simulate(MSD, _scenario(), base).trajectory.values.tobytes()


def test_a_space_fits_a_width_with_its_term_and_checks_both_when_it_loads(tmp_path):
    term, width = "derivative_term(msd.der(v), tanh(v/0.05))", "derivative_width(msd.der(v), tanh(v/0.05))"
    space = load_space(_space(tmp_path, {term: [0.0, -0.3], width: [0.005, 0.1]}))
    assert space.parameters[width] == [0.005, 0.1]
    with pytest.raises(
        DseError,
        match=r"space.yaml: parameters.derivative_width\(msd.der\(v\), tanh\(v/0.05\)\): the parameters have "
        r"no derivative_term\(msd.der\(v\), tanh\(v/0.05\)\), whose width it fits; sweep or fit the "
        r"coefficient too$",
    ):
        load_space(_space(tmp_path, {"msd.k": [10.0, 12.0], width: [0.01]}))
    with pytest.raises(
        DseError,
        match=r"space.yaml: parameters.derivative_width\(msd.der\(v\), tanh\(v/0.05\)\): a width is a "
        r"finite number > 0, not 0.0$",
    ):
        load_space(_space(tmp_path, {term: [-0.3], width: [0.1, 0.0]}))
    with pytest.raises(
        DseError,
        match=r"parameters.derivative_width\(msd.der\(v\), x\^3\): a width is that of the one factor",
    ):
        load_space(
            _space(
                tmp_path,
                {"derivative_term(msd.der(v), x^3)": [1.0], "derivative_width(msd.der(v), x^3)": [0.1]},
            )
        )
    with pytest.raises(
        DseError,
        match=r"derivative_term\(msd.der\(w\), tanh\(w\)\): instance 'msd' has no continuous state 'w'",
    ):
        load_space(
            _space(
                tmp_path,
                {
                    "derivative_width(msd.der(w), tanh(w))": [0.1],
                    "derivative_term(msd.der(w), tanh(w))": [1.0],
                },
            )
        )
