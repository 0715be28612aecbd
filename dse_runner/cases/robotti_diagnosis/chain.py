"""The Robotti's fits: the engine's fitter (analysis/diagnose/fitter.py) with the vehicle's effect
parameters, the fix residuals it minimises and Equation 1 as a held-out run's error."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...analysis.diagnose.calibration import held_at
from ...analysis.diagnose.engine import Fits
from ...analysis.diagnose.fitter import scored_ok
from ...analysis.diagnose.validation import Validation
from ...sweeps.fit import FitResult, Parameter
from ...sweeps.spec import Space
from .hypotheses import LOOK_ALIKES, hypothesis
from .outcome import DiagnosisSettings

RESIDUALS = (
    "fix_residuals"  # the field-data case's vector objective (cases/fielddata.py): offsets at every fix
)
SCORED = "cross_track_error"  # a held-out run's error: the paper's Equation 1
DiagnosisMessages = Callable[[str], None]  # one line per step, for a person watching (the CLI: stderr)


def fitted_error(fit: FitResult) -> float:
    """Equation 1 on the runs the fit saw (the mean distance at each run's fixes, averaged over runs), from
    its residuals (x offsets, then y offsets: fielddata.fix_residuals). The same units as held-out error
    and the noise floor, at no cost: optimistic, but by little with a few parameters and many fixes."""
    runs = [np.hypot(*np.split(r, 2)).mean() for r in fit.residuals if len(r) >= 2 and len(r) % 2 == 0]
    return float(np.mean(runs)) if runs else math.inf


TIME_STARTS = 3  # a delay's or a lag's fit starts from absent and from this many less one points inside its
# range: against manoeuvres that repeat (a sine's steering) its misfit has minima a period apart, which a fit
# from absent alone can miss


def time_starts(parameter: Parameter, count: int = TIME_STARTS) -> tuple[float, ...]:
    """The parameter's own start (the effect absent), then ``count`` - 1 points evenly inside its range."""
    span = parameter.upper - parameter.lower
    return (parameter.start, *(parameter.lower + span * k / count for k in range(1, count)))


@dataclass(frozen=True)
class VehicleEffect:
    """A library hypothesis as the engine fits it: its parameters in the vehicle's effects variant, each
    starting absent (0); a one-parameter delay or lag (in seconds) from points inside its range too."""

    parameters: tuple[Parameter, ...]
    starts: tuple[tuple[float, ...], ...]
    term: None = None  # no term inside the model: the correction block is discovery's, not a hypothesis

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def start(self, k: int) -> dict[str, float]:
        return dict(zip(self.names, self.starts[k]))

    @classmethod
    def of(cls, vehicle: str, hid: str) -> VehicleEffect:
        """The library's hypothesis ``hid`` on the instance ``vehicle``."""
        declared = hypothesis(hid).parameters
        parameters = tuple(
            Parameter(f"{vehicle}.{p.variable}", 0.0, p.lower, p.upper, p.step) for p in declared
        )
        timed = len(declared) == 1 and declared[0].unit == "s"
        starts = (
            tuple((v,) for v in time_starts(parameters[0])) if timed else (tuple(0.0 for _ in parameters),)
        )
        return cls(parameters, starts)


@dataclass
class Chain(Fits):
    """The engine's fits (engine.Fits) with the vehicle's effects as its hypotheses, and what the Robotti's
    steps also read: the vehicle's instance and the diagnosis settings."""

    vehicle: str = ""
    settings: DiagnosisSettings = field(default_factory=DiagnosisSettings)

    @classmethod
    def for_vehicle(
        cls,
        space: Space,
        vehicle: str,
        base: tuple[Parameter, ...],
        client,
        settings: DiagnosisSettings,
        progress: DiagnosisMessages,
        validation: Validation,
        best: Mapping[str, Any],
    ) -> Chain:
        """The fits of a diagnosis of ``vehicle``'s effects in ``space``, held out as ``validation`` says,
        what no fit frees held where the calibration's search found it best (``best``)."""

        library = {hid: VehicleEffect.of(vehicle, hid) for (hid,) in settings.singles()}

        return cls(
            space=space,
            client=client,
            base=base,
            parameters=lambda hid: VehicleEffect.of(vehicle, hid).parameters,
            unfreed=held_at(space, best),
            validation=validation,
            residuals=RESIDUALS,
            scored=[SCORED],
            score=scored_ok(SCORED),
            say=progress,
            in_sample=fitted_error,
            iterations=settings.max_iterations,
            library=library,
            look_alikes=LOOK_ALIKES,
            min_gain=settings.min_gain,
            bic_margin=settings.bic_margin,
            survivors=settings.survivors,
            vehicle=vehicle,
            settings=settings,
        )
