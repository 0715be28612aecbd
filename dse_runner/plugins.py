"""Plug-ins: every extension point is found the same way, by its entry-point group and a name.

dse-runner's own implementations are entry points of its own distribution (pyproject.toml), found by
the same lookup as another package's: a group's module defines the contract and never imports its
implementations, and a plug-in stands beside the built-ins on equal terms (but cannot take a built-in
name). The groups:

- ``dse_runner.search``: search strategies (sweeps/search.py, ``Strategy`` subclasses)
- ``dse_runner.clusters``: cluster makers (sweeps/makers.py, ``ClusterMaker`` subclasses)
- ``dse_runner.scenarios``: scenario kinds (simulation/scenario.py, ``ScenarioKind`` instances)
- ``dse_runner.objectives``: named objectives (simulation/objectives.py, objectives or functions)
- ``dse_runner.hypotheses``: hypothesis libraries (analysis/diagnose/library.py, ``HypothesisLibrary``
  subclasses)
- ``dse_runner.screens``: combination screens of a diagnosis (analysis/diagnose/screens/, ``ScreenStrategy``
  subclasses)

Why one helper: every group should fail the same way, at once and naming the entry, when a plug-in
cannot be imported or is not what its group promises, rather than half-way through a sweep or a
diagnosis.
"""

from __future__ import annotations

import functools
from importlib.metadata import EntryPoint, entry_points
from typing import Any, TypeVar

from .errors import DseError

T = TypeVar("T")
OWN = "dse-runner"  # the distribution whose entries are the built-ins


def _distribution(entry: EntryPoint) -> str:
    return (entry.dist.name if entry.dist is not None else "").lower().replace("_", "-")


@functools.cache
def entries(group: str) -> dict[str, EntryPoint]:
    """Name -> entry point of ``group``, the built-ins first: a name another package also declares stays
    dse-runner's. Read once per process (scanning the installed distributions takes tens of ms; a test
    that registers a plug-in clears it)."""
    found: dict[str, EntryPoint] = {}
    for entry in sorted(entry_points(group=group), key=lambda e: (_distribution(e) != OWN, e.name)):
        found.setdefault(entry.name, entry)
    return found


def names(group: str) -> list[str]:
    """Every name of ``group``, sorted: for messages that list what is there."""
    return sorted(entries(group))


def load(group: str, name: str, label: str) -> Any:
    """What the entry ``name`` of ``group`` names, imported now; None if no installed package declares it.
    ``label`` names it in errors (``search strategy 'tpe'``)."""
    entry = entries(group).get(name)
    return None if entry is None else loaded(entry, label)


def loaded(entry: EntryPoint, label: str) -> Any:
    """The object ``entry`` names; an import failure is an error naming the entry."""
    try:
        return entry.load()
    except ImportError as e:
        raise DseError(f"{label} ({entry.value}) cannot be imported: {e}") from None
    except AttributeError as e:
        raise DseError(f"{label} ({entry.value}) cannot be loaded: {e}") from None


def subclass_of(found: Any, base: type[T], label: str, value: str) -> type[T]:
    """``found`` held to being a subclass of ``base``."""
    if not (isinstance(found, type) and issubclass(found, base)):
        raise DseError(f"{label} ({value}) is not a subclass of {base.__module__}.{base.__qualname__}")
    return found


def instance_of_subclass(entry: EntryPoint, base: type[T], label: str) -> T:
    """The plug-in class ``entry`` names, checked to be a subclass of ``base`` and built with no arguments;
    ``label`` names it in errors (``cluster.kind 'mine'``)."""
    return subclass_of(loaded(entry, label), base, label, entry.value)()
