"""Search strategies: which parameter points a sweep visits.

A strategy is a function ``(space) -> iterator of points`` (a point maps each
swept ``instance.variable`` to a value). ``exhaustive`` is built in; others
plug in without touching this module, the way ``distributed`` takes plugins:
a package declares an entry point in the group ``dse_runner.search``, e.g. in
its pyproject.toml::

    [project.entry-points."dse_runner.search"]
    latin_hypercube = "my_package.search:latin_hypercube"
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator
from importlib.metadata import entry_points
from typing import TYPE_CHECKING, Any

from ..errors import DseError

if TYPE_CHECKING:
    from .spec import Space

Point = dict[str, Any]
Strategy = Callable[["Space"], Iterator[Point]]


def exhaustive(space: "Space") -> Iterator[Point]:
    """Every combination of the parameters' values that satisfies the constraints."""
    names = list(space.parameters)
    for values in itertools.product(*(space.parameters[n] for n in names)):
        point = dict(zip(names, values))
        if space.admits(point):
            yield point


BUILTIN: dict[str, Strategy] = {"exhaustive": exhaustive}


def strategies() -> dict[str, Strategy]:
    """Built-in strategies and those installed packages declare."""
    found = dict(BUILTIN)
    for entry in entry_points(group="dse_runner.search"):
        found.setdefault(entry.name, entry.load())
    return found


def strategy(name: str) -> Strategy:
    available = strategies()
    if name not in available:
        raise DseError(f"unknown search strategy {name!r}: available are {', '.join(sorted(available))}")
    return available[name]
