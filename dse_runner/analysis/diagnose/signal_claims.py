"""What the signal effects' diagnosis may claim: twins named where the recordings cannot tell them apart,
and where a remaining error must lie (the noise rule, that a member is claimed only if it changes the fit by
more than the noise, is every library's: explain.claimed).

Two effects fit alike when neither's held-out error is clearly lower. The evidence between them is the
engine's (lookalike.py): the log-likelihood ratio of their residuals, corrected for the residuals'
autocorrelation, which decides where held-out error and BIC cannot. This library supplies the twins
(:func:`alike`) and the samples' layout and segments (:func:`segments`); the windows of time where the two
residuals differ most say where a run tells them apart. Where nothing does, the diagnosis names both.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...simulation import derivative_terms
from . import explain, lookalike
from .explain import Candidate
from .noise import Whiteness
from .signal_locate import CHANGING, NO_INPUT, STEADY, Residual, activity, window_of, windows

LOOKALIKES = 3  # at most this many look-alikes are weighed
TELLING = 1.0  # a window tells two fits apart when their mean squares there differ by a noise variance


# ---- limits the recordings reach ----------------------------------------------------------------------

LIMITS = ("output_max", "output_min", "state_max", "state_min", "state_overflow")
REACHED = 3.0  # the recording is at a bound where it lies within this many noise σ of it
HELD = 0.1  # the fit holds a signal at its bound where it lies within this share of a noise σ of it
AT_BOUND = 0.5  # share of the samples the fit holds at a bound where the recording must be there too


def unreached(
    chosen: Candidate,
    library: Mapping[str, Any],
    residuals: Sequence[Residual],
    recorded: Mapping[str, Mapping[str, np.ndarray]],
    noise: Mapping[str, float],
) -> dict[str, str]:
    """The limits of ``chosen`` on a measured signal that the recordings do not reach, each with its reason:
    a bound is physics (a sensor's end of range, a store that is full) only if, where the fit holds the signal
    at it, the recording is there too. A clamp the fit holds while the recording is elsewhere only stops the
    simulation's drift. ``residuals``: the chosen fit's, in the signals' units; ``recorded``: each compared
    signal's recorded values per scenario, at the residuals' samples; a limit on a state no signal measures
    cannot be judged here and is kept."""
    found = {}
    for member in chosen.ids:
        h = library[member]
        if h.id not in LIMITS or h.target not in noise:
            continue
        kind = "min" if h.id.endswith("min") else "max"
        bound = chosen.full.values[h.parameters[h.kinds.index(kind)].name]
        sigma = noise[h.target]
        held = there = 0
        for r in residuals:
            if r.signal != h.target or r.scenario not in recorded.get(h.target, {}):
                continue
            values = np.asarray(recorded[h.target][r.scenario], float)[: r.values.size]
            simulated = values + r.values[: values.size]
            at = np.abs(simulated - bound) <= HELD * sigma
            held += int(at.sum())
            there += int(np.sum(np.abs(values[at] - bound) <= REACHED * sigma))
        if held and there < AT_BOUND * held:
            found[member] = (
                f"while the fit holds {h.target} at {bound:.4g}, the recording is there on {there} of its "
                f"{held} samples: the bound stops the simulation's drift, not a limit the process reaches"
            )
    return found


# ---- look-alikes ---------------------------------------------------------------------------------


def alike(
    chosen: Candidate, candidates: Sequence[Candidate], min_gain: float = explain.MIN_GAIN
) -> list[Candidate]:
    """The cross-validated candidates that fit as well as the chosen one on held-out runs (neither is
    ``min_gain`` better) and are a different explanation (neither a part nor a superset of it)."""
    if not chosen.ids:
        return []
    inside = set(chosen.ids)
    found = [
        c
        for c in explain.ranked(list(candidates))
        if c.validated
        and c.ids
        and not set(c.ids) <= inside
        and not inside <= set(c.ids)
        and c.cross_validated * (1.0 - min_gain) <= chosen.cross_validated
    ]
    return found[:LOOKALIKES]


def segments(
    residuals: Mapping[str, Sequence[Residual]], noise: Mapping[str, float], scenarios: Mapping[str, Any]
) -> lookalike.Segments:
    """The layout the engine weighs twins on: each compared signal of each run a piece of one component
    (its residual over its recording's noise, so σ is 1), each sample labelled by what the driven inputs do
    in its window (signal_locate.windows, as the misfit is located): ``changing``, ``steady`` or ``no
    input``. Why these segments: twins differ in how the model answers its inputs (a delay against a lag,
    a gain against an offset), which shows where the inputs move, or in what holds while they rest; they
    come from the inputs alone, never from a fit that would then judge itself. ``residuals``: per
    candidate label (a candidate missing there cannot be weighed)."""

    def labels(r: Residual) -> np.ndarray:
        edges = windows(r.time)
        kinds = [activity(scenarios[r.scenario], edges[k], edges[k + 1]) for k in range(len(edges) - 1)]
        return np.array(kinds, dtype=object)[window_of(r.time, edges)]

    def pieces(candidate: Candidate) -> list[lookalike.Piece] | None:
        found = residuals.get(candidate.label)
        return [(r.values[None, :] / noise[r.signal], labels(r)) for r in found] if found else None

    return lookalike.Segments(pieces, (CHANGING, STEADY, NO_INPUT))


@dataclass
class FitsAlike:
    """The chosen set against one that fits alike: the scenario-level evidence (explain.evidence), the
    engine's LLR between their residuals and its decision (``llr``; None when they could not be laid out
    alike), and the windows of time where their residuals differ by more than the noise."""

    chosen: str
    other: str
    evidence: explain.Evidence
    telling: list[dict[str, Any]] = field(default_factory=list)  # windows, most telling first
    favours_chosen: float = 0.0  # summed difference of mean squares over the telling windows (other - chosen)
    llr: lookalike.Twins | None = None

    @property
    def told_apart(self) -> bool:
        """Whether the recordings tell the two apart: by the engine's rule (held-out error and BIC, else the
        LLR); without an LLR, by a window where they differ by more than the noise."""
        return self.llr.decision != lookalike.CANNOT_TELL if self.llr else bool(self.telling)

    def to_json(self) -> dict[str, Any]:
        e = self.evidence
        return {
            "chosen": self.chosen,
            "id": self.other,
            "held_out": e.other_held_out,
            "delta_held_out": e.delta_held_out,
            "delta_bic": e.delta_bic,
            "runs_better": e.runs_better_text,
            "runs_tied": e.runs_tied,
            "told_apart": self.told_apart,
            "favours_chosen": self.favours_chosen,
            "telling_windows": self.telling,
            "segment_llr": self.llr.to_json() if self.llr else None,
        }


def telling_windows(
    chosen: Sequence[Residual],
    other: Sequence[Residual],
    noise: Mapping[str, float],
    scenarios: Mapping[str, Any],
    count: int = 5,
) -> list[dict[str, Any]]:
    """The windows (signal_locate.windows) where the two fits' mean squares differ by at least ``TELLING``
    noise variances, largest first: where a run tells the two apart."""
    theirs = {(r.signal, r.scenario): r for r in other}
    found = []
    for mine in chosen:
        twin = theirs.get((mine.signal, mine.scenario))
        if twin is None or twin.values.size != mine.values.size:
            continue
        edges = windows(mine.time)
        index = window_of(mine.time, edges)
        sigma2 = noise[mine.signal] ** 2
        for k in range(len(edges) - 1):
            inside = index == k
            if not inside.any():
                continue
            delta = float(np.mean(twin.values[inside] ** 2) - np.mean(mine.values[inside] ** 2)) / sigma2
            if abs(delta) >= TELLING:
                found.append(
                    {
                        "signal": mine.signal,
                        "scenario": mine.scenario,
                        "start": float(edges[k]),
                        "stop": float(edges[k + 1]),
                        "input": activity(scenarios[mine.scenario], edges[k], edges[k + 1]),
                        "delta_mean_square": delta,
                    }
                )
    return sorted(found, key=lambda w: -abs(w["delta_mean_square"]))[:count]


def weigh(
    chosen: Candidate,
    other: Candidate,
    residuals: Mapping[str, Sequence[Residual]],
    noise: Mapping[str, float],
    scenarios: Mapping[str, Any],
) -> FitsAlike:
    """The evidence between the chosen set and a look-alike: their held-out errors, the engine's LLR between
    their full fits' residuals (and its decision), and the windows where those residuals differ."""
    telling = telling_windows(residuals[chosen.label], residuals[other.label], noise, scenarios)
    llr = lookalike.weighed(chosen, other, segments(residuals, noise, scenarios), 1.0)
    if llr is not None:
        llr.chosen = chosen.label
    return FitsAlike(
        chosen.label,
        other.label,
        explain.evidence(chosen, other),
        telling,
        float(sum(w["delta_mean_square"] for w in telling)),
        llr,
    )


# ---- what the verdict says -----------------------------------------------------------------------


def verdict_text(
    verdict: str,
    held_out: float,
    chosen: Candidate,
    interfaces: Mapping[str, str],
    looks: Sequence[FitsAlike],
    dropped: Sequence[explain.Dropped],
    factor: float,
    formulas: Sequence[str] = (),
    coloured: Mapping[str, Whiteness] | None = None,
    terms: bool = False,
) -> str:
    """The verdict in a sentence: what was named (a term inside the model as its ``formulas``' sentence), what
    was not claimed, which twins cannot be told apart, whose residuals are not white, and, when an error well
    above the noise remains, where it must lie (``terms``: whether terms inside were offered)."""
    written = [i for i in chosen.ids if not i.startswith(f"{derivative_terms.PREFIX}(")]
    named = ", ".join([*written, *formulas]) or "no effect"
    parts = [f"{verdict}: {named}; held-out error {held_out:.3g} noise floors"]
    for signal, w in (coloured or {}).items():
        parts.append(
            f"the residuals of {signal} are not white (lag-1 autocorrelation {w.rho1:.2f}, Ljung-Box p "
            f"{w.p:.2g}): either the model still misses something there, or the recording's noise is "
            "coloured and its floor reads low"
        )
    noise = [d.id for d in dropped if not d.reason]
    if noise:
        parts.append("not claimed (changes the fit by less than the noise): " + ", ".join(noise))
    parts += [f"not claimed: {d.id} ({d.reason})" for d in dropped if d.reason]
    twins = [x.other for x in looks if not x.told_apart]
    if twins:
        parts.append(
            f"the recordings cannot tell {named} from {', '.join(twins)}: a run that moves the inputs "
            "differently (another shape or timing, or a release away from rest) would"
        )
    if verdict in (explain.PARTIAL, explain.UNEXPLAINED) and explain.above_floor(held_out, 1.0, factor):
        parts.append(
            interior(interfaces, factor, terms)
        )  # not when only the residuals' colour made it partial
    return "; ".join(parts)


def interior(interfaces: Mapping[str, str], factor: float, terms: bool = False) -> str:
    """Where an error the signal effects leave must lie: inside the FMUs, and whether that can be corrected;
    ``terms``: whether the physical terms inside the model-exchange FMUs were tried too."""
    cs = sorted(name for name, kind in interfaces.items() if kind == "cs")
    me = sorted(name for name, kind in interfaces.items() if kind == "me")
    tried = "every effect on the inputs and outputs" + (
        " and every physical term offered inside" if terms else ""
    )
    said = [
        (
            f"more than {factor:g} noise floors remain after {tried}, so the missing part lies inside the "
            "model"
            + (
                ", beyond the terms offered (or the noise is coloured and its floor reads low)"
                if terms
                else ""
            )
        )
    ]
    if cs:
        said.append(
            f"inside the co-simulation FMU{'s' * (len(cs) > 1)} {', '.join(cs)}, which cannot be augmented "
            "from outside: only its inputs and outputs can be corrected, and the FMU itself has to change"
        )
    if me and not terms:
        said.append(
            f"the model-exchange FMU{'s' * (len(me) > 1)} {', '.join(me)} could take a correction of "
            "their state derivatives, integrated by the master"
        )
    return ": ".join(said[:1]) + ("; " + "; ".join(said[1:]) if len(said) > 1 else "")
