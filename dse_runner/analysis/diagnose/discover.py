"""Discover: a sparse correction for what no effect of the library explains, proposed from the GPS and proven by the fits.

When the chosen library set R (possibly ``none``) leaves held-out error well above the noise floor, the
missing physics is sought among the correction block's terms (correction.py), in two stages
(docs/research/diagnosis-beyond-library.md, §4):

1. **Propose** (no simulation). The recorded state comes from the fixes alone (kinematics.py): speed,
   course, yaw rate and acceleration. At that state the calibrated reference R says what the vehicle
   should do; the difference is the *equation error* of each channel, the standard SINDy target for
   residual dynamics: for ``acc`` in speed (the drive's stiff speed loop turns an added acceleration into
   a speed change), for ``steer`` in yaw rate (steering enters it through the steady-state gain
   G(v) = −v / (L + K_us·v²); the yaw mode settles in hundredths of a second at these speeds). The features
   are taken at R's state, and every model-side signal is seen through the same local-polynomial window
   as the fixes, so neither side is sharper. The antenna's channels (``gps_along``, ``gps_cross``) are
   outputs, not dynamics, so equation error cannot see them: their target is R's fix residuals turned
   into the vehicle's axes (one sweep of points the fits mostly simulated already), where a term's
   column is its feature itself. PySINDy's sequentially thresholded least squares (STLSQ) picks the few
   terms that explain each channel; the threshold comes from leave-one-run-out error, and a term is kept
   only if it is picked in most of a seeded bootstrap over *runs* (rows within a run are correlated, so
   resampling rows would overstate the evidence). Some terms depend on a *shape* of the block (the time a
   change mid-run sets in, a steering rate limit): each shape is first scanned for the value at which its
   channel's equation error is least (:func:`find_shape`), and its terms are offered only if they then cut
   that channel's leave-one-run-out error by SHAPE_GAIN (:func:`shape_gain`); the fits hold the value.
2. **Rank on positions** (one sweep). Equation error sees the model's own misfit too, so the order it
   gives mixes channels unfairly (a pair of steering terms can outrank the antenna terms they stand in
   for). The terms every channel supports compete instead on what each does to the fix residuals,
   linearised at the parent fit (one probe per term, as screen.py does for library effects): forward
   selection, the parent's parameters refitted within their bounds, while the predicted BIC falls by the
   extended margin's share of each term (:func:`rank_on_positions`).
3. **Prove** (the same sweeps as the library). The chosen terms are freed as ``corr_*`` parameters of
   the effects FMU and fitted on positions jointly with the calibrated parameters and R's effects (R + D),
   and without R (D alone). Terms within two standard errors of zero are pruned, their slots refilled in
   the ranked order. Each fold re-does the proposal and the ranking on its training runs only, so the
   held-out error does not leak the choice of terms. D is accepted only if it beats R and every fitted
   part of itself by the library's rule, with the BIC margin raised for the search among many terms
   (extended BIC).

Equation-error coefficients are biased by noise in the recorded state, so they are only starting values:
the fits size the terms on positions.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any, Protocol

import numpy as np

from ... import bundled
from ...simulation.build import real_parameters
from ...simulation.scenario import Scenario, read_table
from ...sweeps.fit import FitProblem, FitResult, Parameter, Point, Residuals
from . import correction, explain, kinematics
from .correction import FeatureInputs, Term
from .explain import Candidate
from .hypotheses import EFFECTS_FMU, LIBRARY

DISCOVERED = "discovered"  # the id a discovered correction takes among a candidate's ids
DYNAMIC = ("acc", "steer")  # the channels equation error can see
OUTPUT = ("gps_along", "gps_cross")  # the antenna's: outputs, not dynamics, so proposed from the fix residuals
CHANNELS = (*DYNAMIC, *OUTPUT)
THRESHOLDS = (0.02, 0.05, 0.1, 0.2, 0.35)  # STLSQ thresholds tried, as fractions of the channel target's RMS
ALPHA = 0.05  # STLSQ's ridge weight per row, on columns scaled to unit RMS: enough to keep look-alike
# columns (the reference's yaw rate is nearly v·δ) from cancelling with huge coefficients; the fits then size and prune
BOOTSTRAP = 50  # run resamples
INCLUSION = 0.7  # share of the resamples a term must be picked in
SEED = 0  # every proposal is seeded: a re-run asks for the same points and resumes from the store
MIN_ACC_SPEED = 0.3  # m/s: below this the recorded acceleration is mostly the start from rest
PRUNE_SE = 2.0  # a fitted term within this many standard errors of zero is dropped
NEGLIGIBLE = 1e-9  # a column this small against its feature's typical size is empty
SCANNED = 40  # values of each shape scanned (onset times, rate limits); the extended BIC charges for them
ONSET_MARGIN = 0.15  # onset times are scanned inside the moving span less this share at each end: a change
# nearer the start than that is the start-up itself, and one nearer the end has too little run after it
RATE_LIMITS = (0.01, 1.0)  # rad/s: the rate limits scanned, geometrically; the Robotti steers at most ~0.2 rad/s
MAX_BINDING = 0.5  # a rate limit binding for more of the moving time than this is a gain, not a limit: not scanned
SHAPE_GAIN = 0.10  # a shape's terms are offered only if, at its best value, they cut the channel's leave-one-run-out
# error by this much: twice the library's min_gain, since the value was the best of a scan
RESEMBLES, PARTLY = 0.9, 0.5  # cosine similarity above which a term resembles, partly resembles, a library effect


# ---- the recorded state and the reference's view of it ----------------------------------------

@dataclass(frozen=True)
class Observed:
    """One run as the fixes and the command log give it, before any model: kinematics at each fix."""

    name: str
    time: np.ndarray  # fix times [s]
    x: np.ndarray
    y: np.ndarray
    log_time: np.ndarray  # command log
    log_speed: np.ndarray
    log_steering: np.ndarray  # positive = right [rad]


def observe(scenario: Scenario) -> Observed:
    """A field-data run's fixes and command log."""
    from ...cases import fielddata

    fixes = fielddata.gps(scenario)
    log = read_table(scenario.files["steering_inputs"], ("time", "velocity", "delta_f"))
    t, v, d = (np.asarray(c, float) for c in log.columns)
    return Observed(scenario.name, np.asarray(fixes.time, float), np.asarray(fixes.x, float),
                    np.asarray(fixes.y, float), t, v, d)


@lru_cache(maxsize=4)
def _defaults(fmu: str) -> dict[str, float]:
    """The start values of an FMU's real parameters, from its modelDescription.xml as FMPy reads it."""
    return real_parameters(bundled.bundled_path(fmu))


def vehicle_values(point: Mapping[str, float], vehicle: str, fixed: Mapping[str, Any] = {}) -> dict[str, float]:
    """Every parameter of the effects vehicle as a model at ``point`` uses it (local names): the FMU's
    defaults, then the multi-model's fixed values ``fixed``, then the point's."""
    values = dict(_defaults(EFFECTS_FMU))
    prefix = f"{vehicle}."
    for source in (fixed, point):
        values.update({k[len(prefix):]: float(v) for k, v in source.items()
                       if k.startswith(prefix) and isinstance(v, (int, float))})
    return values


def held(log_time: np.ndarray, command: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The command in force at ``t`` (the last logged at or before it; 0 before the first), as the FMU holds it."""
    k = np.searchsorted(log_time, t + 1e-9 * (1.0 + np.abs(t)), side="right") - 1
    return np.where(k < 0, 0.0, command[np.clip(k, 0, None)]) if len(command) else np.zeros_like(t)


def acted(log_time: np.ndarray, command: np.ndarray, t: np.ndarray, delay: float, lag: float
          ) -> tuple[np.ndarray, np.ndarray]:
    """A command as the vehicle acts on it at ``t``: delayed, through its actuator's first-order lag, and
    its rate through the correction block's filter (correction.TAU_F). Returns (value, filtered rate)."""
    shifted = np.asarray(t, float) - delay
    if lag > 0:  # the lagged command on the log's grid, held between its rows: close enough for a proposal
        command = correction.filtered_rate(log_time, command, log_time, lag)[0]
    value = held(log_time, command, shifted)
    _, rate = correction.filtered_rate(log_time, command, shifted)
    return value, rate


@dataclass(frozen=True)
class Regression:
    """One channel's equation error over some runs: the target and each term's column as the target sees
    it, one row per usable fix, with the run each row came from."""

    channel: str
    terms: tuple[Term, ...]
    theta: np.ndarray  # rows x terms
    y: np.ndarray
    run: np.ndarray  # run index per row
    rms: dict[str, float]  # each term's raw feature RMS over the rows: bounds its coefficient
    shapes: dict[str, float] = field(default_factory=dict)  # shape variable -> the value its terms' columns used

    @staticmethod
    def join(parts: Sequence[Regression]) -> Regression:
        """The rows of several runs' regressions of one channel, runs numbered in order."""
        first = parts[0]
        theta = np.vstack([p.theta for p in parts])
        rms = {t.variable: math.sqrt(sum(p.rms[t.variable] ** 2 * len(p.y) for p in parts)
                                     / max(sum(len(p.y) for p in parts), 1)) for t in first.terms}
        return Regression(first.channel, first.terms, theta, np.concatenate([p.y for p in parts]),
                          np.concatenate([np.full(len(p.y), k) for k, p in enumerate(parts)]), rms, first.shapes)


def _filled(time: np.ndarray, values: np.ndarray) -> np.ndarray:
    """NaNs replaced by linear interpolation (held at the ends): model-side signals must be finite everywhere."""
    ok = np.isfinite(values)
    if ok.all() or not ok.any():
        return np.where(ok, values, 0.0)
    return np.interp(time, time[ok], values[ok])


@dataclass(frozen=True)
class Reference:
    """One run as the reference model (parameters ``values``) sees it, quasi-statically on the command log's
    grid, next to the fixes' own kinematics: what both kinds of proposal (equation error, output error) need."""

    run: Observed
    kin: Any  # kinematics.gps_kinematics of the fixes (moved to the reference point when R has an antenna offset)
    grid: np.ndarray
    inputs: FeatureInputs  # the reference's state on the grid, as the correction block's features see it
    gain: np.ndarray  # steady-state yaw rate per rad of steering to the right, on the grid
    tau: float  # the drive's speed response time [s]
    operators: Mapping[str, tuple[np.ndarray, int]]  # channel -> the fixes' derivative operator and its order


def reference_state(run: Observed, values: Mapping[str, float]) -> Reference:
    """The reference's speed, heading, yaw rate and commands on the command log's grid.

    Its speed follows the command through the drive (:func:`speed_response`), its yaw rate is the
    steady-state gain times the steering it acts on, its heading is the fixes' course (GPS gives course, not
    heading; they differ by the body slip angle, a few mrad here)."""
    t, x, y = run.time, run.x, run.y
    kin = kinematics.gps_kinematics(t, x, y)
    ax_, ay_ = values.get("antenna_x", 0.0), values.get("antenna_y", 0.0)
    if ax_ or ay_:  # the fixes moved to the reference point, along the course
        c, s = np.cos(_filled(t, kin.course)), np.sin(_filled(t, kin.course))
        x, y = x - (ax_ * c - ay_ * s), y - (ax_ * s + ay_ * c)
        kin = kinematics.gps_kinematics(t, x, y)
    step = float(np.median(np.diff(run.log_time))) if len(run.log_time) > 1 else 0.05
    grid = np.arange(0.0, max(t[-1], run.log_time[-1] if len(run.log_time) else 0.0) + step, step)
    delay = values.get("time_offset", 0.0)
    v_cmd, a_cmd = acted(run.log_time, run.log_speed, grid, delay, values.get("speed_lag", 0.0))
    delta, delta_rate = acted(run.log_time, run.log_steering, grid, delay, values.get("steering_lag", 0.0))
    m, g, mu, kv = values["mass"], values["g"], values["mu"], values["Kv"]
    slip = values.get("wheel_slip", 0.0)
    psi = np.interp(grid, t, _filled(t, kin.course))
    slope = -g * (values.get("grade_x", 0.0) * np.cos(psi) + values.get("grade_y", 0.0) * np.sin(psi))
    v = speed_response(grid, v_cmd, slope, values)
    lf, lr = values["lf"], values["lr"]
    L = lf + lr
    understeer = m / L * (lr / values["cAlphaF"] - lf / values["cAlphaR"])
    gain = -v / (L + understeer * v * v)  # quasi-static yaw rate per rad of steering to the right
    r = gain * (delta + values.get("steering_offset", 0.0))
    f_drive = np.clip(kv * (v_cmd - v / (1.0 - slip)), -mu * m * g, mu * m * g) / m
    inputs = FeatureInputs(v=v, psi=psi, r=r, s=correction.distance(grid, v), v_cmd=v_cmd, a_cmd=a_cmd, delta=delta,
                           delta_rate=delta_rate, f_drive=f_drive, v_min=values["v_min"], t=grid)
    operators = {"acc": (kinematics.local_operator(t, kinematics.VELOCITY_WINDOW, 1)[1], 1),
                 "steer": (kinematics.local_operator(t, kinematics.ACCELERATION_WINDOW, 2)[2], 2)}
    return Reference(run, kin, grid, inputs, gain, m * (1.0 - slip) / kv, operators)


def _rms(columns: Mapping[str, np.ndarray], terms: Sequence[Term], moving: np.ndarray) -> dict[str, float]:
    """Each term's raw feature RMS while the vehicle is commanded to move: bounds its coefficient."""
    return {tm.variable: float(np.sqrt(np.mean(columns[tm.variable][moving] ** 2))) if moving.any() else math.nan
            for tm in terms}


def equation_error(ref: Reference, terms: Sequence[Term] = ()) -> dict[str, Regression]:
    """Each dynamic channel's equation error on one run: what the fixes show minus what the reference model
    predicts, and what each term would add, both seen through the fixes' window.

    The features are evaluated at the reference state, not at the recorded one: the recorded speed and yaw
    rate *are* the targets, so features made of them would explain any residual, noise included. Channels:
    ``acc`` in speed (a term c·f of d(v)/dt moves the speed by the drive's answer to c·f, so the stiff speed
    loop needs no differentiated GPS acceleration), ``steer`` in yaw rate (a term c·f of the steering moves
    the yaw rate by G(v)·c·f). Rows where the fixes give no estimate are left out."""
    terms = tuple(terms) or tuple(t for t in correction.searched_terms() if t.channel in DYNAMIC)
    t, kin, grid, inputs = ref.run.time, ref.kin, ref.grid, ref.inputs
    columns = correction.features(inputs, terms)
    recorded = {"acc": kin.speed, "steer": kin.yaw_rate}
    model = {"acc": inputs.v, "steer": inputs.r}
    effect = {"acc": lambda f: lagged(grid, ref.tau * f, ref.tau), "steer": lambda f: ref.gain * f}
    moving = inputs.v_cmd > 0
    out = {}
    for channel in DYNAMIC:
        mine = [tm for tm in terms if tm.channel == channel]
        if not mine:
            continue
        operator, order = ref.operators[channel]

        def seen(signal: np.ndarray, operator: np.ndarray = operator, order: int = order) -> np.ndarray:
            return kinematics.smoothed_like(operator, order, grid, signal, t)  # as the fixes would show it

        target = recorded[channel] - seen(model[channel])
        theta = np.column_stack([seen(effect[channel](columns[tm.variable])) for tm in mine])
        rows = np.isfinite(target) & np.isfinite(theta).all(axis=1)
        if channel == "acc":
            rows &= kin.speed >= MIN_ACC_SPEED
        shapes = {sh.variable: getattr(inputs, sh.name) for tm in mine if (sh := correction.shape_of(tm))}
        out[channel] = Regression(channel, tuple(mine), theta[rows], target[rows], np.zeros(int(rows.sum()), int),
                                  _rms(columns, mine, moving), shapes)
    return out


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
    """The share of the moving time a steering rate limit of ``limit`` binds (the limited angle still more than
    limit·τ from the angle at the end of a log step), over ``refs``' runs. Where it binds most of the time,
    lim(δ, L) − δ is mostly −δ, a gain the other steering terms already have."""
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


def _shaped_rows(refs: Sequence[Reference], shape: correction.Shape, value: float | None,
                 ) -> tuple[Regression, ...]:
    """The equation error of the channel ``shape``'s terms belong to, run by run: on all that channel's terms
    with the shaped ones made at ``value``, or without them when ``value`` is None."""
    channel = next(t.channel for t in correction.searched_terms() if correction.shape_of(t) == shape)
    terms = [t for t in correction.searched_terms() if t.channel == channel
             and (value is not None or correction.shape_of(t) != shape)]
    made = (equation_error(shaped(ref, shape, value) if value is not None else ref, terms) for ref in refs)
    return tuple(r[channel] for r in made if channel in r)


def _joined(regs: Sequence[Regression]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One channel's runs pooled: columns scaled to unit RMS, target, run index per row."""
    joined = Regression.join(list(regs))
    return _scaled(joined)[0], joined.y, joined.run


def _sse(regs: Sequence[Regression]) -> float:
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
    after, before = (held_out_error(*_joined(regs), 0.0) for regs in (with_, without))
    return 1.0 - after / before if before > 0 else 0.0


def find_shape(refs: Sequence[Reference], shape: correction.Shape) -> float:
    """The value of ``shape`` at which every term of its channel together explains that channel's equation error
    best, pooled over ``refs``' runs: a coarse scan (:func:`candidates`), then 20 steps between the best's
    neighbours. A change mid-run is a step in the acc error, a rate limit a lag of the yaw rate while the
    steering turns fast; least squares finds where (and :func:`shape_gain` whether it is worth it)."""
    coarse = candidates(refs, shape)
    if len(coarse) == 0:
        return shape.default

    def sse(value: float) -> float:
        return _sse(_shaped_rows(refs, shape, value))

    k = min(range(len(coarse)), key=lambda i: sse(coarse[i]))
    low, high = coarse[max(k - 1, 0)], coarse[min(k + 1, len(coarse) - 1)]
    return float(min([coarse[k], *np.linspace(low, high, 21)], key=sse))


def searched_shapes() -> list[correction.Shape]:
    """The shapes some searched term depends on."""
    return list({sh.name: sh for t in correction.searched_terms() if (sh := correction.shape_of(t))}.values())


def body_axes(dx: np.ndarray, dy: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A world-frame displacement (east, north) in the vehicle's axes at heading ``psi``: (forward, left)."""
    c, s = np.cos(psi), np.sin(psi)
    return dx * c + dy * s, -dx * s + dy * c


def output_error(ref: Reference, residuals: np.ndarray | None, terms: Sequence[Term] = ()) -> dict[str, Regression]:
    """The antenna channels' error on one run: the reference's fix residuals (fielddata.fix_residuals,
    simulated minus recorded, x then y) turned into recorded minus simulated in the vehicle's axes, forward
    and left.

    An antenna term moves the simulated fix by exactly c·f(ψ, v) along its axis and leaves the dynamics
    alone, so its column *is* its feature and the residual in body axes is its target: no GPS is
    differentiated (output effects are invisible to equation error). The features are at the reference's
    speed and the recorded course, at the fix times. ``residuals`` None (the reference failed to simulate
    the run) gives no rows."""
    terms = tuple(terms) or tuple(t for t in correction.searched_terms() if t.channel in OUTPUT)
    if residuals is None or len(residuals) < 2:
        return {}
    n = len(residuals) // 2  # the fixes inside the simulated span: the first n (every run starts at 0)
    t = ref.run.time[:n]
    grid_columns = correction.features(ref.inputs, terms)
    psi = np.interp(t, ref.grid, ref.inputs.psi)
    along, left = body_axes(-residuals[:n], -residuals[n:], psi)
    moving = ref.inputs.v_cmd > 0
    out = {}
    for channel, target in zip(OUTPUT, (along, left)):
        mine = [tm for tm in terms if tm.channel == channel]
        if not mine:
            continue
        theta = np.column_stack([np.interp(t, ref.grid, grid_columns[tm.variable]) for tm in mine])
        rows = np.isfinite(target) & np.isfinite(theta).all(axis=1)
        out[channel] = Regression(channel, tuple(mine), theta[rows], target[rows], np.zeros(int(rows.sum()), int),
                                  _rms(grid_columns, mine, moving))
    return out


def speed_response(grid: np.ndarray, v_cmd: np.ndarray, slope: np.ndarray, values: Mapping[str, float],
                   substeps: int = 10) -> np.ndarray:
    """The reference's speed on a uniform ``grid``: d(v)/dt = clamp(Kv·(v_cmd − v/(1 − i)), ±mu·m·g)/m + slope
    from rest, by explicit Euler in ``substeps`` per grid step (the drive's time constant m/Kv is several
    grid steps), the lateral coupling left out (it cancels to first order in a steady turn)."""
    m, g, mu, kv = values["mass"], values["g"], values["mu"], values["Kv"]
    slip = values.get("wheel_slip", 0.0)
    dt = float(grid[1] - grid[0]) / substeps if len(grid) > 1 else 0.0
    out = np.zeros(len(grid))
    v = 0.0
    for k in range(1, len(grid)):
        for _ in range(substeps):
            v += dt * (min(max(kv * (v_cmd[k - 1] - v / (1.0 - slip)), -mu * m * g), mu * m * g) / m + slope[k - 1])
        out[k] = v
    return out


def lagged(time: np.ndarray, signal: np.ndarray, tau: float) -> np.ndarray:
    """``signal`` (on a uniform grid) through a first-order lag of time constant ``tau`` from rest (scipy's lfilter)."""
    from scipy.signal import lfilter

    if tau <= 0:
        return np.asarray(signal, float)
    a = math.exp(-float(time[1] - time[0]) / tau) if len(time) > 1 else 0.0
    return lfilter([1.0 - a], [1.0, -a], np.asarray(signal, float))


def regressions(runs: Sequence[Observed], values: Mapping[str, Mapping[str, float]] | Mapping[str, float],
                residuals: Mapping[str, np.ndarray | None] | None = None) -> dict[str, Regression]:
    """Each channel's error over ``runs``; ``values`` is one parameter set, or one per run name; ``residuals``
    the reference's fix residuals per run name (the antenna channels; none without them)."""
    refs = [reference_state(run, values.get(run.name, values)) for run in runs]
    dropped = set()
    for shape in searched_shapes():  # each shape at its best value, or its terms left out when they do not pay
        value = find_shape(refs, shape)
        if shape_gain(refs, shape, value) >= SHAPE_GAIN:
            refs = [shaped(ref, shape, value) for ref in refs]
        else:
            dropped.add(shape.name)
    terms = [t for t in correction.searched_terms() if not ((s := correction.shape_of(t)) and s.name in dropped)]
    dynamic, output = [t for t in terms if t.channel in DYNAMIC], [t for t in terms if t.channel in OUTPUT]
    per_run = [{**equation_error(ref, dynamic),
                **(output_error(ref, residuals.get(ref.run.name), output) if residuals is not None else {})}
               for ref in refs]
    return {c: Regression.join([p[c] for p in per_run if c in p]) for c in CHANNELS
            if any(c in p for p in per_run)}


# ---- proposal: PySINDy's STLSQ, threshold by leave-one-run-out, terms by a bootstrap over runs ---

@dataclass(frozen=True)
class Proposal:
    """The terms equation error supports, with their equation-error coefficients (starting values only)."""

    terms: dict[str, float]  # parameter name (corr_*) -> coefficient
    inclusion: dict[str, float]  # every term picked at least once -> share of resamples picking it
    threshold: dict[str, float]  # channel -> STLSQ threshold chosen (in the target's units per unit-RMS column)
    rms: dict[str, float]  # every term's feature RMS over the runs
    ranked: tuple[tuple[str, float], ...] = ()  # every term that passed the bootstrap, best first (terms: the first)
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
    terms by how much they move the channel, whatever their units."""
    import pysindy as ps

    if len(y) == 0:
        return np.zeros(theta.shape[1])
    optimizer = ps.STLSQ(threshold=threshold, alpha=ALPHA * len(y), max_iter=20, normalize_columns=False,
                         unbias=False)
    with warnings.catch_warnings():  # "eliminated all coefficients" is an answer here (no term), not a fault
        warnings.filterwarnings("ignore", message="Sparsity parameter is too big", category=UserWarning)
        optimizer.fit(theta, y)
    return np.asarray(optimizer.coef_, float).reshape(-1)


def _scaled(reg: Regression) -> tuple[np.ndarray, np.ndarray]:
    """The columns scaled to unit RMS, and the scales. A column far below its feature's typical size (the
    drive's force once the speed has settled, to rounding) carries no information, only rounding: it is
    zeroed rather than blown up to unit size."""
    scale = np.sqrt(np.mean(reg.theta ** 2, axis=0)) if len(reg.y) else np.ones(reg.theta.shape[1])
    typical = np.array([t.feature_info.typical for t in reg.terms])
    empty = scale <= NEGLIGIBLE * typical
    scale = np.where(empty, 1.0, scale)
    return np.where(empty, 0.0, reg.theta / scale), scale


def held_out_error(z: np.ndarray, y: np.ndarray, run: np.ndarray, threshold: float) -> float:
    """Leave-one-run-out squared error of STLSQ at ``threshold`` (math.inf for no threshold: the empty model)."""
    total = 0.0
    for k in np.unique(run):
        out = run == k
        coef = np.zeros(z.shape[1]) if math.isinf(threshold) else stlsq(z[~out], y[~out], threshold)
        total += float(np.sum((y[out] - z[out] @ coef) ** 2))
    return total


def choose_threshold(z: np.ndarray, y: np.ndarray, run: np.ndarray) -> float:
    """The threshold of ``THRESHOLDS`` (times the target's RMS) with the least leave-one-run-out error, the
    largest within 2 % of it (the sparser model, as a tie); math.inf when none beats the empty model."""
    size = float(np.sqrt(np.mean(y ** 2))) if len(y) else 0.0
    if size == 0.0 or len(np.unique(run)) < 2:
        return math.inf
    errors = {f * size: held_out_error(z, y, run, f * size) for f in THRESHOLDS}
    empty = float(np.sum(y ** 2))
    best = min(errors.values())
    if best >= empty:
        return math.inf
    return max(th for th, e in errors.items() if e <= 1.02 * best)


def propose(regs: Mapping[str, Regression], max_terms: int = 3, seed: int = SEED,
            bootstrap: int = BOOTSTRAP) -> Proposal:
    """The few terms the error of every channel supports: per channel the STLSQ threshold of least
    leave-one-run-out error, then a seeded bootstrap over runs; terms picked in at least ``INCLUSION`` of the
    resamples, at most ``max_terms`` in all (the order only until :func:`screened` re-ranks them on
    positions), the dynamic channels' before the antenna's (a misfit of the
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
        size = float(np.sqrt(np.mean(reg.y ** 2)))
        for k, tm in enumerate(reg.terms):
            if share[k] > 0:
                inclusion[tm.variable] = float(share[k])
            if share[k] >= INCLUSION and coef[k] != 0:
                ranked.append((channel in DYNAMIC, float(share[k]), abs(coef[k]) * scale[k] / size, tm.variable,
                               float(coef[k])))
    order = tuple((v, c) for *_, v, c in sorted(ranked, reverse=True))
    return Proposal(dict(order[:max_terms]), inclusion, thresholds, rms, order,
                    {k: v for reg in regs.values() for k, v in reg.shapes.items()})


# ---- proof: the same fits, folds and rule as the library ------------------------------------

def searched_count() -> int:
    """How many terms the proposal chooses among: the extended BIC charges for the search. A shaped term
    counts once per value scanned (a step at each onset time is a term of its own)."""
    return sum(SCANNED if correction.shape_of(t) else 1 for t in correction.searched_terms() if t.channel in CHANNELS)


def extended_margin(bic_margin: float, terms: int, searched: int | None = None) -> float:
    """The BIC margin for a set of ``terms`` chosen among ``searched``: bic_margin + 2 ln C(P, k) (extended
    BIC with γ = 1), since picking the best k of P terms buys a better fit by chance alone."""
    p = searched_count() if searched is None else searched
    k = max(0, min(terms, p))
    return bic_margin + 2.0 * (math.lgamma(p + 1) - math.lgamma(k + 1) - math.lgamma(p - k + 1))


def library_ids(ids: Sequence[str]) -> tuple[str, ...]:
    return tuple(h for h in ids if h != DISCOVERED)


def held_shapes(shapes: Mapping[str, float], vehicle: str, variables: Sequence[str]) -> dict[str, float]:
    """The shapes the terms ``variables`` depend on, as the vehicle's parameters at their found values (a
    shape no term uses changes nothing, and leaving it at its default keeps the points the store has)."""
    out = {}
    for v in variables:
        shape = correction.shape_of(correction.term(v))
        if shape is not None and shape.variable in shapes:
            out[f"{vehicle}.{shape.variable}"] = shapes[shape.variable]
    return out


def with_terms(problem: FitProblem, vehicle: str, terms: Mapping[str, float], start: Mapping[str, float],
               rms: Mapping[str, float], shapes: Mapping[str, float] = {}) -> FitProblem:
    """``problem`` with the correction terms freed: each bounded by correction.bound over the runs' feature
    RMS, starting from ``start`` (a fitted point) where it has the term, else from the proposal; the shapes
    the terms depend on held at their values in ``shapes``."""
    extra = []
    for variable, value in terms.items():
        name = f"{vehicle}.{variable}"
        extra.append(correction.parameter(correction.term(variable), vehicle, rms.get(variable),
                                          start.get(name, value)))
    names = {p.name for p in extra}
    held = held_shapes(shapes, vehicle, list(terms))
    return replace(problem, parameters=problem.parameters + tuple(extra),
                   fixed={**{k: v for k, v in problem.fixed.items() if k not in names}, **held})


def fitted_terms(fit: FitResult) -> dict[str, float]:
    """The correction terms a fit moved, local names -> values."""
    return {n.rsplit(".", 1)[-1]: v for n, v in fit.values.items() if correction.is_correction(n)}


def pruned(fit: FitResult, factor: float = PRUNE_SE) -> dict[str, float]:
    """The fitted terms at least ``factor`` cluster-robust standard errors from zero (an undetermined one is dropped)."""
    out = {}
    for name, value in fit.values.items():
        if correction.is_correction(name):
            se = fit.standard_error.get(name, math.inf)
            if math.isfinite(se) and abs(value) >= factor * se and value != 0.0:
                out[name.rsplit(".", 1)[-1]] = value
    return out


def refilled(kept: Mapping[str, float], proposal: Proposal, tried: set[str], max_terms: int) -> dict[str, float]:
    """The kept terms (at zero: the dropped ones may have balanced them) and, in the slots pruning freed, the
    next terms the proposal ranked that were not tried yet (at their proposed values). Equation error sees
    more than dynamics (the model's own misfit shows in it too), so a term it ranks high may fall on
    positions; the slot is then the next term's, not lost."""
    out = {v: 0.0 for v in kept}
    for variable, value in proposal.ranked:
        if len(out) >= max_terms:
            break
        if variable not in out and variable not in tried:
            out[variable] = value
    return out


@dataclass(frozen=True)
class Screen:
    """What ranking on positions needs of one parent fit: where it stands, on which runs, and what was proposed."""

    fit: FitResult  # the parent (R, or the calibrated model) fitted on ``scenarios``
    scenarios: tuple[str, ...]
    proposal: Proposal
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)  # the parent's parameters' bounds

    def moves(self) -> tuple[np.ndarray, np.ndarray]:
        """How far each of the parent's parameters (``fit.names``) may move from its fitted value, down and up."""
        low = [self.bounds.get(n, (-math.inf, math.inf))[0] - self.fit.values[n] for n in self.fit.names]
        high = [self.bounds.get(n, (-math.inf, math.inf))[1] - self.fit.values[n] for n in self.fit.names]
        return np.minimum(low, 0.0), np.maximum(high, 0.0)


def term_parameters(variables: Sequence[str], vehicle: str, rms: Mapping[str, float]) -> dict[str, Parameter]:
    return {v: correction.parameter(correction.term(v), vehicle, rms.get(v)) for v in variables}


def screen_probes(job: Screen, parameters: Mapping[str, Parameter]) -> list[Point]:
    """The parent's point, then the point moved by one step in each proposed term (the missing columns)."""
    point = dict(job.fit.point)
    out = [point]
    for variable, _ in job.proposal.ranked:
        p = parameters[variable]
        out.append({**point, p.name: point.get(p.name, 0.0) + p.step,
                    **held_shapes(job.proposal.shapes, p.name.rsplit(".", 1)[0], [variable])})
    return out


def linear_sse(r: np.ndarray, base: np.ndarray, columns: np.ndarray, bounds: np.ndarray,
               moves: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[float, np.ndarray]:
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


def rank_on_positions(r: np.ndarray, base: np.ndarray, columns: Mapping[str, np.ndarray],
                      bounds: Mapping[str, float], max_terms: int, bic_margin: float,
                      moves: tuple[np.ndarray, np.ndarray] | None = None
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
            sse, c = linear_sse(r, base, np.column_stack([columns[x] for x in names]),
                                np.array([bounds[x] for x in names]), moves)
            trials[v], solutions[v] = sse, c
        if not trials:
            break
        best = min(trials, key=trials.get)
        k = len(chosen)
        charge = extended_margin(bic_margin, k + 1) - (extended_margin(bic_margin, k) if k else 0.0)
        if n * math.log(max(trials[best], 1e-300) / max(current, 1e-300)) + math.log(n) > -charge:
            break
        chosen.append(best)
        coefficients, current = solutions[best], trials[best]
        trials.pop(best)
    rest = sorted(trials, key=trials.get)
    return [(v, float(c)) for v, c in zip(chosen, coefficients)], rest


def screened(chain: Fitter, jobs: Mapping[str, Screen], rms: Mapping[str, float]) -> dict[str, Proposal]:
    """Each job's proposal re-ranked on positions (:func:`rank_on_positions`) at its parent fit, on the
    parent's runs only, all in one sweep of probes (one per proposed term and parent; the parents' own
    points are in the store). Equation error says *which* terms the data carry; this says which of them
    the fix residuals want first, so the full fit and every fold choose their terms the same way."""
    variables = {v for job in jobs.values() for v, _ in job.proposal.ranked}
    parameters = term_parameters(sorted(variables), chain.vehicle, rms)
    probes = {label: screen_probes(job, parameters) for label, job in jobs.items()}
    residuals = chain.evaluate([p for points in probes.values() for p in points],
                               [jobs[label].scenarios for label, points in probes.items() for _ in points])
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
        if r is None:  # the parent does not simulate (cannot happen for a fitted point): keep the proposal's order
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
        chosen, rest = rank_on_positions(r, base, columns, bounds, chain.settings.max_terms,
                                         chain.settings.bic_margin, moves)
        proposed = dict(job.proposal.ranked)
        order = (*chosen, *((v, proposed[v]) for v in rest))
        out[label] = replace(job.proposal, terms=dict(chosen), ranked=order)
    return out


def settle(chain: Fitter, jobs: Mapping[str, tuple[Callable[[Mapping[str, float]], FitProblem], Proposal]],
           what: str) -> dict[str, FitResult | None]:
    """Fit each job's proposed terms, prune those within PRUNE_SE standard errors of zero, refit with the freed
    slots refilled (:func:`refilled`; all of them when no term survived), then prune and refit without
    refilling until every term stands; lockstep batches throughout. ``jobs``: label -> (problem for given
    terms, proposal). None where no term survives."""
    max_terms = chain.settings.max_terms
    fits = chain.fit([make(dict(proposal.terms)) for make, proposal in jobs.values()], what)
    tried = {label: set(proposal.terms) for label, (_, proposal) in jobs.items()}
    out: dict[str, FitResult | None] = {}
    for refill in (True, *[False] * max_terms):  # without refilling each pass drops a term: it ends
        again = []
        for label, (make, proposal) in jobs.items():
            if label in out:
                continue
            fit = fits[label]
            kept = pruned(fit)
            if kept == fitted_terms(fit):
                continue  # settled: every term two standard errors from zero
            terms = refilled(kept, proposal, tried[label], max_terms) if refill else {v: 0.0 for v in kept}
            if not terms:
                out[label] = None  # nothing survived, and nothing is left to try
                continue
            tried[label] |= set(terms)
            again.append(make(terms))
        if not again:
            break
        fits.update(chain.fit(again, f"{what}: refitting without the terms near zero"))
    return {label: out.get(label, fits[label]) for label in jobs}


class Fitter(Protocol):
    """What discovery needs from the chain (diagnose.Chain): problems, lockstep fits, held-out scoring, residuals."""

    vehicle: str
    folds: list[list[str]]
    all: tuple[str, ...]
    settings: Any
    say: Callable[[str], None]

    def problem(self, label: str, ids: tuple[str, ...], start: dict[str, float], scenarios: tuple[str, ...]
                ) -> FitProblem: ...

    def fit(self, problems: list[FitProblem], what: str) -> dict[str, FitResult]: ...

    def score(self, candidates: list[Candidate], fits: dict[str, FitResult]) -> None: ...

    def evaluate(self, points: list[Point]) -> Residuals: ...


@dataclass
class Discovery:
    """What discovery tried on top of ``reference`` and what it found."""

    reference: Candidate
    proposal: Proposal | None = None  # from every run
    candidates: list[Candidate] = field(default_factory=list)  # fitted with terms: R + D, and D alone
    chosen: Candidate | None = None  # the accepted one; None if no term paid its way
    folds: list[dict[str, Any]] = field(default_factory=list)  # each set's and fold's own proposal
    resembles: list[tuple[str, float]] = field(default_factory=list)  # library effects by similarity, best first
    margin: float = math.nan  # the BIC margin the terms had to beat (extended)
    reason: str = ""

    @property
    def terms(self) -> dict[str, float]:
        return fitted_terms(self.chosen.full) if self.chosen is not None else {}

    def to_json(self) -> dict[str, Any]:
        best = min(self.candidates, key=lambda c: c.cross_validated, default=None)
        return {"reference": self.reference.label, "held_out_reference": self.reference.cross_validated,
                "proposed": dict(self.proposal.terms) if self.proposal else {},
                "inclusion": dict(self.proposal.inclusion) if self.proposal else {},
                "folds": self.folds, "bic_margin": self.margin, "accepted": self.chosen is not None,
                "tried": [{"id": c.label, "terms": fitted_terms(c.full), "cross_track_held_out": c.cross_validated,
                           "bic": c.bic} for c in self.candidates],
                "best_held_out": best.cross_validated if best is not None else None, "reason": self.reason}


def _sets(reference: Candidate) -> list[tuple[str, ...]]:
    """R + D, and D alone when R has effects (a term may explain what R was only a look-alike of)."""
    return [(*reference.ids, DISCOVERED)] + ([(DISCOVERED,)] if reference.ids else [])


def discover(chain: Fitter, reference: Candidate, candidates: Sequence[Candidate], runs: Sequence[Observed],
             fixed: Mapping[str, Any] = {}) -> Discovery:
    """Propose terms on top of ``reference`` (R + D) and of the calibrated model alone (D alone, when R has
    effects: a term may explain what R only looked like), each from every run; fit them on every run and
    prune them; re-propose and fit inside each fold on its training runs; score the held-out runs; accept by
    the library's rule with the extended BIC margin. ``candidates`` are the library sets already fitted."""
    settings, vehicle = chain.settings, chain.vehicle
    result = Discovery(reference)
    by_name = {r.name: r for r in runs}
    baseline = next((c for c in candidates if not c.ids), reference)
    parents = {ids: reference if library_ids(ids) == reference.ids else baseline for ids in _sets(reference)}

    # The parents' fix residuals (the antenna channels' targets), full and per fold, in one sweep: every
    # point was simulated by its fit already, so the store answers most of it.
    points = [f.point for parent in parents.values() for f in (parent.full, *parent.folds)]
    residuals = chain.evaluate(points)

    def proposal(parent: FitResult, names: Sequence[str]) -> Proposal:
        values = vehicle_values(parent.point, vehicle, fixed)
        mine = [by_name[n] for n in names if n in by_name]
        return propose(regressions(mine, values, {r.name: residuals(parent.point, r.name) for r in mine}),
                       settings.max_terms)

    def training(k: int) -> tuple[str, ...]:
        return tuple(s for s in chain.all if s not in chain.folds[k])

    def parent_fold(ids: tuple[str, ...], k: int) -> FitResult:
        return parents[ids].folds[k] if k < len(parents[ids].folds) else parents[ids].full

    # Every proposal, from every run and from each fold's training runs (so the held-out error does not
    # leak the choice of terms), then ranked on positions at its parent, all in one sweep.
    raw = {ids: proposal(parent.full, chain.all) for ids, parent in parents.items()}
    rms = {k: v for p in raw.values() for k, v in p.rms.items()}
    bounds = {ids: {p.name: (p.lower, p.upper) for p in chain.problem("", library_ids(ids), {}, chain.all).parameters}
              for ids in parents}
    jobs_ = {("+".join(ids), -1): Screen(parent.full, chain.all, raw[ids], bounds[ids])
             for ids, parent in parents.items()}
    for ids in parents:
        for k in range(len(chain.folds)):
            fold_proposal = proposal(parent_fold(ids, k), training(k))
            rms.update({v: x for v, x in fold_proposal.rms.items() if v not in rms})
            jobs_[("+".join(ids), k)] = Screen(parent_fold(ids, k), training(k), fold_proposal, bounds[ids])
    ranked = screened(chain, {f"{a}/{k}": job for (a, k), job in jobs_.items()}, rms)
    proposals = {ids: ranked[f"{'+'.join(ids)}/-1"] for ids in parents}
    result.proposal = proposals[_sets(reference)[0]]
    sets = [ids for ids in parents if not proposals[ids].empty]
    if not sets:
        result.reason = ("the equation error supports no term" if all(p.empty for p in raw.values())
                         else "no proposed term moves the fix residuals enough to pay its way, linearised")
        return result
    for ids in sets:
        chain.say(f"discovery: proposed for {'+'.join(ids)}: " + "; ".join(proposals[ids].readable()))

    def full_problem(ids: tuple[str, ...], terms: Mapping[str, float]) -> FitProblem:
        base = chain.problem("+".join(ids), library_ids(ids), dict(parents[ids].full.values), chain.all)
        return with_terms(base, vehicle, terms, {}, rms, proposals[ids].shapes)

    settled = settle(chain, {"+".join(ids): (lambda terms, ids=ids: full_problem(ids, terms), proposals[ids])
                             for ids in sets}, "discovery: fitting the correction")
    fitted = [Candidate(ids, settled["+".join(ids)]) for ids in sets if settled["+".join(ids)] is not None]
    if not fitted:
        result.reason = "no proposed term is two standard errors from zero when fitted on positions"
        return result
    jobs, copies = {}, {}
    for c in fitted:  # fold-honest: each fold's own proposal, on its training runs, ranked at its parent's fold fit
        for k in range(len(chain.folds)):
            label = f"{c.label}/fold{k}"
            mine = ranked[f"{c.label}/{k}"]
            result.folds.append({"set": c.label, "fold": k, "terms": mine.terms})
            copies[label] = parent_fold(c.ids, k)  # what the fold predicts with when no term is proposed
            if mine.empty:
                continue

            def make(terms: Mapping[str, float], label: str = label, c: Candidate = c, k: int = k,
                     shapes: Mapping[str, float] = mine.shapes) -> FitProblem:
                base = chain.problem(label, library_ids(c.ids), {**parent_fold(c.ids, k).values, **c.full.values},
                                     training(k))
                return with_terms(base, vehicle, terms, c.full.values, rms, shapes)

            jobs[label] = (make, mine)
    # Each fold's proposal is fitted and scored as ranked: the ranking on positions already leaves out the
    # terms that would only stand in for others, and pruning inside a fold (fewer runs, so wider
    # cluster-robust intervals) can leave it with no term where the full fit keeps one.
    fold_fits = chain.fit([make(dict(mine.terms)) for make, mine in jobs.values()],
                          "discovery: cross-validating the correction") if jobs else {}
    for entry in result.folds:
        fit = fold_fits.get(f"{entry['set']}/fold{entry['fold']}")
        entry["kept"] = fitted_terms(fit) if fit is not None else {}
    chain.score(fitted, {**copies, **fold_fits})
    result.candidates = fitted
    result.margin = extended_margin(settings.bic_margin, max(len(fitted_terms(c.full)) for c in fitted))
    result.chosen = accept(fitted, reference, [*candidates, *fitted], settings.min_gain, settings.bic_margin)
    if result.chosen is None:
        best = min(fitted, key=lambda c: c.cross_validated)
        result.reason = (f"no correction pays its way: held-out {reference.cross_validated:.4f} m at best → "
                         f"{best.cross_validated:.4f} m, ΔBIC {best.bic - reference.bic:+.1f} (the rule: "
                         f"{settings.min_gain:.0%} lower held-out error and {result.margin:.1f} lower BIC, every "
                         "term two standard errors from zero)")
    return result


def pays(candidate: Candidate, candidates: Sequence[Candidate], min_gain: float, bic_margin: float) -> bool:
    """Whether a candidate with discovered terms beats every fitted part of itself: the parts without the
    terms by the extended BIC margin (the terms were searched for), those with them by the library's."""
    terms = len(fitted_terms(candidate.full))
    for part in explain.subsets(candidate, list(candidates)):
        margin = bic_margin if DISCOVERED in part.ids else extended_margin(bic_margin, terms)
        if not explain.beats(candidate, part, min_gain, margin):
            return False
    return True


def accept(fitted: Sequence[Candidate], reference: Candidate, candidates: Sequence[Candidate], min_gain: float,
           bic_margin: float) -> Candidate | None:
    """The accepted candidate with terms, or None: cross-validated, beating the reference by the extended
    margin and every fitted part of itself; the lowest held-out error, fewer ids winning a tie within
    ``min_gain``."""
    eligible = [c for c in fitted if c.validated and math.isfinite(c.cross_validated)
                and pruned(c.full) == fitted_terms(c.full)  # every term still two standard errors from zero
                and explain.beats(c, reference, min_gain, extended_margin(bic_margin, len(fitted_terms(c.full))))
                and pays(c, candidates, min_gain, bic_margin)]
    return explain.simplest_best(eligible, min_gain) if eligible else None


# ---- resemblance: does the correction act like an effect of the library? --------------------

def _library_parameters(vehicle: str) -> list[tuple[str, Parameter]]:
    return [(h.id, Parameter(f"{vehicle}.{p.variable}", 0.0, p.lower, p.upper, p.step))
            for h in LIBRARY.values() for p in h.parameters]


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
        found = [residuals(pt, s) for s in chain.all]
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
        out.append((hid, similarity(change, np.column_stack(cols), np.minimum(lows, 0.0), np.maximum(highs, 0.0))))
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
    """The discovered terms of a fit as the JSON's ``terms``: readable text, parameter, value, ~95 % interval."""
    interval = fit.interval()
    shapes = correction.shape_values(fit.point)
    out = []
    for name, value in fit.values.items():
        if correction.is_correction(name):
            t = correction.term(name)
            low, high = interval[name]
            shape = correction.shape_of(t)
            out.append({"text": correction.readable_term(t, value, (low, high), shapes), "variable": t.variable,
                        "value": value, "interval": [low, high]}
                       | ({shape.key: shapes[shape.variable]} if shape and shape.variable in shapes else {}))
    return out
