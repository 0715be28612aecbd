"""The combination screen's contract: what a strategy is given, what it answers, and the shortlist.

Why a screen: when no single hypothesis explains the recordings to the noise, a combination may, but fitting
every pair and triple for real (a fit on everything and one per fold each) would cost some ten times the
singles. A screen predicts every combination cheaply from the fits already made, checks the most promising
by simulating a few points, and shortlists the best few for engine.cross_validated to fit for real.

How to predict is a strategy, chosen by name (registry.py), as Optuna's study takes any sampler: the stages
never ask which one ran. Lifecycle: :meth:`ScreenStrategy.run` is called once per diagnosis, after
engine.singles, with

* the engine's fits (engine.Fits): the library's hypotheses and their parameters, the calibrated ones
  (``base``), the scenarios, which hypotheses cannot share a set (``shares``), their declared look-alikes,
  and ``evaluate`` to simulate points on every scenario in one sweep;
* the full fits of none (``()``) and of each hypothesis alone, with their final Jacobians and residuals;
* the settings: how many pairs and triples to shortlist (no triple is screened when that is 0), and at most
  how many sets in all.

It answers a :class:`Screening`: every combination it checked by simulation, best real BIC first, and the
shortlist. A strategy implements :meth:`ScreenStrategy.screened`; :meth:`ScreenStrategy.shortlist` is a hook
with a default (the best pairs, the best triples, then their look-alike swaps).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

from ....sweeps.fit import FitResult
from ..engine import Fits
from ..lookalike import swaps

Singles = Mapping[tuple[str, ...], FitResult]  # none (``()``) and each hypothesis alone, fitted on everything


@dataclass(frozen=True)
class ScreenSettings:
    """How much of the screen is fitted for real: a library's declared default, or the user's settings."""

    pairs: int = 3  # best screened pairs fitted for real
    triples: int = 0  # best screened triples fitted for real; with 0 no triple is screened at all
    limit: int = 10  # most sets fitted for real: those pairs and triples, then their look-alike swaps


@dataclass(frozen=True)
class Screened:
    """A combination as the screen saw it: the SSE predicted, and the real SSE at the best point checked."""

    ids: tuple[str, ...]
    anchor: tuple[str, ...]  # the fitted set the prediction was made from (() for none)
    predicted_sse: float
    sse: float  # the best real SSE of the points simulated for it
    bic: float  # of ``sse``, charged for every parameter the set fits
    start: Mapping[str, float]  # where that SSE was found: the set's full fit starts there
    weights: tuple[float, ...] = ()  # how much of each member's single change the prediction mixes in, if so

    @property
    def label(self) -> str:
        return "+".join(self.ids)

    def to_json(self) -> dict[str, Any]:
        found: dict[str, Any] = {
            "id": self.label,
            "from": "+".join(self.anchor) or "none",
            "predicted_sse": self.predicted_sse,
            "sse": self.sse,
            "bic": self.bic,
        }
        return {**found, "weights": list(self.weights)} if self.weights else found


@dataclass
class Screening:
    """What a screen did: its strategy and how it predicts, how many combinations it predicted, those it
    checked by simulation (best real BIC first) and the shortlist fitted for real."""

    strategy: str
    how: str = ""
    predicted: int = 0
    screened: list[Screened] = field(default_factory=list)
    shortlist: list[Screened] = field(default_factory=list)


class ScreenStrategy(ABC):
    """One way to screen combinations: the contract of the entry-point group ``dse_runner.screens`` (the
    module says the lifecycle)."""

    name: ClassVar[str]
    how: ClassVar[str] = ""  # how it predicts, in a sentence a report can say
    shortlisted: ClassVar[ScreenSettings] = ScreenSettings()  # its own default, where a library sets none

    def run(self, fits: Fits, singles: Singles, settings: ScreenSettings) -> Screening:
        """Screen, then shortlist: what the stages call."""
        screened, predicted = self.screened(fits, singles, settings)
        shortlist = self.shortlist(screened, settings, fits.look_alikes)
        return Screening(self.name, self.how, predicted, screened, shortlist)

    @abstractmethod
    def screened(self, fits: Fits, singles: Singles, settings: ScreenSettings) -> tuple[list[Screened], int]:
        """The combinations checked by simulation, best real BIC first, and how many were predicted: pairs,
        and triples when ``settings.triples`` asks for them."""

    def shortlist(
        self,
        screened: Sequence[Screened],
        settings: ScreenSettings,
        look_alikes: Mapping[str, Sequence[str]],
    ) -> list[Screened]:
        """The sets worth a real fit, at most ``settings.limit``: the best pairs and the best triples whose
        simulation succeeded, then the look-alike swaps of those (lookalike.swaps: one member replaced by its
        twin, if that set was screened), best real BIC first."""
        good = [s for s in screened if math.isfinite(s.sse)]
        chosen = [s for s in good if len(s.ids) == 2][: settings.pairs]
        chosen += [s for s in good if len(s.ids) == 3][: settings.triples]
        by_ids = {frozenset(s.ids): s for s in good}
        twins = [by_ids[swap] for s in chosen for swap in swaps(s.ids, look_alikes) if swap in by_ids]
        result: list[Screened] = []
        for s in chosen + sorted(twins, key=lambda x: x.bic):
            if s not in result and len(result) < settings.limit:
                result.append(s)
        return result


def combinable(fits: Fits, ids: Sequence[str]) -> bool:
    """Whether the hypotheses ``ids`` can be in one set: no two act on one thing (an overflow, its bound)."""
    return not any(fits.shares(a, b) for k, a in enumerate(ids) for b in ids[k + 1 :])


def parameter_count(fits: Fits, ids: Sequence[str]) -> int:
    """How many parameters a set fits: the calibrated ones and its hypotheses'."""
    return len(fits.base) + len({p.name for h in ids for p in fits.library[h].parameters})
