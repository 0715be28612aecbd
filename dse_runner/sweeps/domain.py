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
from typing import Any

from ..simulation.variables import Value

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
