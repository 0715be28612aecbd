"""The combination screens by name, as Optuna names its samplers: what ``--screen NAME`` chooses among.

Why a registry: a library declares its default screen by name (HypothesisLibrary.screen) and a user may
choose another (``Request.screen``); the engine looks the name up here and never asks which case it
screens for. Screens are the entry points of the group ``dse_runner.screens`` (plugins.py), dse-runner's
own (``mixed``, ``linearised``) declared in pyproject.toml like anyone's: a new strategy is a
``ScreenStrategy`` subclass and one entry point.
"""

from __future__ import annotations

from .... import plugins
from ....errors import DseError
from .base import ScreenStrategy

GROUP = "dse_runner.screens"


def names() -> list[str]:
    """Every screen installed, by name."""
    return plugins.names(GROUP)


def known(name: str) -> str:
    """``name``, once it names a strategy: an unknown one is an error listing them, before anything runs."""
    if name not in plugins.entries(GROUP):
        raise DseError(f"--screen {name!r}: no such combination screen (known: {', '.join(names())})")
    return name


def strategy(name: str) -> ScreenStrategy:
    """The strategy called ``name``, built and held to the contract."""
    return plugins.instance_of_subclass(
        plugins.entries(GROUP)[known(name)], ScreenStrategy, f"screen {name!r}"
    )
