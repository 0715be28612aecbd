"""Calibration: the model before any hypothesis, which every diagnosis judges its hypotheses against.

Why here: every library calibrates the same way before its hypotheses are fitted. The space's own search (its
grid, or a design over its intervals: library.calibrated_by_search) runs on the recorded runs, and its best
point starts the least squares of the calibrated parameters: each parameter given more than one real value,
bounded by them (an integer parameter is a choice, not a quantity least squares can move). A library
chooses only the finite-difference step, as a share of each range (over a long record of an oscillation a
step of a percent moves the phase by a good part of a cycle), and what it refines further: the signal
library from many starts; another may fit its baseline among its hypotheses instead.

What least squares does not refine is held where the search found it best (:func:`held_at`): a parameter
given one value at that value, a whole-numbered one at the search's best choice.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from ...sweeps.fit import Parameter
from ...sweeps.rank import Ranking, rank
from ...sweeps.spec import Space
from ...sweeps.sweep import submit


def searched(space: Space, client, say: Callable[[str], None]) -> Ranking | None:
    """The space's own search run on its scenarios and ranked; None when there is nothing to search: no
    parameter, or its points given as they are (search strategy ``given``)."""
    search = space.spec.search
    if not space.dimensions or search.strategy == "given":
        return None
    how = (
        "the space's grid"
        if search.strategy == "exhaustive"
        else f"{search.strategy} over its intervals, {search.max_points} points"
    )
    say(f"calibrating: {space.name}, {how}, on {len(space.scenarios)} runs")
    submit(space, client=client)
    return rank(space.output, space.name)


def parameters_at(space: Space, best: Mapping[str, Any], step: float) -> tuple[Parameter, ...]:
    """The space's parameters given more than one real value, each bounded by them and starting from
    ``best`` (its search's best point), or from the middle of its range where ``best`` lacks it; the
    finite-difference step is ``step`` times the range."""
    params = []
    whole = {d.name for d in space.dimensions if d.integer}
    for name, values in space.parameters.items():  # a grid's values, or an interval's ends
        numbers = [v for v in values if isinstance(v, float)]
        if name not in whole and len(numbers) == len(values) and len(set(numbers)) > 1:
            low, high = min(numbers), max(numbers)
            start = float(best.get(name, 0.5 * (low + high)))
            params.append(Parameter(name, start, low, high, step * (high - low)))
    return tuple(params)


def held_at(space: Space, best: Mapping[str, Any]) -> dict[str, Any]:
    """Every parameter of the space where the search found it best (``best``), or at its first value where
    the search did not set it: what a fit holds of the parameters it does not free."""
    return {name: best.get(name, values[0]) for name, values in space.parameters.items()}
