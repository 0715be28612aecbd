"""The Robotti's fits: the engine's fitter (analysis/diagnose/fitter.py) with the vehicle's effect
parameters, the fix residuals it minimises and Equation 1 as a held-out run's error."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ...analysis.diagnose.fitter import Fitter, scored_ok
from ...analysis.diagnose.validation import Validation
from ...sweeps.fit import FitResult, Parameter
from ...sweeps.spec import Space
from .hypotheses import hypothesis
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


@dataclass
class Chain(Fitter):
    """The engine's fitter with what the Robotti's steps also read: the vehicle's instance and the
    diagnosis settings."""

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
    ) -> Chain:
        """The fits of a diagnosis of ``vehicle``'s effects in ``space``, held out as ``validation`` says."""

        def parameters(hid: str) -> tuple[Parameter, ...]:
            return tuple(
                Parameter(f"{vehicle}.{p.variable}", 0.0, p.lower, p.upper, p.step)
                for p in hypothesis(hid).parameters
            )

        return cls(
            space=space,
            client=client,
            base=base,
            parameters=parameters,
            unfreed={name: values[0] for name, values in space.parameters.items()},
            validation=validation,
            residuals=RESIDUALS,
            scored=[SCORED],
            score=scored_ok(SCORED),
            say=progress,
            in_sample=fitted_error,
            iterations=settings.max_iterations,
            vehicle=vehicle,
            settings=settings,
        )
