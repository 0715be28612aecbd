"""The choice: the stages every library's diagnosis runs, in this order, to choose among its hypotheses.

Why one function: which sets are fitted, screened, held out and grown, and when a screen is worth its
simulations, is statistics, not a case's physics. A library gives its fits (engine.Fits: its hypotheses,
residuals and score), the combination screen its settings name (screens/) and its noise floor; what it does
afterwards with the choice (look-alikes, the noise rule, discovery) is its own.

1. none and every hypothesis alone, fitted on every scenario from each of its starts (engine.singles);
2. unless a single already fits to within ``floor_stop`` noise floors, or one effect at a time is the most
   allowed, the combinations the screen predicts and checks, its shortlist to fit for real;
3. the singles and the shortlist held out, the BIC gate (engine.cross_validated);
4. the rule's choice (explain.select);
5. grown one effect at a time while each pays its way and the held-out error stays above ``noise_factor``
   floors (engine.grown; not without a floor, which says where "above the noise" is).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ...sweeps.fit import FitResult
from . import answer, engine, explain, screens
from .explain import Candidate

Singles = Mapping[tuple[str, ...], FitResult]


@dataclass
class Choice:
    """What the stages chose, and everything they fitted on the way."""

    baseline: Candidate  # no effect: the calibrated model
    chosen: Candidate  # the baseline when nothing is missing
    everything: list[Candidate]  # none, the singles, the shortlist, what growth tried
    full: dict[tuple[str, ...], FitResult]  # none and each single, fitted on every scenario
    screening: screens.Screening
    unscreened: str = ""  # why no combination was screened; "" when the screen ran
    growth: list[dict[str, Any]] = field(default_factory=list)  # each round of one more effect (engine.grown)


def unscreened(f: engine.Fits, full: Singles, floor: float | None, floor_stop: float, most: int) -> str:
    """Why combinations could not explain more, or "" when they could: not when one effect at a time is the
    most allowed or fewer than two hypotheses are offered, nor when a single already leaves no more than
    ``floor_stop`` noise floors of error on the scenarios it saw (``f.in_sample``). Without a floor
    nothing is within it."""
    fitted = [fit for ids, fit in full.items() if ids and fit.error is None]  # a failed one says nothing
    if most < 2 or len(fitted) < 2:
        return "the settings allow one effect at a time, or fewer than two effects are fitted"
    if floor is None or not (math.isfinite(floor) and floor > 0):
        return ""
    if min(f.in_sample(fit) for fit in fitted) <= floor_stop * floor:
        return f"a single effect already fits within {floor_stop:g} noise floors"
    return ""


def choose(
    f: engine.Fits,
    strategy: screens.ScreenStrategy,
    shortlisted: screens.ScreenSettings,
    floor: float | None = 1.0,
    noise_factor: float = explain.NOISE_FACTOR,
    floor_stop: float = explain.FLOOR_STOP,
    most: int = engine.MAX_EFFECTS,
) -> Choice:
    """The stages of the module's docstring on ``f``'s library; ``floor``: the noise floor in the held-out
    error's units (1 where the residuals are in noise units; None when the recordings give none)."""
    sets, full = engine.singles(f)
    why = unscreened(f, full, floor, floor_stop, most)
    if why:
        screening = screens.Screening(strategy.name, strategy.how)
        f.say(f"no combination screened: {why}")
    else:
        screening = strategy.run(f, full, shortlisted)
        f.say(
            f"combinations ({strategy.name} screen): {screening.predicted} predicted from the single fits, "
            f"{len(screening.screened)} checked, {len(screening.shortlist)} to fit"
        )
    baseline, everything = engine.cross_validated(f, sets, full, screening.shortlist)
    chosen = explain.select(everything[1:], baseline, f.min_gain, f.bic_margin)
    growth: list[dict[str, Any]] = []
    if floor is not None and math.isfinite(floor) and floor > 0:
        chosen, growth = engine.grown(f, chosen, full, everything, noise_factor, floor, most)
    return Choice(baseline, chosen, everything, dict(full), screening, why, growth)


def screen_of(choice: Choice) -> answer.Screen:
    """What the screen did, as the answer says it: its checked sets best first, each marked if fitted."""
    fitted = [x.label for x in choice.screening.shortlist]
    return answer.Screen(
        strategy=choice.screening.strategy,
        how=choice.screening.how,
        predicted=choice.screening.predicted,
        screened=[{**x.to_json(), "shortlisted": x.label in fitted} for x in choice.screening.screened],
        fitted=fitted,
        reason=choice.unscreened,
    )
