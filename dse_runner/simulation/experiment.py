"""The experiment: from when to when a study simulates, and with which communication step.

Several places may say it; the most specific wins (docs/space.md):

====================  =====================================================================
start and stop time   the caller (``--start-time``) > the scenario > the space's
                      ``experiment`` > a single FMU's DefaultExperiment > start 0, stop
                      start + 1 (FMPy's defaults)
step                  the caller > the scenario's ``step`` > the space's ``experiment`` >
                      the multi-model's ``step`` > the scenario's data period (a field-data
                      steering log's) > a single FMU's DefaultExperiment > FMPy's automatic
                      interval (single FMU only)
====================  =====================================================================

A multi-model of several FMUs has no default stop time or step: a study must
give them, and the error says where.
"""

from __future__ import annotations

from dataclasses import dataclass

from fmpy.util import auto_interval
from pydantic import BaseModel, PositiveFloat, model_validator

from ..errors import DseError
from ..schema import Strict


class Experiment(BaseModel):
    """``experiment: {start_time: 0, stop_time: 100, step: 0.1}`` in space.yaml."""

    model_config = Strict
    start_time: float | None = None
    stop_time: float | None = None
    step: PositiveFloat | None = None

    @model_validator(mode="after")
    def _ordered(self) -> Experiment:
        if self.stop_time is not None and self.stop_time <= (self.start_time or 0.0):
            raise ValueError(f"stop_time {self.stop_time} must be after start_time {self.start_time or 0.0}")
        return self


@dataclass(frozen=True)
class Times:
    start: float
    stop: float
    step: float


def _first(*candidates: float | None) -> float | None:
    return next((c for c in candidates if c is not None), None)


def resolve_times(
    plan,
    scenario,
    experiment: Experiment | None = None,
    start: float | None = None,
    stop: float | None = None,
    step: float | None = None,
) -> Times:
    """The start, stop and step of one simulation of ``plan`` on ``scenario``."""
    experiment = experiment or Experiment()
    single = len(plan.fmu_paths) == 1
    fmu_start, fmu_stop, fmu_step = plan.defaults
    start = _first(start, scenario.start_time, experiment.start_time, fmu_start, 0.0)
    stop = _first(stop, scenario.stop_time, experiment.stop_time, fmu_stop, start + 1.0 if single else None)
    if stop is None:
        raise DseError(
            f"no stop time for scenario {scenario.name}: give experiment: {{stop_time: ...}} in "
            "space.yaml, --stop-time, or the scenario's stop_time"
        )
    if stop <= start:
        raise DseError(f"stop time {stop:g} must be after start time {start:g} (scenario {scenario.name})")
    step = _first(step, scenario.step, experiment.step, plan.multimodel.step, scenario.natural_step, fmu_step)
    if step is None:
        if not single:
            raise DseError(
                f"no communication step for scenario {scenario.name}: give experiment: {{step: ...}} "
                "in space.yaml, --step, or the multi-model's step"
            )
        step = float(auto_interval(stop - start))
    return Times(float(start), float(stop), float(step))
