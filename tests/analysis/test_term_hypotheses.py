"""Terms inside the model as hypotheses: which the library offers a model-exchange FMU, what each means in an
engineer's words, what outside the model imitates each, what the search among them costs, and which limits
the recordings reach. The parts, without a cluster; the diagnoses that use them are in
test_physics_inside.py."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import REPO

from dse_runner.analysis.diagnose import explain
from dse_runner.analysis.diagnose.derivatives import model_exchange_instances, observe
from dse_runner.analysis.diagnose.explain import Candidate
from dse_runner.analysis.diagnose.signal_claims import unreached
from dse_runner.analysis.diagnose.signal_hypotheses import SignalHypothesis, state_hypotheses
from dse_runner.analysis.diagnose.signal_locate import Residual
from dse_runner.analysis.diagnose.term_hypotheses import (
    PhysicalTerm,
    hypothesis,
    laws,
    meaning,
    readable,
    rivals,
    term_hypotheses,
)
from dse_runner.simulation.derivative_terms import parse_term
from dse_runner.simulation.run import simulate
from dse_runner.sweeps.fit import FitResult, Parameter
from dse_runner.sweeps.spec import load_space

PLAIN = REPO / "jobs" / "msd" / "physics" / "plain" / "space.yaml"
POINT = {"msd.m": 1.0, "msd.k": 12.0, "msd.c": 0.3, "msd.x0": 0.06, "msd.v0": -0.25}


@pytest.fixture(scope="module")
def msd():
    """The msd FMU's instance and its runs on the plain case's three records, at a calibrated point."""
    space = load_space(PLAIN)
    (instance,) = model_exchange_instances(space.plan)
    return instance, observe(space, POINT, [instance])


def test_terms_are_offered_on_physics_with_friction_on_the_velocity_alone(msd):
    instance, runs = msd
    found = {t.term.text: t for t in laws(instance, runs)}
    assert {t.target for t in found.values()} == {"msd.der(v)"}  # der(x) = v on every run: a definition
    assert {"1", "x", "v", "F", "x^3", "x*abs(x)", "v*abs(v)", "x*F"} <= set(found)
    assert not {"sqrt(x)", "sqrt(v)"} & set(found)  # both cross zero: no opening's square root of them
    frictions = [t for t in found.values() if t.law == "friction"]
    assert len(frictions) == 1 and frictions[0].term.text == "tanh(v)"  # its width is a parameter
    assert found["x^3"].position == "x" and found["v"].position == ""  # x is the position whose rate is v
    assert all(t.scale > 0 and math.isfinite(t.scale) for t in found.values())


def test_a_friction_fits_its_width_and_pushes_against_the_motion_from_every_start(msd):
    instance, runs = msd
    (friction,) = [t for t in laws(instance, runs) if t.law == "friction"]
    h = hypothesis(friction)
    assert h.kinds == ("coefficient", "width")
    assert h.names[1] == f"derivative_width(msd.der(v), {friction.term.text})"
    assert all(start[0] < 0 for start in h.starts)  # against the motion
    widths = sorted(start[1] for start in h.starts)
    assert widths[0] < widths[-1] / 50  # from a smoothed sign to a nearly sharp one
    assert h.absent()[h.names[0]] == 0.0  # at 0 the model runs without it


def test_the_fitted_width_is_the_width_the_run_uses(msd):
    """The hypothesis' two parameters, as a fit sends them, run the friction the readable form names."""
    instance, runs = msd
    (friction,) = [t for t in laws(instance, runs) if t.law == "friction"]
    h = hypothesis(friction)
    space = load_space(PLAIN)
    scenario = space.scenarios[0]
    companion = {**POINT, h.names[0]: -0.5, h.names[1]: 0.003}
    written = {**POINT, "derivative_term(msd.der(v), tanh(v/0.003))": -0.5}
    a = simulate(space.plan, scenario, companion, objectives={}, experiment=space.experiment)
    b = simulate(space.plan, scenario, written, objectives={}, experiment=space.experiment)
    assert np.array_equal(a.outputs["msd.x"], b.outputs["msd.x"])
    assert "w = 0.003" in readable(friction, {h.names[0]: -0.5, h.names[1]: 0.003})


def test_each_term_says_what_it_means_given_its_sign(msd):
    instance, runs = msd
    found = {t.term.text: t for t in laws(instance, runs)}
    assert meaning(found["x^3"], -60.0) == "a spring that hardens"
    assert meaning(found["x^3"], 60.0) == "a spring that softens"
    assert "restoring force" in meaning(found["x"], -1.0) and "linear spring" in meaning(found["x"], -1.0)
    assert "damping" in meaning(found["v"], -1.0)
    friction = next(t for t in found.values() if t.law == "friction")
    assert meaning(friction, -0.3).startswith("dry (Coulomb) friction opposing v")
    assert "not friction" in meaning(friction, 0.3)
    outflow = PhysicalTerm("tanks", "x2", parse_term("sqrt(x2)"), 1.0, law="sqrt", variable="x2")
    assert "Torricelli" in meaning(outflow, -1.0) and "not an outflow" in meaning(outflow, 1.0)
    root = PhysicalTerm("msd", "v", parse_term("sqrt(x)"), 1.0, law="sqrt", variable="x", position="x")
    assert "restoring force" in meaning(root, -1.0)  # a position: no opening to flow through
    assert meaning(found["v*abs(v)"], -0.1) == "quadratic drag on v"
    assert "not a loss" in meaning(found["v*abs(v)"], 0.1)
    said = readable(found["x^3"], {found["x^3"].name: -60.01})
    assert said == "der(msd.v) += −k3·x^3: a spring that hardens, k3 = 60.01"


def test_look_alikes_pair_a_dead_zone_with_friction_and_a_clamp_with_a_restoring_force(msd):
    instance, runs = msd
    terms = term_hypotheses([instance], runs)
    limits = state_hypotheses({"msd": ("x", "v")}, runs)
    deadzone = SignalHypothesis(
        "input_deadzone",
        "msd.F",
        (Parameter("input_deadzone(msd.F)", 0.1, 0, 1, 0.01),),
        ("deadzone",),
        (0.0,),
        ((0.1,),),
    )
    library = {**terms, **limits, deadzone.name: deadzone}
    (friction,) = [name for name, h in terms.items() if h.law == "friction"]
    assert rivals("input_deadzone(msd.F)", library) == [friction]
    assert "input_deadzone(msd.F)" in rivals(friction, library)
    clamp = {library[name].term.term.text for name in rivals("state_max(msd.x)", library)}
    assert clamp == {"x", "x^3"}  # a spring or a hardening one holds the position back
    assert rivals("derivative_term(msd.der(v), x*F)", library) == []
    saturation = SignalHypothesis(
        "input_min",
        "msd.F",
        (Parameter("input_min(msd.F)", -1, -2, 0, 0.01),),
        ("min",),
        (-math.inf,),
        ((-1,),),
    )
    assert rivals(saturation.name, {**library, saturation.name: saturation}) == []  # not a clamp on a state


def test_the_search_among_many_terms_pays_more_than_one_named_beforehand():
    assert explain.search_charge(30, 0) == 0.0
    assert explain.search_charge(30, 1) == pytest.approx(2 * math.log(30))
    assert explain.search_charge(30, 2) == pytest.approx(2 * math.log(30 * 29 / 2))
    assert explain.search_charge(5, 1) < explain.search_charge(50, 1)
    fit = FitResult("x", ["a"], {"a": 1.0}, 10.0, 100, 3, True, {"a": 0.1}, [], {"a": 1.0})
    assert Candidate(("a",), fit, charge=5.0).bic == pytest.approx(explain.bic(fit) + 5.0)


def _bounded(bound: float) -> tuple[Candidate, dict[str, SignalHypothesis]]:
    name = "state_max(p.x)"
    h = SignalHypothesis(
        "state_max", "p.x", (Parameter(name, bound, 0, 2, 0.01),), ("max",), (math.inf,), ((1,),)
    )
    fit = FitResult("clamp", [name], {name: bound}, 1.0, 100, 3, True, {name: 0.01}, [], {name: bound})
    return Candidate((name,), fit), {name: h}


def test_a_clamp_the_recording_sits_at_is_a_limit_and_one_that_only_stops_a_drift_is_not():
    """Where the fit holds the measured state at its bound, a saturated recording is there too; a drifting
    one is elsewhere, so the clamp only stopped the simulation's drift."""
    t = np.linspace(0.0, 10.0, 201)
    simulated = np.minimum(t / 5.0, 1.0)  # reaches the bound 1.0 at t = 5 and is held there
    rng = np.random.default_rng(0)
    noise = 0.01
    saturated = simulated + rng.normal(0.0, noise, t.size)
    drifting = t / 5.0 + rng.normal(0.0, noise, t.size)  # goes on past 1.0
    chosen, library = _bounded(1.0)
    for recorded, expected in ((saturated, set()), (drifting, {"state_max(p.x)"})):
        residuals = [Residual("p.x", "run", t, simulated - recorded)]
        found = unreached(chosen, library, residuals, {"p.x": {"run": recorded}}, {"p.x": noise})
        assert set(found) == expected
    found = unreached(
        chosen,
        library,
        [Residual("p.x", "run", t, simulated - drifting)],
        {"p.x": {"run": drifting}},
        {"p.x": noise},
    )
    assert "stops the simulation's drift" in found["state_max(p.x)"]
    unmeasured = unreached(chosen, library, [], {}, {"p.y": noise})  # no signal measures p.x: kept
    assert unmeasured == {}


def test_a_term_may_be_named_with_hypothesis_before_any_run_sizes_it():
    """``--hypothesis`` is checked against the library's listing before anything runs: the terms are
    listed by name (a friction's without a width, which is a parameter of its own), and a name the model
    cannot have is refused with the list."""
    from dse_runner.analysis.diagnose.library import Request, checked
    from dse_runner.analysis.diagnose.signal_library import SignalEffects
    from dse_runner.errors import DseError

    space = load_space(PLAIN)
    library = SignalEffects()
    for name in ("derivative_term(msd.der(v), x^3)", "derivative_term(msd.der(v), tanh(v))"):
        assert checked(library, space, Request(hypotheses=(name,))) is library
    with pytest.raises(DseError, match=r"derivative_term\(msd.der\(v\), y\^3\).*no such hypothesis"):
        checked(library, space, Request(hypotheses=("derivative_term(msd.der(v), y^3)",)))
