"""The built-in library's hypotheses: every effect the master can add to any model without changing it,
with its parameters, their ranges and where its fits start.

Why: what a first model most often misses is either between the model and the world (a late, sluggish,
scaled or biased input or sensor: simulation/signal_effects.py) or a hard limit of the process that
the equations leave out (a tank that overflows, an end stop: simulation/state_limits.py). Both act
outside the FMU, so they can be offered for any model with recordings. Each hypothesis here is one such
effect on one signal or state:

* signal effects on every input all scenarios drive (delay, lag, gain, offset, saturation at a maximum
  or a minimum, dead zone, backlash, rate limit, a square term) and on every compared signal (those a
  sensor has: delay, lag, gain, offset, saturation, a square term);
* state limits on every state of a model-exchange instance: an upper bound (``state_max``), a lower
  bound (``state_min``), and an upper bound whose overflow passes, in a fitted fraction, into another
  state of the instance (``state_overflow``: two parameters, the fraction and the bound).

A hypothesis's parameters are each at a neutral value when it is absent (the model bit for bit without
it); its name is its first parameter's. Ranges and starts come from the data: a delay or a lag up to a
share of the shortest scenario, an offset up to the recorded span, a bound within the span the
calibrated model's state covers on the runs (``observed``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...simulation import signal_effects, state_limits
from ...simulation.run import qualify
from ...simulation.trajectory import Series
from ...sweeps.fit import Parameter
from ...sweeps.spec import Space

SPAN_SHARE = 0.1  # a delay or lag is sought up to this share of the shortest scenario
GAIN_RANGE = (0.5, 2.0)
STARTS = 4  # a delay's or a lag's fit on every scenario starts from this many values across its range: in an
# oscillating model their misfit has local minima a period apart, which a fit from neutral alone can miss
BOUND_STARTS = (0.1, 0.3, 0.5)  # a bound's fits start this share of its state's span inside the span's edge
BOUND_REACH = 1.0  # a bound is sought over this share of the span, from the edge it limits
SQUARE = 3.0  # a square term is sought up to where it adds this many times the signal at its largest
PHYSICS = {  # what each kind of effect stands for, and the residual it leaves
    "delay": (
        "the signal arrives late: a transport or processing delay, a late actuator or a late time stamp",
        "residuals grow with the signal's rate of change; the simulation leads the recording",
    ),
    "lag": (
        "the signal is smoothed on its way: a first-order actuator or sensor response (a filter)",
        "residuals at steps and fast changes, decaying with the lag's time constant; peaks are lower",
    ),
    "gain": (
        "the signal is scaled: a miscalibrated actuator or sensor, or a unit error",
        "residuals proportional to the signal itself",
    ),
    "offset": (
        "the signal is shifted: an actuator's or a sensor's bias",
        "a constant residual, whatever the signal does",
    ),
    "deadzone": (
        (
            "nothing passes until the signal exceeds a threshold: a valve or a pump that needs some drive "
            "before it moves"
        ),
        "the simulation responds to small inputs that the process ignores",
    ),
    "backlash": (
        "play between the signal and what it moves: a gear or linkage that must take up slack first",
        "residuals after every reversal of the signal, the size of the play",
    ),
    "rate": (
        "the signal can change only so fast: a slew-limited actuator",
        (
            "residuals at steps and steep changes, growing with "
            "their size, the simulation ahead of the recording"
        ),
    ),
    "square": (
        (
            "the signal passes through a curved characteristic: an uncalibrated sensor or a nonlinear "
            "actuator (with gain and offset, a polynomial map)"
        ),
        "residuals that grow with the square of the signal: too low at one end, too high at the other",
    ),
    "max": (
        "the signal saturates at a maximum: an actuator at its limit, a sensor at the end of its range",
        "the recording stays flat at its highest values where the simulation goes on",
    ),
    "min": (
        "the signal saturates at a minimum: an actuator at its limit, a sensor at the end of its range",
        "the recording stays flat at its lowest values where the simulation goes on",
    ),
    "state_max": (
        "the state cannot rise above a bound: a store that is full, a tank at its brim, an end stop",
        (
            "the simulation overshoots where the recording stays flat at its highest values, and "
            "falls back too late"
        ),
    ),
    "state_min": (
        "the state cannot fall below a bound: a store that is empty, an end stop",
        "the simulation undershoots where the recording stays flat at its lowest values",
    ),
    "state_overflow": (
        (
            "the state overflows at a bound, and part of what overflows reaches another state (a "
            "tank spilling into the one below)"
        ),
        "the first state stays flat at its highest values while the other rises faster than modelled",
    ),
    # terms inside the model (term_hypotheses.py), by their law
    "term_constant": (
        "a constant inflow, outflow or force the equations leave out: a bias",
        "a residual that grows steadily, as an integrated constant does",
    ),
    "term_linear": (
        "a linear leak, damping, spring or coupling the equations leave out",
        "residuals in proportion to a state or an input, integrated",
    ),
    "term_cubic": (
        "a response that steepens with the cube of a state: a spring that hardens (or softens)",
        "too slow an oscillation at large amplitudes only; small ones fit",
    ),
    "term_square": (
        "a loss growing with a state's square, its sign kept: quadratic drag, turbulent flow",
        "large excursions damped more than small ones",
    ),
    "term_sqrt": (
        "a flow through an opening, growing with the square root of a level (Torricelli)",
        "low levels drain too slowly, high ones too fast",
    ),
    "term_friction": (
        "dry (Coulomb) friction: a force of nearly constant size opposing a velocity, smoothed over a width",
        "the simulation moves where the process sticks, and overshoots after every reversal",
    ),
    "term_product": (
        "an input whose effect scales with a state (a flow that depends on a level, a force on a position)",
        "residuals where the input acts, growing with the state",
    ),
}


@dataclass(frozen=True)
class SignalHypothesis:
    """One effect the library may add: its parameters (the first named as the effect), what each is (a
    kind of PHYSICS), its neutral values, and where its fits start (one value per parameter each)."""

    id: str  # input_delay, output_gain, state_max, ...
    target: str  # the signal or state it acts on
    parameters: tuple[Parameter, ...]
    kinds: tuple[str, ...]
    neutral: tuple[float, ...]
    starts: tuple[tuple[float, ...], ...]
    resolution: float = (
        0.0  # the finest change of its first value a run can show (a delay: one communication step)
    )
    into: str | None = None  # an overflow's receiving state
    law: str = ""  # a term's physical law (term_hypotheses.py): cubic, sqrt, friction, ...
    term: Any = None  # a term's PhysicalTerm: what it reads and adds to, and how it is sized

    @property
    def name(self) -> str:
        return self.parameters[0].name

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def physics(self) -> tuple[str, str]:
        if self.law:
            return PHYSICS[f"term_{self.law}"]
        return PHYSICS[self.id if self.id.startswith("state_") else self.kinds[0]]

    def absent(self) -> dict[str, float]:
        """Its parameters at their neutral values: the model without it."""
        return dict(zip(self.names, self.neutral))

    def start(self, k: int) -> dict[str, float]:
        return dict(zip(self.names, self.starts[k]))


def signal_hypotheses(space: Space, compared_signals: Sequence[str]) -> dict[str, SignalHypothesis]:
    """Every signal effect on every input all scenarios drive and every compared signal, with its range."""
    experiment = space.spec.experiment
    lengths = [
        float(s.stop_time or experiment.stop_time or 0) - float(s.start_time or experiment.start_time or 0)
        for s in space.scenarios
    ]
    span = min((length for length in lengths if length > 0), default=math.inf)
    span = span if math.isfinite(span) else 10.0
    # The master feeds inputs at its communication points, so a run responds to a delay in steps of one
    # (the delay's resolution): a finite difference finer than that sees no change
    step = max((float(s.step or space.spec.experiment.step or 0.0) for s in space.scenarios), default=0.0)
    inputs: dict[str, list[np.ndarray]] = {}
    for scenario in space.scenarios:
        for ref, signal in scenario.inputs.items():
            if isinstance(signal, Series):
                inputs.setdefault(qualify(space.plan, ref), []).append(signal.values)
    driven = [ref for ref, values in inputs.items() if len(values) == len(space.scenarios)]
    outputs = {
        signal: [s.recorded.samples(recorded)[1] for s in space.scenarios if s.recorded]
        for signal, recorded in compared_signals
    }
    found = {}
    for side, signals in (("input", {r: inputs[r] for r in driven}), ("output", outputs)):
        for target, samples in signals.items():
            for kind, (low, high, starts, difference) in signal_ranges(side, samples, span, step).items():
                effect = signal_effects.Effect(side, kind, target)  # type: ignore[arg-type]
                neutral = signal_effects.NEUTRAL[kind]
                found[effect.name] = SignalHypothesis(
                    effect.id,
                    target,
                    (Parameter(effect.name, starts[0], low, high, difference),),
                    (kind,),
                    (neutral,),
                    tuple((v,) for v in starts),
                    step if kind == "delay" else 0.0,
                )
    return found


OUTPUT_KINDS = (
    "delay",
    "lag",
    "gain",
    "offset",
    "max",
    "min",
    "square",
)  # a sensor's; an actuator may have any


def signal_ranges(
    side: str, samples: Sequence[np.ndarray], span: float, step: float
) -> dict[str, tuple[float, float, list[float], float]]:
    """Each kind of effect on one signal: its range, where its fits start, its finite-difference step; from
    the signal's values (``samples``: a driven input's, or a compared signal's recordings), the shortest
    scenario's length ``span`` and the communication ``step``."""
    values = np.concatenate([np.asarray(v, float) for v in samples])
    values = values[np.isfinite(values)]
    low, high = (float(values.min()), float(values.max())) if values.size else (0.0, 1.0)
    size = (high - low) or 1.0
    largest = float(np.max(np.abs(values))) if values.size else 1.0
    largest = largest or 1.0
    rates = [np.max(np.abs(np.diff(v))) for v in samples if len(v) > 1]
    fastest = max(
        float(max(rates, default=0.0)) / (step or 1.0), 1e-9
    )  # per second, at the fastest sample change
    reach = SPAN_SHARE * span

    def multistart(lo: float, hi: float, first: float) -> list[float]:
        others = np.linspace(lo, hi, STARTS + 1)[1:]
        return [first, *(float(v) for v in others if v != first)][:STARTS]

    kinds = {
        "delay": (0.0, reach, multistart(0.0, reach, 0.0), max(0.01 * reach, step)),
        "lag": (0.0, reach, multistart(0.0, reach, 0.0), max(0.01 * reach, step)),
        "gain": (*GAIN_RANGE, [1.0], 0.01 * (GAIN_RANGE[1] - GAIN_RANGE[0])),
        "offset": (-size, size, [0.0], 0.02 * size),
        # a bound starts inside the signal's span: at its edge it would clip
        # nothing, and a fit there sees no slope
        "max": (high - BOUND_REACH * size, high, [high - f * size for f in BOUND_STARTS], 0.01 * size),
        "min": (low, low + BOUND_REACH * size, [low + f * size for f in BOUND_STARTS], 0.01 * size),
        "deadzone": (0.0, 0.5 * largest, [0.1 * largest, 0.3 * largest], 0.01 * largest),
        "backlash": (0.0, 0.5 * size, [0.05 * size, 0.2 * size], 0.01 * size),
        "rate": (0.01 * fastest, fastest, [0.3 * fastest, 0.1 * fastest], 0.01 * fastest),
        "square": (-SQUARE / largest, SQUARE / largest, [0.0], 0.01 / largest),
    }
    return {k: v for k, v in kinds.items() if side == "input" or k in OUTPUT_KINDS}


def state_hypotheses(
    instances: Mapping[str, Sequence[str]], observed: Sequence[Mapping[str, np.ndarray]]
) -> dict[str, SignalHypothesis]:
    """Every bound on every state of the model-exchange ``instances`` (name -> states), ranged over the span
    each state covers in the ``observed`` runs (``instance.state`` -> values); a state that does not move
    gets none."""
    found = {}
    for instance, states in instances.items():
        spans = {}
        for state in states:
            values = [
                np.asarray(run[f"{instance}.{state}"], float)
                for run in observed
                if f"{instance}.{state}" in run
            ]
            values = [v[np.isfinite(v)] for v in values]
            joined = np.concatenate(values) if values else np.zeros(0)
            if joined.size and np.ptp(joined) > 0:
                spans[state] = (float(joined.min()), float(joined.max()))
        for state, (low, high) in spans.items():
            width = high - low
            bounds = {
                "max": Parameter(
                    state_limits.limit_name("max", instance, state),
                    high,
                    high - BOUND_REACH * width,
                    high,
                    0.01 * width,
                ),
                "min": Parameter(
                    state_limits.limit_name("min", instance, state),
                    low,
                    low,
                    low + BOUND_REACH * width,
                    0.01 * width,
                ),
            }
            starts = {
                "max": [high - f * width for f in BOUND_STARTS],
                "min": [low + f * width for f in BOUND_STARTS],
            }
            target = f"{instance}.{state}"
            for kind, bound in bounds.items():
                found[bound.name] = SignalHypothesis(
                    f"state_{kind}",
                    target,
                    (bound,),
                    (kind,),
                    (state_limits.NEUTRAL[kind],),
                    tuple((v,) for v in starts[kind]),
                )
            for other in spans:
                if other == state:
                    continue
                name = state_limits.limit_name("overflow", instance, state, other)
                fraction = Parameter(name, 0.5, 0.0, 1.0, 0.02)
                found[name] = SignalHypothesis(
                    "state_overflow",
                    target,
                    (fraction, bounds["max"]),
                    ("overflow", "max"),
                    (0.0, state_limits.NEUTRAL["max"]),
                    tuple((0.5, v) for v in starts["max"]),
                    into=f"{instance}.{other}",
                )
    return found


def shares(a: SignalHypothesis, b: SignalHypothesis) -> bool:
    """Whether two hypotheses fit a parameter in common (an overflow and its
    bound): they cannot be combined."""
    return bool(set(a.names) & set(b.names))
