"""Discovery, stage 1: propose terms from equation error: shapes scanned first, then PySINDy's STLSQ, the
threshold by leave-one-run-out error, the terms by a bootstrap over runs."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ....analysis.diagnose.sparse_regression import choose_threshold as generic_threshold
from ....analysis.diagnose.sparse_regression import held_out_error
from ....analysis.diagnose.sparse_regression import stlsq as sparse_regression
from .. import correction
from ..correction import CorrectionTerm
from .observe import (
    DYNAMIC,
    OUTPUT,
    ChannelRegression,
    Column,
    Observed,
    Reference,
    equation_error,
    output_error,
    reference_state,
    term_columns,
)

CHANNELS = (*DYNAMIC, *OUTPUT)
BOOTSTRAP = 50  # run resamples
INCLUSION = 0.7  # share of the resamples a term must be picked in
SEED = 0  # every proposal is seeded: a re-run asks for the same points and resumes from the store
NEGLIGIBLE = 1e-9  # a column this small against its feature's typical size is empty
SCANNED = 40  # values of each shape scanned (onset times, rate limits); the extended BIC charges for them
ONSET_MARGIN = 0.15  # onset times are scanned inside the moving span less this share at each end: a change
# nearer the start than that is the start-up itself, and one nearer the end has too little run after it
RATE_LIMITS = (
    0.01,
    1.0,
)  # rad/s: the rate limits scanned, geometrically; the Robotti steers at most ~0.2 rad/s
MAX_BINDING = (
    0.5  # a rate limit binding for more of the moving time than this is a gain, not a limit: not scanned
)
SHAPE_GAIN = (
    0.10  # a shape's terms are offered only if, at its best value, they cut the channel's leave-one-run-out
)
# error by this much: twice the library's min_gain, since the value was the best of a scan


def shaped(ref: Reference, shape: correction.Shape, value: float) -> Reference:
    """The reference with the features of ``shape`` made at ``value``."""
    return replace(ref, inputs=replace(ref.inputs, **{shape.name: float(value)}))


def candidates(refs: Sequence[Reference], shape: correction.Shape, count: int = SCANNED) -> np.ndarray:
    """The values of ``shape`` scanned: onset times evenly inside the span some run is commanded to move in,
    less ONSET_MARGIN at each end; rate limits geometrically over RATE_LIMITS."""
    if shape.name == "rate_limit":
        return np.array([v for v in np.geomspace(*RATE_LIMITS, count) if binding(refs, v) <= MAX_BINDING])
    if shape.name != "onset":
        raise ValueError(f"no scan for the shape {shape.name!r}")
    spans = [s for s in (ref.grid[ref.inputs.v_cmd > 0] for ref in refs) if len(s)]
    if not spans:
        return np.zeros(0)
    low, high = min(float(s[0]) for s in spans), max(float(s[-1]) for s in spans)
    margin = ONSET_MARGIN * (high - low)
    return np.linspace(low + margin, high - margin, count)


def binding(refs: Sequence[Reference], limit: float) -> float:
    """The share of the moving time a steering rate limit of ``limit`` binds (the limited angle still more
    than limit·τ from the angle at the end of a log step), over ``refs``' runs. Where it binds most of
    the time, lim(δ, L) − δ is mostly −δ, a gain the other steering terms already have."""
    bound = moving = 0
    for ref in refs:
        x = ref.inputs
        if x.t is None:
            continue
        # behind the angle it followed over each step (the log holds each angle until the next time)
        gap = np.abs(correction.rate_limited(x.t, x.delta, limit)[1:] - np.asarray(x.delta)[:-1])
        on = np.asarray(x.v_cmd)[1:] > 0
        bound += int(np.sum(gap[on] > limit * correction.TAU_TRACK * 1.01))
        moving += int(np.sum(on))
    return bound / moving if moving else 0.0


def _channel(shape: correction.Shape) -> str:
    """The channel ``shape``'s terms belong to."""
    return next(t.channel for t in correction.searched_terms() if correction.shape_of(t) == shape)


def _channel_terms(shape: correction.Shape, with_shape: bool) -> list[CorrectionTerm]:
    """The searched terms of ``shape``'s channel, with or without the shaped ones."""
    channel = _channel(shape)
    return [
        t
        for t in correction.searched_terms()
        if t.channel == channel and (with_shape or correction.shape_of(t) != shape)
    ]


def _shaped_rows(
    refs: Sequence[Reference],
    shape: correction.Shape,
    value: float | None,
    known: Sequence[Mapping[str, Column]] | None = None,
) -> tuple[ChannelRegression, ...]:
    """The equation error of the channel ``shape``'s terms belong to, run by run: on all that channel's terms
    with the shaped ones made at ``value``, or without them when ``value`` is None. ``known`` holds, per run,
    columns of the other terms already computed (they do not change with ``value``)."""
    terms = _channel_terms(shape, value is not None)
    known = known or [{}] * len(refs)
    made = (
        equation_error(shaped(ref, shape, value) if value is not None else ref, terms, columns)
        for ref, columns in zip(refs, known)
    )
    channel = _channel(shape)
    return tuple(r[channel] for r in made if channel in r)


def _joined(regs: Sequence[ChannelRegression]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One channel's runs pooled: columns scaled to unit RMS, target, run index per row."""
    joined = ChannelRegression.join(list(regs))
    return _scaled(joined)[0], joined.y, joined.run


def _sse(regs: Sequence[ChannelRegression]) -> float:
    """The least squares SSE of one channel's equation error on all its columns, pooled over runs."""
    z, y, _ = _joined(regs)
    if len(y) == 0:
        return math.inf
    coef = np.linalg.lstsq(z, y, rcond=None)[0]
    return float(np.sum((y - z @ coef) ** 2))


def shape_gain(refs: Sequence[Reference], shape: correction.Shape, value: float) -> float:
    """How much the terms of ``shape``, made at ``value``, cut their channel's leave-one-run-out error (the
    ridge fit of STLSQ at threshold 0) beside the channel's other terms; 0 with fewer than two runs."""
    with_, without = _shaped_rows(refs, shape, value), _shaped_rows(refs, shape, None)
    if len(with_) < 2:
        return 0.0
    after, before = (held_out_error(*_joined(regs), 0.0, stlsq) for regs in (with_, without))
    return 1.0 - after / before if before > 0 else 0.0


def find_shape(refs: Sequence[Reference], shape: correction.Shape) -> float:
    """The value of ``shape`` at which every term of its channel together explains that channel's
    equation error best, pooled over ``refs``' runs: a coarse scan (:func:`candidates`), then 20
    steps between the best's neighbours. A change mid-run is a step in the acc error, a rate limit a
    lag of the yaw rate while the steering turns fast; least squares finds where (and
    :func:`shape_gain` whether it is worth it)."""
    coarse = candidates(refs, shape)
    if len(coarse) == 0:
        return shape.default

    others = _channel_terms(shape, False)
    known = [term_columns(ref, others) for ref in refs]  # once: a scan changes only the shaped terms' columns

    def sse(value: float) -> float:
        return _sse(_shaped_rows(refs, shape, value, known))

    k = min(range(len(coarse)), key=lambda i: sse(coarse[i]))
    low, high = coarse[max(k - 1, 0)], coarse[min(k + 1, len(coarse) - 1)]
    return float(min([coarse[k], *np.linspace(low, high, 21)], key=sse))


def searched_count() -> int:
    """How many terms the proposal chooses among: the extended BIC charges for the search. A shaped term
    counts once per value scanned (a step at each onset time is a term of its own)."""
    return sum(
        SCANNED if correction.shape_of(t) else 1 for t in correction.searched_terms() if t.channel in CHANNELS
    )


def searched_shapes() -> list[correction.Shape]:
    """The shapes some searched term depends on."""
    return list({sh.name: sh for t in correction.searched_terms() if (sh := correction.shape_of(t))}.values())


def regressions(
    runs: Sequence[Observed],
    values: Mapping[str, Mapping[str, float]] | Mapping[str, float],
    residuals: Mapping[str, np.ndarray | None] | None = None,
) -> dict[str, ChannelRegression]:
    """Each channel's error over ``runs``; ``values`` is one parameter set, or one per run name; ``residuals``
    the reference's fix residuals per run name (the antenna channels; none without them)."""
    refs = [reference_state(run, values.get(run.name, values)) for run in runs]
    dropped = set()
    for (
        shape
    ) in searched_shapes():  # each shape at its best value, or its terms left out when they do not pay
        value = find_shape(refs, shape)
        if shape_gain(refs, shape, value) >= SHAPE_GAIN:
            refs = [shaped(ref, shape, value) for ref in refs]
        else:
            dropped.add(shape.name)
    terms = [
        t for t in correction.searched_terms() if not ((s := correction.shape_of(t)) and s.name in dropped)
    ]
    dynamic, output = [t for t in terms if t.channel in DYNAMIC], [t for t in terms if t.channel in OUTPUT]
    per_run = [
        {
            **equation_error(ref, dynamic),
            **(output_error(ref, residuals.get(ref.run.name), output) if residuals is not None else {}),
        }
        for ref in refs
    ]
    return {
        c: ChannelRegression.join([p[c] for p in per_run if c in p])
        for c in CHANNELS
        if any(c in p for p in per_run)
    }


@dataclass(frozen=True)
class CorrectionProposal:
    """The terms equation error supports, with their equation-error coefficients (starting values only)."""

    terms: dict[str, float]  # parameter name (corr_*) -> coefficient
    inclusion: dict[str, float]  # every term picked at least once -> share of resamples picking it
    threshold: dict[
        str, float
    ]  # channel -> STLSQ threshold chosen (in the target's units per unit-RMS column)
    rms: dict[str, float]  # every term's feature RMS over the runs
    ranked: tuple[
        tuple[str, float], ...
    ] = ()  # every term that passed the bootstrap, best first (terms: the first)
    shapes: dict[str, float] = field(default_factory=dict)  # shape variable -> the value the columns used

    def readable(self) -> list[str]:
        """The proposed terms as equations, their shapes' values written in."""
        return correction.readable({**self.terms, **self.shapes})

    @property
    def empty(self) -> bool:
        return not self.terms


def stlsq(theta: np.ndarray, y: np.ndarray, threshold: float) -> np.ndarray:
    """PySINDy's sequentially thresholded least squares on columns of unit RMS: coefficients per column,
    each in the target's units (what the term adds at its typical size). Thresholding on that scale keeps
    terms by how much they move the channel, whatever their units. The ridge keeps look-alike columns (the
    reference's yaw rate is nearly v·δ) from cancelling with huge coefficients, and its shrinkage is kept (no
    unbiasing): the fits size and prune the terms afterwards."""
    return sparse_regression(theta, y, threshold, unbias=False)


def _scaled(reg: ChannelRegression) -> tuple[np.ndarray, np.ndarray]:
    """The columns scaled to unit RMS, and the scales. A column far below its feature's typical size (the
    drive's force once the speed has settled, to rounding) carries no information, only rounding: it is
    zeroed rather than blown up to unit size."""
    scale = np.sqrt(np.mean(reg.theta**2, axis=0)) if len(reg.y) else np.ones(reg.theta.shape[1])
    typical = np.array([t.feature_info.typical for t in reg.terms])
    empty = scale <= NEGLIGIBLE * typical
    scale = np.where(empty, 1.0, scale)
    return np.where(empty, 0.0, reg.theta / scale), scale


def choose_threshold(z: np.ndarray, y: np.ndarray, run: np.ndarray) -> float:
    """The engine's threshold (sparse_regression.choose_threshold), with this module's STLSQ."""
    return generic_threshold(z, y, run, stlsq)


def propose(
    regs: Mapping[str, ChannelRegression], max_terms: int = 3, seed: int = SEED, bootstrap: int = BOOTSTRAP
) -> CorrectionProposal:
    """The few terms the error of every channel supports: per channel the STLSQ threshold of least
    leave-one-run-out error, then a seeded bootstrap over runs; terms picked in at least ``INCLUSION`` of the
    resamples, at most ``max_terms`` in all (the order only until the engine re-ranks them on the fix
    residuals, analysis/diagnose/term_ranking.py), the dynamic channels' before the antenna's (a misfit of the
    dynamics shows in the fix residuals too, integrated, so the antenna's channels are the fallback: they
    take the slots the fits free, :func:`refilled`), then the most often picked and the largest first."""
    rng = np.random.default_rng(seed)
    ranked: list[tuple[bool, float, float, str, float]] = []
    inclusion: dict[str, float] = {}
    thresholds: dict[str, float] = {}
    rms: dict[str, float] = {}
    for channel, reg in regs.items():
        rms.update(reg.rms)
        z, scale = _scaled(reg)
        threshold = choose_threshold(z, reg.y, reg.run)
        thresholds[channel] = threshold
        if math.isinf(threshold):
            continue
        runs = np.unique(reg.run)
        picked = np.zeros(z.shape[1])
        for _ in range(bootstrap):
            sample = rng.choice(runs, size=len(runs), replace=True)
            rows = np.concatenate([np.flatnonzero(reg.run == k) for k in sample])
            picked += stlsq(z[rows], reg.y[rows], threshold) != 0
        share = picked / bootstrap
        coef = stlsq(z, reg.y, threshold) / scale
        size = float(np.sqrt(np.mean(reg.y**2)))
        for k, tm in enumerate(reg.terms):
            if share[k] > 0:
                inclusion[tm.variable] = float(share[k])
            if share[k] >= INCLUSION and coef[k] != 0:
                ranked.append(
                    (
                        channel in DYNAMIC,
                        float(share[k]),
                        abs(coef[k]) * scale[k] / size,
                        tm.variable,
                        float(coef[k]),
                    )
                )
    order = tuple((v, c) for *_, v, c in sorted(ranked, reverse=True))
    return CorrectionProposal(
        dict(order[:max_terms]),
        inclusion,
        thresholds,
        rms,
        order,
        {k: v for reg in regs.values() for k, v in reg.shapes.items()},
    )
