"""Hypotheses inside the model: a physical term missing from a model-exchange state's derivative, each fitted
by simulating the whole model, as the library's effects are.

Why: what a first model leaves out inside its equations is most often one of a few physical laws: a spring
that hardens (x³), a drag or a turbulent flow (x·|x|), an outflow through an opening (√|x|, signed), dry
friction (a smoothed sign of a velocity, with a fitted width), a linear leak or coupling, a constant push,
an input whose effect scales with a state (x·u). Offered as hypotheses beside the signal effects, each is
fitted with the calibrated parameters by least squares against the recordings: the master integrates the
whole model with the term, so an unmeasured state (an upper tank) or a noisy derivative does not matter,
and a term competes with the effects that only imitate it from outside (a dead zone on a force against dry
friction) on held-out error.

Each term is sized along the calibrated model's runs (:func:`laws`): its coefficient's range is ±BOUND
times what makes it add as much as its derivative does, and 0 is the model without it.
Each term says what it means in the user's words, given the sign its fit takes (:func:`meaning`).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ...simulation import derivative_terms as dt
from ...sweeps.fit import Parameter
from .derivatives import CandidateTerm, ModelExchangeInstance, kinematic_pairs, rms
from .signal_hypotheses import SignalHypothesis

BOUND = 3.0  # a coefficient adds at most this many times its derivative's RMS
STEP = 0.01  # a coefficient's finite-difference step, as a share of what adds as much as its derivative
WIDTHS = (0.1, 0.01, 0.001)  # a friction's width starts at these shares of its velocity's RMS
WIDTH_RANGE = (1e-4, 1.0)  # ... and is sought between these shares
KIND = "term"  # the hypotheses' id


@dataclass(frozen=True)
class PhysicalTerm(CandidateTerm):
    """A candidate term (its instance, state, term and size) with the law it stands for and how it reads
    the instance's motion: what :func:`meaning` needs to say it in an engineer's words."""

    law: str = ""  # constant, linear, cubic, square, sqrt, friction, product
    variable: str = ""  # the state or input it reads ("" for a constant)
    position: str = ""  # the variable is the position whose rate is ``state`` (der(position) = state)
    velocity: float = 0.0  # a friction's velocity RMS: its width's scale
    moving: bool = False  # ``state`` is a velocity (the rate of another state)


def _shapes(
    state: str,
    states: Sequence[str],
    inputs: Sequence[str],
    moving: bool,
    signed: Collection[str] | None = None,
) -> list[tuple[str, str, dt.Term]]:
    """Every law's term on der(``state``) over the instance's ``states`` and ``inputs``: (law, the variable
    it reads, the term). A friction (``moving``: ``state`` is a velocity) is written without a width: its
    width is a parameter of its own (derivative_width), so its name does not depend on the data. A square
    root only of a state that keeps one sign (``signed``; None: any), as a level or a pressure does: where a
    state crosses zero, √ is no law of it, and its infinite slope there stalls the solver."""
    found: list[tuple[str, str, dt.Term]] = [("constant", "", dt.Term())]
    found += [("linear", v, dt.Term((dt.Factor(v),))) for v in (*states, *inputs)]
    for v in states:
        found += [
            ("cubic", v, dt.Term((dt.Factor(v, power=3),))),
            ("square", v, dt.Term((dt.Factor(v), dt.Factor(v, "abs")))),
        ]
        if signed is None or v in signed:
            found.append(("sqrt", v, dt.Term((dt.Factor(v, "sqrt"),))))
        found += [("product", v, dt.Term((dt.Factor(v), dt.Factor(u)))) for u in inputs]
    if moving:
        found.append(("friction", state, dt.Term((dt.Factor(state, "tanh"),))))
    return found


def term_names(instance: ModelExchangeInstance) -> dict[str, str]:
    """Every term the library could offer ``instance``, by name with its law, before any run sizes them
    (what ``--hypothesis`` may name): on every state's derivative, each state possibly a velocity. A
    diagnosis offers those of them its runs show to be physics."""
    return {
        dt.term_name(instance.name, state, term): law
        for state in instance.states
        for law, _, term in _shapes(state, instance.states, instance.inputs, True)
    }


def laws(instance: ModelExchangeInstance, runs: Sequence[Mapping[str, np.ndarray]]) -> list[PhysicalTerm]:
    """Every physical term on every non-kinematic state's derivative of ``instance``, sized over ``runs``
    (each a run of the calibrated model recording the instance's states, derivatives and real inputs). A
    term that is zero on every run, or whose derivative never moves, is left out."""

    def values(name: str) -> list[np.ndarray]:
        return [np.asarray(r[f"{instance.name}.{name}"], float) for r in runs]

    varying = {v for v in (*instance.states, *instance.inputs) if any(np.ptp(x) > 0 for x in values(v))}
    states = [s for s in instance.states if s in varying]
    inputs = [u for u in instance.inputs if u in varying]
    signed = {
        v
        for v in states
        if min(float(np.min(x)) for x in values(v)) >= 0 or max(float(np.max(x)) for x in values(v)) <= 0
    }
    pairs = kinematic_pairs(instance, runs)  # position -> velocity
    positions = {velocity: position for position, velocity in pairs.items()}
    found = []
    for state, derivative in zip(instance.states, instance.derivatives):
        if state in pairs:  # der(x) = v is a definition: no term belongs there
            continue
        size = rms(values(derivative))
        if not size > 0:
            continue
        speed = rms(values(state))
        moving = state in positions and speed > 0  # a velocity: dry friction opposes it
        shapes = _shapes(state, states, inputs, moving, signed)
        for law, variable, term in shapes:
            # a friction sized as the nearly sharp sign its first start is, not as tanh(v) over a width of 1
            sized = dt.Term((dt.Factor(state, "tanh", _width(speed)),)) if law == "friction" else term
            feature = rms([_feature(sized, instance, r, state) for r in runs])
            if feature > 0 and math.isfinite(feature):
                found.append(
                    PhysicalTerm(
                        instance.name,
                        state,
                        term,
                        size / feature,
                        law=law,
                        variable=variable,
                        position=variable if variable and variable == positions.get(state) else "",
                        velocity=speed if law == "friction" else 0.0,
                        moving=moving,
                    )
                )
    return found


def _width(speed: float, share: float = WIDTHS[0]) -> float:
    """A friction's width at ``share`` of its velocity's RMS ``speed``, to two significant digits."""
    return float(f"{share * speed:.2g}")


def _feature(
    term: dt.Term, instance: ModelExchangeInstance, run: Mapping[str, np.ndarray], state: str
) -> np.ndarray:
    """The term's values along one run."""
    values = {v: np.asarray(run[f"{instance.name}.{v}"], float) for v in (*instance.states, *instance.inputs)}
    return np.broadcast_to(term.value(values), values[state].shape)


def hypothesis(term: PhysicalTerm) -> SignalHypothesis:
    """A term as a hypothesis of the library: its coefficient (and a friction's width) with their ranges,
    neutral at 0, fitted from 0 (a friction from each of WIDTHS, pushing against the motion)."""
    limit = BOUND * term.scale
    coefficient = Parameter(term.name, 0.0, -limit, limit, STEP * term.scale)
    if term.law != "friction":
        return SignalHypothesis(
            KIND, term.target, (coefficient,), ("coefficient",), (0.0,), ((0.0,),), law=term.law, term=term
        )
    low, high = (share * term.velocity for share in WIDTH_RANGE)
    # differenced at a tenth of the narrowest start: a step much finer drowns in the solver's own error
    narrow = WIDTHS[-1] * term.velocity
    width = Parameter(
        dt.width_name(term.instance, term.state, term.term), _width(term.velocity), low, high, 0.1 * narrow
    )
    push = -0.3 * term.scale  # against the motion, a third of what adds as much as the derivative
    starts = tuple((push, _width(term.velocity, share)) for share in WIDTHS)
    return SignalHypothesis(
        KIND,
        term.target,
        (coefficient, width),
        ("coefficient", "width"),
        (0.0, _width(term.velocity)),
        starts,
        law=term.law,
        term=term,
    )


def term_hypotheses(
    instances: Sequence[ModelExchangeInstance], runs: Sequence[Mapping[str, np.ndarray]]
) -> dict[str, SignalHypothesis]:
    """Every physical term of every model-exchange instance, as hypotheses by name."""
    return {t.name: hypothesis(t) for i in instances for t in laws(i, runs)}


# ---- what a term means ---------------------------------------------------------------------------------


def meaning(term: PhysicalTerm, coefficient: float) -> str:
    """What the term says of the process, in an engineer's words, given the sign its fit took."""
    v, s = term.variable, term.state
    against = coefficient < 0
    if term.law == "constant":
        return f"a constant {'outflow or force against' if against else 'inflow or push on'} {s}: a bias"
    if term.law == "linear":
        if v == s:
            return (
                f"a loss in proportion to {s}: a linear leak or damping" if against else f"{s} feeds itself"
            )
        if term.position:
            return (
                f"a restoring force in proportion to {v}: a linear spring" if against else "a negative spring"
            )
        return f"{s} driven in proportion to {v}: a linear coupling"
    if term.law == "cubic":
        if term.position:
            return "a spring that hardens" if against else "a spring that softens"
        return f"a response to {v} that steepens with its cube"
    if term.law == "square":
        if v == s:
            if not against:
                return f"a gain growing with the square of {s}: not a loss"
            return f"quadratic drag on {s}" if term.moving else f"a loss growing with the square of {s}"
        if term.position:
            return (
                "a progressive spring" if against else "a spring that weakens with the square of the position"
            )
        return f"a flow or force from {v} growing with its square, its sign kept"
    if term.law == "sqrt":
        if term.moving and v == s:
            return f"a drag growing with the square root of {s}" if against else f"a push growing with √{s}"
        if term.position:
            return (
                f"a restoring force growing with the square root of {v}" if against else f"a push with √{v}"
            )
        if v == s:
            return (
                f"an outflow of {s} through an opening, growing with its square root (Torricelli)"
                if against
                else f"an inflow growing with the square root of {s}: not an outflow"
            )
        return (
            f"a flow {'out of' if against else 'from'} {v} through an opening, growing with its square root"
        )
    if term.law == "friction":
        return f"dry (Coulomb) friction opposing {s}" if against else f"a push along {s}: not friction"
    return f"the input {term.term.factors[1].variable} acting in proportion to {v}"


SYMBOLS = {
    "constant": "b",
    "linear": "a",
    "cubic": "k3",
    "square": "d",
    "sqrt": "q",
    "friction": "Fc",
    "product": "g",
}


def shown(term: PhysicalTerm) -> str:
    """The term as the user reads it: a friction's width as ``w`` (it is fitted; its name holds the start)."""
    return f"tanh({term.state}/w)" if term.law == "friction" else term.term.text


def readable(term: PhysicalTerm, values: Mapping[str, float]) -> str:
    """``der(msd.v) += −k3·x^3: a spring that hardens, k3 = 60.01``, from the fitted ``values``."""
    coefficient = float(values[term.name])
    symbol = SYMBOLS[term.law]
    told = f"{symbol} = {abs(coefficient):.4g}"
    if term.law == "friction":
        width = values.get(dt.width_name(term.instance, term.state, term.term), term.term.factors[0].width)
        told += f", w = {width:.3g}"
    text = shown(term)
    written = ("−" if coefficient < 0 else "") + (symbol if text == "1" else f"{symbol}·{text}")
    return f"der({term.instance}.{term.state}) += {written}: {meaning(term, coefficient)}, {told}"


# ---- look-alikes: what outside the model imitates a term inside ---------------------------------------

IMITATED = {  # an effect (its id) -> the laws of the terms it imitates from outside
    "input_deadzone": ("friction",),  # a force that must exceed a threshold, as against dry friction
    "input_backlash": ("friction",),
    "state_max": ("linear", "cubic"),  # a clamp on a state, as against a force that restores it
    "state_min": ("linear", "cubic"),
    "state_overflow": ("linear", "sqrt"),  # a spill into another state, as against a flow between them
}


def rivals(name: str, library: Mapping[str, SignalHypothesis]) -> list[str]:
    """The hypotheses that explain what ``name`` does the other way round, inside or outside the model: an
    input's dead zone or backlash and dry friction in the instance it drives; a state's clamp or overflow
    and a restoring force or flow of that state. Each pair is fitted and decided on held-out error."""
    h = library[name]
    if h.term is not None:
        return [other for other, g in library.items() if g.term is None and name in rivals(other, library)]
    laws = IMITATED.get(h.id, ())
    instance, _, variable = h.target.partition(".")
    state = variable if h.id.startswith("state_") else None
    return [
        other
        for other, g in library.items()
        if g.term is not None
        and g.law in laws
        and g.term.instance == instance
        and (state is None or g.term.variable == state)
    ]
