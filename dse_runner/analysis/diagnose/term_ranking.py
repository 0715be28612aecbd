"""Which proposed terms the residuals want first: every proposal of a term search ranked again on what each
term does to its parent fit's residuals, linearised there.

Why: a search proposes terms by its own measure (equation error channel by channel, say), and that
measure may see the model's own misfit too, or weigh channels unfairly (a pair of terms can outrank the one
term they stand in for). The fits judge terms by the residuals, so the ranking does too, on one scale for
every term: at each parent fit, one probe per proposed term (one step of its parameter, its shapes held)
gives the term's column, and forward selection adds the term that lowers the linearised SSE most, the
parent's parameters refitted within their bounds (linear_step.py), while the predicted BIC falls by the
extended margin's share of that term (:func:`forward_selection`). The full fit and every fold choose their
terms the same way, all parents' probes in one sweep. A search supplies only which parameter a term is and
which shapes its probe holds (term_search.TermSearch).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import replace

import numpy as np

from ...sweeps.domain import Point
from ...sweeps.fit import Parameter
from .fitter import Fitter
from .linear_step import bounded_step
from .term_search import Parent, Proposal, TermSearch


def linear_sse(
    r: np.ndarray,
    base: np.ndarray,
    columns: np.ndarray,
    bounds: np.ndarray,
    moves: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[float, np.ndarray]:
    """The least SSE of r + base·a + columns·c with the parent's parameters ``a`` refitted within ``moves``
    (down, up; free without) and the terms' coefficients ``c`` within ±``bounds``, every column solved at
    unit norm (linear_step.bounded_step); returns (SSE, c)."""
    k = base.shape[1]
    down, up = moves if moves is not None else (np.full(k, -np.inf), np.full(k, np.inf))
    step, sse = bounded_step(
        np.hstack([base, columns]),
        r,
        np.concatenate([down, -bounds]),
        np.concatenate([up, bounds]),
        method="trf",
    )
    return sse, step[k:]


def forward_selection(
    r: np.ndarray,
    base: np.ndarray,
    columns: Mapping[str, np.ndarray],
    bounds: Mapping[str, float],
    max_terms: int,
    margin: Callable[[int], float],
    moves: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[list[tuple[str, float]], list[str]]:
    """Forward selection of terms by what they do to the residuals ``r``, linearised at the parent fit
    (``base``: its Jacobian): each step adds the term that lowers the SSE most with the terms already chosen
    and the parent's parameters refitted, while the predicted BIC falls by that term's share of ``margin``
    (the BIC margin k terms must beat), so the chosen set beats the parent by ``margin``, as acceptance asks
    of the real fit. Every term competes on one scale, the residuals: a term that only stands in for another
    loses to it. Returns (chosen terms with their linearised coefficients, every other term by its last
    trial SSE, best first)."""
    n = max(len(r), 1)
    current = linear_sse(r, base, np.zeros((len(r), 0)), np.zeros(0), moves)[0]
    chosen: list[str] = []
    coefficients = np.zeros(0)
    trials: dict[str, float] = {}
    while len(chosen) < max_terms:
        trials = {}
        solutions = {}
        for v in columns:
            if v in chosen:
                continue
            names = [*chosen, v]
            sse, c = linear_sse(
                r,
                base,
                np.column_stack([columns[x] for x in names]),
                np.array([bounds[x] for x in names]),
                moves,
            )
            trials[v], solutions[v] = sse, c
        if not trials:
            break
        best = min(trials, key=trials.get)
        k = len(chosen)
        charge = margin(k + 1) - (margin(k) if k else 0.0)
        if n * math.log(max(trials[best], 1e-300) / max(current, 1e-300)) + math.log(n) > -charge:
            break
        chosen.append(best)
        coefficients, current = solutions[best], trials[best]
        trials.pop(best)
    rest = sorted(trials, key=trials.get)
    return [(v, float(c)) for v, c in zip(chosen, coefficients)], rest


def probes(parent: Parent, parameters: Mapping[str, Parameter], search: TermSearch) -> list[Point]:
    """The parent's point, then the point moved by one step in each proposed term (the missing columns),
    the shapes that term was made at held."""
    point = dict(parent.fit.point)
    out = [point]
    for variable, _ in parent.proposal.ranked:
        p = parameters[variable]
        out.append(
            {
                **point,
                p.name: point.get(p.name, 0.0) + p.step,
                **search.held(parent.proposal.shapes, [variable]),
            }
        )
    return out


def ranked(
    f: Fitter, search: TermSearch, parents: Mapping[str, Parent], bic_margin: float
) -> dict[str, Proposal]:
    """Each parent's proposal re-ranked on its residuals (:func:`forward_selection`), on the parent's
    scenarios only, all in one sweep of probes (one per proposed term and parent; the parents' own points
    are in the store): its terms those the residuals pay for with the search charged
    (TermSearch.charged), its order theirs, then every other term by what it did alone."""
    variables = sorted({v for parent in parents.values() for v, _ in parent.proposal.ranked})
    parameters = {v: search.parameter(v) for v in variables}
    points = {label: probes(parent, parameters, search) for label, parent in parents.items()}
    residuals = f.evaluate(
        [p for probed in points.values() for p in probed],
        [parents[label].scenarios for label, probed in points.items() for _ in probed],
    )
    out = {}
    for label, parent in parents.items():
        if parent.proposal.empty:
            out[label] = parent.proposal
            continue

        def stacked(point: Point, scenarios: tuple[str, ...] = parent.scenarios) -> np.ndarray | None:
            found = [residuals(point, s) for s in scenarios]
            return None if any(x is None for x in found) else np.concatenate(found)

        point, *moved = points[label]
        r = stacked(point)
        if r is None:  # the parent does not simulate (cannot happen for a fitted point): its order stands
            out[label] = parent.proposal
            continue
        whole = parent.fit.jacobian and sum(len(j) for j in parent.fit.jacobian) == len(r)
        base = np.vstack(parent.fit.jacobian) if whole else np.zeros((len(r), 0))
        moves = parent.moves() if whole else None
        columns, bounds = {}, {}
        for (variable, _), probe in zip(parent.proposal.ranked, moved):
            m = stacked(probe)
            if m is not None:
                columns[variable] = (m - r) / parameters[variable].step
                bounds[variable] = parameters[variable].upper
        chosen, rest = forward_selection(
            r, base, columns, bounds, search.max_terms, lambda k: search.charged(bic_margin, k), moves
        )
        proposed = dict(parent.proposal.ranked)
        order = (*chosen, *((v, proposed[v]) for v in rest))
        out[label] = replace(parent.proposal, terms=dict(chosen), ranked=order)
    return out
