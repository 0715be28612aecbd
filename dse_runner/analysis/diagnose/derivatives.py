"""A model-exchange instance's derivatives as terms inside the model see them: its states, derivatives and
inputs (:class:`ModelExchangeInstance`), a term on one derivative (:class:`CandidateTerm`, sized along runs),
which derivatives are definitions (der(x) = v: :func:`kinematic_pairs`), and the runs observed to size them.

Why: the master integrates model-exchange FMUs itself and can add terms to their derivatives
(simulation/derivative_terms.py); term_hypotheses.py builds the physical terms it offers on these.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ...simulation import derivative_terms as dt
from ...simulation.fmu import describe
from ...simulation.plan import Plan
from ...simulation.run import simulate
from ...sweeps.domain import Point
from ...sweeps.spec import Space

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


def observe(
    space: Space, point: Point, instances: Sequence[ModelExchangeInstance], names: Sequence[str] | None = None
) -> list[dict[str, np.ndarray]]:
    """Every scenario (of ``names``, when given) simulated here at ``point``, recording each instance's
    states, derivatives and real inputs: what the library sizes its terms on."""
    plan = space.plan.recording([ref for i in instances for ref in i.recorded], "terms inside the model")
    return [
        simulate(plan, scenario, point, objectives={}, experiment=space.experiment).outputs
        for scenario in space.scenarios
        if names is None or scenario.name in names
    ]
