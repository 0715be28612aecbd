"""Discovery, stage 2: rank the proposed terms on what each does to the fix residuals, linearised at the
parent fit."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from ....analysis.diagnose.discovery import Parent
from ....analysis.diagnose.fitter import Fitter
from ....analysis.diagnose.proof import extended_margin
from ....sweeps.domain import Point
from ....sweeps.fit import Parameter
from .. import correction
from .propose import CHANNELS, SCANNED, CorrectionProposal


def searched_count() -> int:
    """How many terms the proposal chooses among: the extended BIC charges for the search. A shaped term
    counts once per value scanned (a step at each onset time is a term of its own)."""
    return sum(
        SCANNED if correction.shape_of(t) else 1 for t in correction.searched_terms() if t.channel in CHANNELS
    )


def charged(bic_margin: float, terms: int) -> float:
    """The BIC margin ``terms`` discovered terms must beat: the search among every term the proposal
    offers is charged (proof.extended_margin)."""
    return extended_margin(bic_margin, searched_count(), terms)


def held_shapes(shapes: Mapping[str, float], vehicle: str, variables: Sequence[str]) -> dict[str, float]:
    """The shapes the terms ``variables`` depend on, as the vehicle's parameters at their found values (a
    shape no term uses changes nothing, and leaving it at its default keeps the points the store has)."""
    out = {}
    for v in variables:
        shape = correction.shape_of(correction.term(v))
        if shape is not None and shape.variable in shapes:
            out[f"{vehicle}.{shape.variable}"] = shapes[shape.variable]
    return out


def term_parameters(variables: Sequence[str], vehicle: str, rms: Mapping[str, float]) -> dict[str, Parameter]:
    return {v: correction.parameter(correction.term(v), vehicle, rms.get(v)) for v in variables}


def screen_probes(job: Parent, parameters: Mapping[str, Parameter]) -> list[Point]:
    """The parent's point, then the point moved by one step in each proposed term (the missing columns)."""
    point = dict(job.fit.point)
    out = [point]
    for variable, _ in job.proposal.ranked:
        p = parameters[variable]
        out.append(
            {
                **point,
                p.name: point.get(p.name, 0.0) + p.step,
                **held_shapes(job.proposal.shapes, p.name.rsplit(".", 1)[0], [variable]),
            }
        )
    return out


def linear_sse(
    r: np.ndarray,
    base: np.ndarray,
    columns: np.ndarray,
    bounds: np.ndarray,
    moves: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[float, np.ndarray]:
    """The least SSE of r + base·a + columns·c with the parent's parameters ``a`` refitted within ``moves``
    (down, up; free without) and the terms' coefficients ``c`` within ±``bounds``; returns (SSE, c)."""
    from scipy.optimize import lsq_linear

    matrix = np.hstack([base, columns])
    scale = np.linalg.norm(matrix, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    k = base.shape[1]
    down, up = moves if moves is not None else (np.full(k, -np.inf), np.full(k, np.inf))
    lower = np.concatenate([down, -bounds]) * scale
    upper = np.concatenate([up, bounds]) * scale
    solved = lsq_linear(matrix / scale, -r, bounds=(lower, upper), method="trf", lsmr_tol="auto")
    x = solved.x / scale
    fitted = r + matrix @ x
    return float(fitted @ fitted), x[k:]


def rank_on_positions(
    r: np.ndarray,
    base: np.ndarray,
    columns: Mapping[str, np.ndarray],
    bounds: Mapping[str, float],
    max_terms: int,
    bic_margin: float,
    moves: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[list[tuple[str, float]], list[str]]:
    """Forward selection of terms by what they do to the fix residuals, linearised at the parent fit: each
    step adds the term that lowers the SSE most with the terms already chosen and the parent's parameters
    refitted, while the predicted BIC falls by the extended margin's share of that term (so the chosen set
    beats the parent by ``extended_margin``, as acceptance asks of the real fit). Every channel competes on
    one scale, positions: a steering term that only stands in for an antenna term loses to it. Returns
    (chosen terms with their linearised coefficients, every other term by its last trial SSE, best first)."""
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
        charge = charged(bic_margin, k + 1) - (charged(bic_margin, k) if k else 0.0)
        if n * math.log(max(trials[best], 1e-300) / max(current, 1e-300)) + math.log(n) > -charge:
            break
        chosen.append(best)
        coefficients, current = solutions[best], trials[best]
        trials.pop(best)
    rest = sorted(trials, key=trials.get)
    return [(v, float(c)) for v, c in zip(chosen, coefficients)], rest


def screened(
    fits: Fitter,
    vehicle: str,
    jobs: Mapping[str, Parent],
    rms: Mapping[str, float],
    max_terms: int,
    bic_margin: float,
) -> dict[str, CorrectionProposal]:
    """Each job's proposal re-ranked on positions (:func:`rank_on_positions`) at its parent fit, on the
    parent's runs only, all in one sweep of probes (one per proposed term and parent; the parents' own
    points are in the store). Equation error says *which* terms the data carry; this says which of them
    the fix residuals want first, so the full fit and every fold choose their terms the same way."""
    variables = {v for job in jobs.values() for v, _ in job.proposal.ranked}
    parameters = term_parameters(sorted(variables), vehicle, rms)
    probes = {label: screen_probes(job, parameters) for label, job in jobs.items()}
    residuals = fits.evaluate(
        [p for points in probes.values() for p in points],
        [jobs[label].scenarios for label, points in probes.items() for _ in points],
    )
    out = {}
    for label, job in jobs.items():
        if job.proposal.empty:
            out[label] = job.proposal
            continue

        def stacked(point: Point, scenarios: tuple[str, ...] = job.scenarios) -> np.ndarray | None:
            found = [residuals(point, s) for s in scenarios]
            return None if any(x is None for x in found) else np.concatenate(found)

        point, *moved = probes[label]
        r = stacked(point)
        if (
            r is None
        ):  # the parent does not simulate (cannot happen for a fitted point): keep the proposal's order
            out[label] = job.proposal
            continue
        whole = job.fit.jacobian and sum(len(j) for j in job.fit.jacobian) == len(r)
        base = np.vstack(job.fit.jacobian) if whole else np.zeros((len(r), 0))
        moves = job.moves() if whole else None
        columns, bounds = {}, {}
        for (variable, _), probe in zip(job.proposal.ranked, moved):
            m = stacked(probe)
            if m is not None:
                columns[variable] = (m - r) / parameters[variable].step
                bounds[variable] = parameters[variable].upper
        chosen, rest = rank_on_positions(r, base, columns, bounds, max_terms, bic_margin, moves)
        proposed = dict(job.proposal.ranked)
        order = (*chosen, *((v, proposed[v]) for v in rest))
        out[label] = replace(job.proposal, terms=dict(chosen), ranked=order)
    return out
