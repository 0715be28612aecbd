"""Combination screens: how the combinations worth a real fit are found before any is fitted.

The contract is ``base`` (what a strategy takes and answers, and the default shortlist); the strategies are
``mixed`` (mixtures of the single fits' changes) and ``linearised`` (the residuals linearised at none and
the best singles); ``registry`` names them for ``--screen``.
"""

from .base import Screened, Screening, ScreenSettings, ScreenStrategy
from .registry import GROUP, known, names, strategy

__all__ = ["GROUP", "ScreenSettings", "ScreenStrategy", "Screened", "Screening", "known", "names", "strategy"]
