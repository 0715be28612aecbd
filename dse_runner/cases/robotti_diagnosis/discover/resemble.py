"""Discovery, afterwards: does the accepted correction act like an effect of the library?"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ....analysis.diagnose.explain import Candidate
from ....sweeps.domain import Point
from ....sweeps.fit import FitResult, Parameter
from .. import correction
from ..hypotheses import LIBRARY
from .rank_terms import Fitter

RESEMBLES, PARTLY = (
    0.9,
    0.5,
)  # cosine similarity above which a term resembles, partly resembles, a library effect


def _library_parameters(vehicle: str) -> list[tuple[str, Parameter]]:
    return [
        (h.id, Parameter(f"{vehicle}.{p.variable}", 0.0, p.lower, p.upper, p.step))
        for h in LIBRARY.values()
        for p in h.parameters
    ]


def similarity(change: np.ndarray, columns: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> float:
    """Cosine between ``change`` and the best bounded linear combination of ``columns`` (scipy's lsq_linear):
    1 when the effect can reproduce the change, 0 when it cannot move the residuals that way at all."""
    from scipy.optimize import lsq_linear

    norm = float(np.linalg.norm(change))
    if norm == 0.0 or not np.any(columns):
        return 0.0
    scale = np.linalg.norm(columns, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    solved = lsq_linear(columns / scale, change, bounds=(lower * scale, upper * scale), method="bvls")
    fitted = columns / scale @ solved.x
    size = float(np.linalg.norm(fitted))
    return float(fitted @ change / (size * norm)) if size > 0 else 0.0


def resembles(chain: Fitter, chosen: Candidate) -> list[tuple[str, float]]:
    """Each library effect's cosine similarity, in output space, to what the discovered terms do: the change
    of the fix residuals when the terms are switched off, against the best bounded linear combination of
    the effect's own columns there (one sweep of 2 + E points). Best first."""
    point = dict(chosen.full.point)
    off = {**point, **{n: 0.0 for n in point if correction.is_correction(n)}}
    params = _library_parameters(chain.vehicle)
    probes = []
    for _, p in params:
        value = off.get(p.name, 0.0)
        step = p.step if value + p.step <= p.upper else -p.step
        probes.append({**off, p.name: value + step})
    residuals = chain.evaluate([point, off, *probes])

    def stacked(pt: Point) -> np.ndarray | None:
        found = [residuals(pt, s) for s in chain.scenarios]
        return None if any(r is None for r in found) else np.concatenate(found)

    with_, without = stacked(point), stacked(off)
    if with_ is None or without is None:
        return []
    change = with_ - without
    out = []
    for hid in dict.fromkeys(h for h, _ in params):
        cols, lows, highs = [], [], []
        for (owner, p), probe in zip(params, probes):
            if owner != hid:
                continue
            moved = stacked(probe)
            delta = probe[p.name] - off.get(p.name, 0.0)
            cols.append(np.zeros_like(without) if moved is None else (moved - without) / delta)
            lows.append(p.lower - off.get(p.name, 0.0))
            highs.append(p.upper - off.get(p.name, 0.0))
        out.append(
            (hid, similarity(change, np.column_stack(cols), np.minimum(lows, 0.0), np.maximum(highs, 0.0)))
        )
    return sorted(out, key=lambda item: -item[1])


def resemblance_words(similar: Sequence[tuple[str, float]]) -> str:
    """'resembles wheel_slip (0.96)', 'is partly like steering_lag (0.72)' or 'is unlike any library effect':
    a predicate, so a sentence reads "It resembles …"."""
    if not similar:
        return "was not compared with the library (a probe failed to simulate)"
    hid, value = similar[0]
    if value >= RESEMBLES:
        return f"resembles `{hid}` ({value:.2f})"
    if value >= PARTLY:
        return f"is partly like `{hid}` ({value:.2f})"
    return f"is unlike any library effect (closest: `{hid}`, {value:.2f})"


def terms_json(fit: FitResult) -> list[dict[str, Any]]:
    """The discovered terms of a fit as the JSON's ``terms``: readable text,
    parameter, value, ~95 % interval."""
    interval = fit.interval()
    shapes = correction.shape_values(fit.point)
    out = []
    for name, value in fit.values.items():
        if correction.is_correction(name):
            t = correction.term(name)
            low, high = interval[name]
            shape = correction.shape_of(t)
            out.append(
                {
                    "text": correction.readable_term(t, value, (low, high), shapes),
                    "variable": t.variable,
                    "value": value,
                    "interval": [low, high],
                }
                | ({shape.key: shapes[shape.variable]} if shape and shape.variable in shapes else {})
            )
    return out
