"""The combination screens by name, as Optuna names its samplers: what ``--screen NAME`` chooses among.

Why a registry: a library declares its default screen by name (HypothesisLibrary.screen) and a user may
choose another (``Request.screen``); the engine looks the name up here and never asks which case it
screens for. A new strategy is one module beside the others and one line below.
"""

from __future__ import annotations

from ....errors import DseError
from .base import ScreenStrategy
from .linearised import Linearised
from .mixed import Mixed

STRATEGIES: dict[str, type[ScreenStrategy]] = {cls.name: cls for cls in (Mixed, Linearised)}


def known(name: str) -> str:
    """``name``, once it names a strategy: an unknown one is an error listing them, before anything runs."""
    if name not in STRATEGIES:
        raise DseError(f"--screen {name!r}: no such combination screen (known: {', '.join(STRATEGIES)})")
    return name


def strategy(name: str) -> ScreenStrategy:
    """The strategy called ``name``."""
    return STRATEGIES[known(name)]()
