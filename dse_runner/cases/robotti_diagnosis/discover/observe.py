"""Discovery, stage 0: the recorded state from the fixes, the calibrated reference's view of it, and each
channel's equation error (see discover/__init__.py)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from .... import bundled
from ....simulation.build import real_parameters
from ....simulation.scenario import Scenario, read_table
from .. import correction, kinematics
from ..correction import CorrectionTerm, FeatureInputs
from ..hypotheses import EFFECTS_FMU

DYNAMIC = ("acc", "steer")  # the channels equation error can see
OUTPUT = (
    "gps_along",
    "gps_cross",
)  # the antenna's: outputs, not dynamics, so proposed from the fix residuals
MIN_ACC_SPEED = 0.3  # m/s: below this the recorded acceleration is mostly the start from rest


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
    from ... import fielddata

    fixes = fielddata.gps(scenario)
    log = read_table(scenario.files["steering_inputs"], ("time", "velocity", "delta_f"))
    t, v, d = (np.asarray(c, float) for c in log.columns)
    return Observed(
        scenario.name,
        np.asarray(fixes.time, float),
        np.asarray(fixes.x, float),
        np.asarray(fixes.y, float),
        t,
        v,
        d,
    )


@lru_cache(maxsize=4)
def _defaults(fmu: str) -> dict[str, float]:
    """The start values of an FMU's real parameters, from its modelDescription.xml as FMPy reads it."""
    return real_parameters(bundled.bundled_path(fmu))


def vehicle_values(
    point: Mapping[str, float], vehicle: str, fixed: Mapping[str, Any] = {}
) -> dict[str, float]:
    """Every parameter of the effects vehicle as a model at ``point`` uses it (local names): the FMU's
    defaults, then the multi-model's fixed values ``fixed``, then the point's."""
    values = dict(_defaults(EFFECTS_FMU))
    prefix = f"{vehicle}."
    for source in (fixed, point):
        values.update(
            {
                k[len(prefix) :]: float(v)
                for k, v in source.items()
                if k.startswith(prefix) and isinstance(v, (int, float))
            }
        )
    return values


def held(log_time: np.ndarray, command: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The command in force at ``t`` (the last logged at or before it; 0 before
    the first), as the FMU holds it."""
    k = np.searchsorted(log_time, t + 1e-9 * (1.0 + np.abs(t)), side="right") - 1
    return np.where(k < 0, 0.0, command[np.clip(k, 0, None)]) if len(command) else np.zeros_like(t)


def acted(
    log_time: np.ndarray, command: np.ndarray, t: np.ndarray, delay: float, lag: float
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
class ChannelRegression:
    """One channel's equation error over some runs: the target and each term's column as the target sees
    it, one row per usable fix, with the run each row came from."""

    channel: str
    terms: tuple[CorrectionTerm, ...]
    theta: np.ndarray  # rows x terms
    y: np.ndarray
    run: np.ndarray  # run index per row
    rms: dict[str, float]  # each term's raw feature RMS over the rows: bounds its coefficient
    shapes: dict[str, float] = field(
        default_factory=dict
    )  # shape variable -> the value its terms' columns used

    @staticmethod
    def join(parts: Sequence[ChannelRegression]) -> ChannelRegression:
        """The rows of several runs' regressions of one channel, runs numbered in order."""
        first = parts[0]
        theta = np.vstack([p.theta for p in parts])
        rms = {
            t.variable: math.sqrt(
                sum(p.rms[t.variable] ** 2 * len(p.y) for p in parts) / max(sum(len(p.y) for p in parts), 1)
            )
            for t in first.terms
        }
        return ChannelRegression(
            first.channel,
            first.terms,
            theta,
            np.concatenate([p.y for p in parts]),
            np.concatenate([np.full(len(p.y), k) for k, p in enumerate(parts)]),
            rms,
            first.shapes,
        )


def _filled(time: np.ndarray, values: np.ndarray) -> np.ndarray:
    """NaNs replaced by linear interpolation (held at the ends): model-side
    signals must be finite everywhere."""
    ok = np.isfinite(values)
    if ok.all() or not ok.any():
        return np.where(ok, values, 0.0)
    return np.interp(time, time[ok], values[ok])


@dataclass(frozen=True)
class Reference:
    """One run as the reference model (parameters ``values``) sees it, quasi-statically on the
    command log's grid, next to the fixes' own kinematics: what both kinds of proposal
    (equation error, output error) need."""

    run: Observed
    # kinematics.gps_kinematics of the fixes (moved to the reference point when R has an antenna offset)
    kin: Any
    grid: np.ndarray
    inputs: FeatureInputs  # the reference's state on the grid, as the correction block's features see it
    gain: np.ndarray  # steady-state yaw rate per rad of steering to the right, on the grid
    tau: float  # the drive's speed response time [s]
    operators: Mapping[str, tuple[np.ndarray, int]]  # channel -> the fixes' derivative operator and its order
    # channel -> the equation error's target: the recorded speed or yaw rate less the
    # reference's, seen through the fixes' window. A shape's value changes none of it, so a scan
    # over it reuses these (propose.find_shape).
    targets: Mapping[str, np.ndarray]


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
    inputs = FeatureInputs(
        v=v,
        psi=psi,
        r=r,
        s=correction.distance(grid, v),
        v_cmd=v_cmd,
        a_cmd=a_cmd,
        delta=delta,
        delta_rate=delta_rate,
        f_drive=f_drive,
        v_min=values["v_min"],
        t=grid,
    )
    operators = {
        "acc": (kinematics.derivative_operator(t, kinematics.VELOCITY_WINDOW, 1, 1), 1),
        "steer": (kinematics.derivative_operator(t, kinematics.ACCELERATION_WINDOW, 2, 2), 2),
    }
    recorded, model = {"acc": kin.speed, "steer": kin.yaw_rate}, {"acc": v, "steer": r}
    targets = {c: recorded[c] - kinematics.smoothed_like(*operators[c], grid, model[c], t) for c in DYNAMIC}
    return Reference(run, kin, grid, inputs, gain, m * (1.0 - slip) / kv, operators, targets)


def _rms(
    columns: Mapping[str, np.ndarray], terms: Sequence[CorrectionTerm], moving: np.ndarray
) -> dict[str, float]:
    """Each term's raw feature RMS while the vehicle is commanded to move: bounds its coefficient."""
    return {
        tm.variable: float(np.sqrt(np.mean(columns[tm.variable][moving] ** 2))) if moving.any() else math.nan
        for tm in terms
    }


@dataclass(frozen=True)
class Column:
    """One term on one run: its feature on the grid, and what the feature adds to its channel's target as
    the fixes would show it. A term's column depends on the reference and on nothing else in the regression,
    so a scan over a shape's values computes the other terms' once (propose.find_shape)."""

    raw: np.ndarray
    seen: np.ndarray
    rms: float  # the raw feature's RMS while the vehicle is commanded to move (:func:`_rms`)


def term_columns(ref: Reference, terms: Sequence[CorrectionTerm]) -> dict[str, Column]:
    """The column on ``ref``'s run of each of ``terms`` in a dynamic channel, keyed by its parameter name
    (see :func:`equation_error`)."""
    t, grid = ref.run.time, ref.grid
    effect = {"acc": lambda f: lagged(grid, ref.tau * f, ref.tau), "steer": lambda f: ref.gain * f}
    dynamic = [tm for tm in terms if tm.channel in DYNAMIC]
    raws = correction.features(ref.inputs, dynamic)
    rms = _rms(raws, dynamic, ref.inputs.v_cmd > 0)
    out = {}
    for tm in dynamic:
        operator, order = ref.operators[tm.channel]
        raw = raws[tm.variable]
        out[tm.variable] = Column(
            raw, kinematics.smoothed_like(operator, order, grid, effect[tm.channel](raw), t), rms[tm.variable]
        )
    return out


def equation_error(
    ref: Reference,
    terms: Sequence[CorrectionTerm] = (),
    known: Mapping[str, Column] | None = None,
) -> dict[str, ChannelRegression]:
    """Each dynamic channel's equation error on one run: what the fixes show minus what the reference model
    predicts, and what each term would add, both seen through the fixes' window; ``known`` holds columns
    already computed on this run (:func:`term_columns`), keyed by variable.

    The features are evaluated at the reference state, not at the recorded one: the recorded speed and yaw
    rate *are* the targets, so features made of them would explain any residual, noise included. Channels:
    ``acc`` in speed (a term c·f of d(v)/dt moves the speed by the drive's answer to c·f, so the stiff speed
    loop needs no differentiated GPS acceleration), ``steer`` in yaw rate (a term c·f of the steering moves
    the yaw rate by G(v)·c·f). Rows where the fixes give no estimate are left out."""
    terms = tuple(terms) or tuple(t for t in correction.searched_terms() if t.channel in DYNAMIC)
    known = known or {}
    kin, inputs = ref.kin, ref.inputs
    columns = {**term_columns(ref, [tm for tm in terms if tm.variable not in known]), **known}
    out = {}
    for channel in DYNAMIC:
        mine = [tm for tm in terms if tm.channel == channel]
        if not mine:
            continue
        target = ref.targets[channel]
        theta = np.column_stack([columns[tm.variable].seen for tm in mine])
        rows = np.isfinite(target) & np.isfinite(theta).all(axis=1)
        if channel == "acc":
            rows &= kin.speed >= MIN_ACC_SPEED
        shapes = {sh.variable: getattr(inputs, sh.name) for tm in mine if (sh := correction.shape_of(tm))}
        out[channel] = ChannelRegression(
            channel,
            tuple(mine),
            theta[rows],
            target[rows],
            np.zeros(int(rows.sum()), int),
            {tm.variable: columns[tm.variable].rms for tm in mine},
            shapes,
        )
    return out


def body_axes(dx: np.ndarray, dy: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A world-frame displacement (east, north) in the vehicle's axes at heading ``psi``: (forward, left)."""
    c, s = np.cos(psi), np.sin(psi)
    return dx * c + dy * s, -dx * s + dy * c


def output_error(
    ref: Reference, residuals: np.ndarray | None, terms: Sequence[CorrectionTerm] = ()
) -> dict[str, ChannelRegression]:
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
        out[channel] = ChannelRegression(
            channel,
            tuple(mine),
            theta[rows],
            target[rows],
            np.zeros(int(rows.sum()), int),
            _rms(grid_columns, mine, moving),
        )
    return out


def speed_response(
    grid: np.ndarray, v_cmd: np.ndarray, slope: np.ndarray, values: Mapping[str, float], substeps: int = 10
) -> np.ndarray:
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
            v += dt * (
                min(max(kv * (v_cmd[k - 1] - v / (1.0 - slip)), -mu * m * g), mu * m * g) / m + slope[k - 1]
            )
        out[k] = v
    return out


def lagged(time: np.ndarray, signal: np.ndarray, tau: float) -> np.ndarray:
    """``signal`` (on a uniform grid) through a first-order lag of time constant
    ``tau`` from rest (scipy's lfilter)."""
    from scipy.signal import lfilter

    if tau <= 0:
        return np.asarray(signal, float)
    a = math.exp(-float(time[1] - time[0]) / tau) if len(time) > 1 else 0.0
    return lfilter([1.0 - a], [1.0, -a], np.asarray(signal, float))
