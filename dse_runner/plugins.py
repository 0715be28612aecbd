"""Installed plug-ins: how an entry point that names a class is loaded and held to its contract.

Why one helper: every group whose entries name a subclass (cluster makers, hypothesis libraries)
should fail the same way, at once and naming the entry, when a plug-in cannot be imported or is
not what its group promises, rather than half-way through a sweep or a diagnosis.
"""

from __future__ import annotations

from importlib.metadata import EntryPoint
from typing import TypeVar

from .errors import DseError

T = TypeVar("T")


def instance_of_subclass(entry: EntryPoint, base: type[T], label: str) -> T:
    """The plug-in class ``entry`` names, checked to be a subclass of ``base`` and built with no arguments;
    ``label`` names it in errors (``cluster.kind 'mine'``)."""
    try:
        found = entry.load()
    except ImportError as e:
        raise DseError(f"{label} ({entry.value}) cannot be imported: {e}") from None
    if not (isinstance(found, type) and issubclass(found, base)):
        raise DseError(f"{label} ({entry.value}) is not a subclass of {base.__module__}.{base.__qualname__}")
    return found()
