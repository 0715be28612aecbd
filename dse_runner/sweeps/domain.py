"""The design space as search strategies see it: one :class:`Dimension` per swept variable.

space.yaml gives a parameter as a list of values, a grid ``{start, stop, step | num}``
or an interval ``{low, high}`` (optionally ``log: true`` or ``integer: true``).
A grid strategy (``exhaustive``) needs the first two; a search strategy takes
all three: an interval is continuous, a grid with a step is a stepped interval,
and a list (or a grid without a step) is a set of choices.

Libraries that work on the unit cube (scipy's quasi-Monte Carlo, pymoo) map
``u`` in [0, 1] to a value with :meth:`Dimension.from_unit`; Optuna gets its
own distributions from these fields.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, Discriminator, Field, PositiveFloat, PositiveInt, Tag, model_validator

from ..schema import Strict
from ..simulation.variables import FiniteValue, Value

# A design point: ``instance.variable`` -> the value it is set to. The one definition: strategies ask for
# them, tasks carry them, constraints and fits (floats only) evaluate them, the store's rows record them.
Point = dict[str, Value]


@dataclass(frozen=True)
class Dimension:
    name: str  # instance.variable
    low: float | None = None  # intervals and stepped grids
    high: float | None = None
    log: bool = False
    integer: bool = False
    step: float | None = None  # a stepped grid: low, low + step, ..., high
    choices: tuple[Any, ...] | None = None  # a list, or a grid given by num

    @property
    def steps(self) -> int:
        """How many values a stepped grid has (its ends included when a step lands on the end)."""
        return math.floor((self.high - self.low) / self.step + 1e-9) + 1

    def grid(self) -> list[Any] | None:
        """Every value, or None for a continuous interval (a grid strategy cannot enumerate it)."""
        if self.choices is not None:
            return list(self.choices)
        if self.step is not None:
            return [round(self.low + i * self.step, 12) for i in range(self.steps)]
        if self.integer:
            return [float(v) for v in range(int(self.low), int(self.high) + 1)]
        return None

    def extremes(self) -> list[Any]:
        """Values at the edges: what the spec check tests against the variable's type and bounds."""
        grid = self.grid()
        return grid if grid is not None else [self.low, self.high]

    def from_unit(self, u: float) -> Any:
        """The value at ``u`` in [0, 1]: uniform (or log-uniform) over an interval, one cell per choice."""
        u = min(max(float(u), 0.0), 1.0)
        if self.choices is not None:
            return self.choices[min(int(u * len(self.choices)), len(self.choices) - 1)]
        if self.step is not None:
            return round(self.low + min(int(u * self.steps), self.steps - 1) * self.step, 12)
        if self.integer:
            span = int(self.high) - int(self.low) + 1
            return float(int(self.low) + min(int(u * span), span - 1))
        if self.log:  # clamped: exp(log(high)) can come out a rounding above high (Morris designs ask u = 1)
            value = math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low)))
            return float(min(max(value, self.low), self.high))
        return float(self.low + u * (self.high - self.low))


def from_units(dimensions: list[Dimension], units: Any) -> Point:
    """A point from one row of unit-cube coordinates, in the dimensions' order."""
    return {d.name: d.from_unit(u) for d, u in zip(dimensions, units)}


class Range(BaseModel):
    """``{start, stop, step}`` (stop included when the steps land on it) or ``{start, stop, num}``."""

    model_config = Strict
    start: float
    stop: float
    step: PositiveFloat | None = None
    num: PositiveInt | None = None
    log: bool = False

    @model_validator(mode="after")
    def _one_of_step_or_num(self) -> Range:
        if (self.step is None) == (self.num is None):
            raise ValueError("give exactly one of 'step' or 'num'")
        if self.log and (self.step is not None or self.start <= 0 or self.stop <= 0):
            raise ValueError("a log range needs 'num' and positive 'start' and 'stop'")
        if self.stop < self.start:
            raise ValueError("'stop' must not be below 'start'")
        return self

    def values(self) -> list[float]:
        if self.log:
            return [float(v) for v in np.geomspace(self.start, self.stop, self.num)]
        if self.num is not None:
            return [float(v) for v in np.linspace(self.start, self.stop, self.num)]
        count = math.floor((self.stop - self.start) / self.step + 1e-9) + 1
        # round() keeps 0.1-steps free of 0.30000000000000004 in tables and ids
        return [round(self.start + i * self.step, 12) for i in range(count)]


class Interval(BaseModel):
    """``{low, high}``: every value between, for search strategies; ``log: true`` samples the
    logarithm uniformly, ``integer: true`` takes whole numbers only."""

    model_config = Strict
    low: float
    high: float
    log: bool = False
    integer: bool = False

    @model_validator(mode="after")
    def _ordered(self) -> Interval:
        if not self.high > self.low:
            raise ValueError("'high' must be above 'low'")
        if self.log and self.low <= 0:
            raise ValueError("a log interval needs a positive 'low'")
        if self.integer and not (self.low.is_integer() and self.high.is_integer()):
            raise ValueError("an integer interval needs whole-number 'low' and 'high'")
        return self


def _parameter_kind(value: Any) -> str | None:
    if isinstance(value, Interval) or (isinstance(value, dict) and ("low" in value or "high" in value)):
        return "interval"
    return "range" if isinstance(value, (dict, Range)) else "values" if isinstance(value, list) else None


# A list of values, a grid or an interval; the discriminator makes a wrong one give
# one message, not one per kind.
ParameterValues = Annotated[
    Annotated[Annotated[list[FiniteValue], Field(min_length=1)], Tag("values")]
    | Annotated[Range, Tag("range")]
    | Annotated[Interval, Tag("interval")],
    Discriminator(
        _parameter_kind,
        custom_error_type="parameter_values",
        custom_error_message="expected a list of values, a grid {start, stop, step or num} "
        "or an interval {low, high}",
    ),
]


def _normal(value: Any) -> Any:
    """Numbers as floats, so 1000 and 1000.0 are one point (and one task id)."""
    return float(value) if isinstance(value, int) and not isinstance(value, bool) else value


def dimension(name: str, values: list[Any] | Range | Interval) -> Dimension:
    """How a search strategy sees one parameter (domain.py)."""
    if isinstance(values, Interval):
        return Dimension(name, values.low, values.high, log=values.log, integer=values.integer)
    if isinstance(values, Range) and values.step is not None and not values.log:
        return Dimension(name, values.start, values.values()[-1], step=values.step)
    listed = values.values() if isinstance(values, Range) else values
    return Dimension(name, choices=tuple(dict.fromkeys(_normal(v) for v in listed)))
