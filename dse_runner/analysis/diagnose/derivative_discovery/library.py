"""The candidate terms: products and powers of a model-exchange instance's states and inputs, and a few
smooth nonlinearities, each sized by what it adds to its derivative along the simulated runs.

Why: a term missing from a model's equations is most often a low power or product of the quantities the
equations already use (a hardening spring x³, a drag v·|v|, a coupling x·F) or a smoothed sign (a Coulomb
friction tanh(v/w)). The library offers them all for every state whose derivative is physics, not a
definition: a derivative that equals another state on every run (der(x) = v) is kinematics, and no term
belongs there.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ....simulation import derivative_terms as dt
from ....simulation.fmu import describe
from ....simulation.plan import Plan

SMOOTH = 0.1  # a smoothed sign's width, as a share of its variable's RMS over the runs
KINEMATIC = 1e-9  # a derivative within this share of a state's size from that state is that state


@dataclass(frozen=True)
class ModelExchangeInstance:
    """A model-exchange instance as the library sees it: its states, their
    derivative variables, its real inputs."""

    name: str
    states: tuple[str, ...]
    derivatives: tuple[str, ...]  # the FMU's variable for each state's derivative, in the same order
    inputs: tuple[str, ...]

    @property
    def recorded(self) -> list[str]:
        """What a run must record for the library: every state, derivative and real input."""
        return [f"{self.name}.{v}" for v in (*self.states, *self.derivatives, *self.inputs)]


@dataclass(frozen=True)
class CandidateTerm:
    """One term on one state's derivative, with the size of a coefficient that makes it matter."""

    instance: str
    state: str
    term: dt.Term
    scale: (
        float  # RMS of the derivative over RMS of the term: a coefficient that adds as much as the derivative
    )

    @property
    def name(self) -> str:
        return dt.term_name(self.instance, self.state, self.term)

    @property
    def target(self) -> str:
        return f"{self.instance}.der({self.state})"


def model_exchange_instances(plan: Plan) -> list[ModelExchangeInstance]:
    """The plan's model-exchange instances (the only ones the master can add terms to)."""
    found = []
    for name, interface in plan.interfaces.items():
        if interface != "me":
            continue
        description = describe(plan.fmu_paths[name])
        states = dt.states_of(description)
        derivatives = [d.variable.name for d in description.derivatives if d.variable.derivative is not None]
        found.append(
            ModelExchangeInstance(
                name, tuple(states), tuple(derivatives), tuple(dt.real_inputs_of(description))
            )
        )
    return found


def rms(values: Sequence[np.ndarray]) -> float:
    joined = np.concatenate([np.asarray(v, float) for v in values]) if values else np.zeros(0)
    return float(np.sqrt(np.mean(joined**2))) if joined.size else 0.0


def kinematic_pairs(
    instance: ModelExchangeInstance, runs: Sequence[Mapping[str, np.ndarray]]
) -> dict[str, str]:
    """Each state whose derivative is another state on every run (der(x) = v), with that state: a position
    and its velocity. The first is a definition, not physics; the second is what moves (and what friction
    opposes)."""
    found = {}
    for state, derivative in zip(instance.states, instance.derivatives):
        for other in instance.states:
            size = max(max(float(np.max(np.abs(r[f"{instance.name}.{other}"]))) for r in runs), 1.0)
            if other != state and all(
                np.max(np.abs(r[f"{instance.name}.{derivative}"] - r[f"{instance.name}.{other}"]))
                <= KINEMATIC * size
                for r in runs
            ):
                found[state] = other
    return found


def kinematic(instance: ModelExchangeInstance, runs: Sequence[Mapping[str, np.ndarray]]) -> set[str]:
    """The states whose derivative is another state on every run (der(x) = v): definitions, not physics."""
    return set(kinematic_pairs(instance, runs))


def width(values: Sequence[np.ndarray], share: float = SMOOTH) -> float:
    """A smoothed sign's width for a variable: ``share`` of its RMS, to two significant digits (it is
    written in the term's name)."""
    size = share * rms(values)
    return float(f"{size:.2g}") if size > 0 else 1.0


def terms(
    variables: Sequence[str], states: Sequence[str], widths: Mapping[str, float], degree: int
) -> list[dt.Term]:
    """1; every monomial of ``variables`` up to ``degree``; z·|z| for each
    variable; tanh(s/w) for each state."""
    found = [dt.Term()]
    for order in range(1, degree + 1):
        for combination in itertools.combinations_with_replacement(variables, order):
            counts = {v: combination.count(v) for v in dict.fromkeys(combination)}
            found.append(dt.Term(tuple(dt.Factor(v, power=p) for v, p in counts.items())))
    found += [dt.Term((dt.Factor(v), dt.Factor(v, "abs"))) for v in variables]
    found += [dt.Term((dt.Factor(s, "tanh", widths[s]),)) for s in states]
    return found


def candidate_terms(
    instance: ModelExchangeInstance, runs: Sequence[Mapping[str, np.ndarray]], degree: int = 3
) -> list[CandidateTerm]:
    """Every library term on every non-kinematic state's derivative, for the variables that vary on
    some run, sized over ``runs`` (each a recorded run: signal name -> values). A term that is
    zero on every run is left out."""

    def values(name: str) -> list[np.ndarray]:
        return [np.asarray(r[f"{instance.name}.{name}"], float) for r in runs]

    varying = [v for v in (*instance.states, *instance.inputs) if any(np.ptp(x) > 0 for x in values(v))]
    states = [s for s in instance.states if s in varying]
    widths = {s: width(values(s)) for s in states}
    library = terms(varying, states, widths, degree)
    skip = kinematic(instance, runs)
    found = []
    for state, derivative in zip(instance.states, instance.derivatives):
        if state in skip:
            continue
        size = rms(values(derivative))
        for term in library:
            feature = rms(
                [
                    np.broadcast_to(
                        term.value({v: r[f"{instance.name}.{v}"] for v in varying}),
                        r[f"{instance.name}.{state}"].shape,
                    )
                    for r in runs
                ]
            )
            if feature > 0 and size > 0 and math.isfinite(feature):
                found.append(CandidateTerm(instance.name, state, term, size / feature))
    return found
