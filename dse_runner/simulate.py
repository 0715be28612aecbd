"""One co-simulation of a multi-model on one recorded scenario, scored.

This is the unit of work a sweep repeats for every (parameter point,
scenario) pair: the multi-model's fixed values, then the scenario's, then the
point's overrides, co-simulated over the scenario's duration and scored with
the objectives.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from . import objectives as objs
from .cosim import Plan, Trajectory, make_plan, run
from .multimodel import MultiModel, Value, load_multimodel
from .scenario import Scenario, load_scenario


@dataclass(frozen=True)
class SimulationResult:
    scenario: Scenario
    values: dict[str, Value]
    step: float
    trajectory: Trajectory
    objectives: dict[str, float]


def scenario_values(multimodel: MultiModel, scenario: Scenario) -> dict[str, Value]:
    """The FMU values the multi-model takes from this scenario (steering file, initial pose...)."""
    return {ref: scenario.value_of(field) for ref, field in multimodel.scenario.items()}


def as_plan(multimodel: Plan | MultiModel | str | Path) -> Plan:
    if isinstance(multimodel, Plan):
        return multimodel
    if not isinstance(multimodel, MultiModel):
        multimodel = load_multimodel(multimodel)
    return make_plan(multimodel)


def simulate(
    multimodel: Plan | MultiModel | str | Path,
    scenario: Scenario | str | Path,
    overrides: dict[str, Value] | None = None,
    objectives: tuple[str, ...] = objs.DEFAULT,
    step: float | None = None,
    timeout: float | None = None,
) -> SimulationResult:
    """Co-simulate ``multimodel`` on ``scenario`` with ``overrides`` and score it."""
    plan = as_plan(multimodel)
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    values = {**plan.multimodel.parameters, **scenario_values(plan.multimodel, scenario), **(overrides or {})}
    step = step or plan.multimodel.step or scenario.control_period
    trajectory = run(plan, values, 0.0, scenario.info.duration, step, timeout)
    scores = objs.evaluate(objectives, trajectory, scenario)
    return SimulationResult(scenario, values, step, trajectory, scores)
