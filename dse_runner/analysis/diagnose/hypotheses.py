"""What a hypothesis is: a named, explained effect with the parameters that model it.

Why: every hypothesis library (library.py) names its effects the same way, so that the fits, the
choice among them (explain.py) and the JSON treat a Robotti's wheel slip and a late input of any
FMU alike. Each parameter is zero (or neutral) when the effect is absent, so that every hypothesis,
and every combination of them, is one point of one space.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict


class EffectParameter(BaseModel):
    """One parameter of an effect: a variable of the space the fits run in, and its range."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    variable: str  # a space parameter: an FMU variable of an effects variant, or a master-side effect
    unit: str
    lower: float
    upper: float
    step: float  # finite-difference step of the fit


class Hypothesis(BaseModel):
    """One effect a library can name: a stable id, a physical name, the physics, the residual signature
    it leaves, and its parameters."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    id: str
    name: str
    explanation: str
    signature: str  # what it does to the residuals
    parameters: tuple[EffectParameter, ...] = ()
    magnitude_unit: str = ""

    def magnitude(self, values: dict[str, float]) -> float:
        """One number for the size of the effect: the Euclidean norm of its parameters."""
        return math.hypot(*(values[p.variable] for p in self.parameters)) if self.parameters else 0.0

    @property
    def variables(self) -> list[str]:
        return [p.variable for p in self.parameters]
