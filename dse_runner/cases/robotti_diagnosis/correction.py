"""The correction block: a generic, sparse correction of the vehicle model whose coefficients are parameters.

When no effect of the library explains the residual, discovery (step 7 of issue 18) proposes a few
terms ``coefficient × feature`` added to one *channel* of the model (an acceleration, the steering
angle, a yaw acceleration, the antenna's position). Every term is a parameter ``corr_<channel>_<feature>``
of the effects variant (``bundled:fmus/robotti_vehicle_effects``), zero when absent, so a discovered
correction is one more point of the same multi-model: it is fitted, cross-validated and re-calibrated
by the same sweeps as the library's effects (docs/research/diagnosis-beyond-library.md, §4.3).

This module owns the catalogue, :data:`TERMS`, in the FMU's order. The C block (``model.c``, the
``CORR_TERMS`` table) evaluates the same features from its own state; :func:`features` evaluates them
from given states (GPS-derived ones, in discovery) with the same definitions. A test checks that the
names and order here, in ``model.c`` and in ``modelDescription.xml`` agree.

Definitions shared with the C block (all at the model's reference point, mid-way between the axles):

* ``v`` is the body-frame longitudinal speed vx (GPS gives the ground speed, which differs by the
  lateral vy ≈ lr·r, a few cm/s); ``psi`` the heading, counter-clockwise from east; ``r`` the yaw rate.
* ``v_cmd`` and ``delta`` are the speed set-point and the steering angle (positive = right) *as the
  vehicle acts on them*: after the library's ``time_offset`` delay and actuator lags, before
  ``steering_offset`` and before the correction itself (the log's commands when those effects are off).
* ``a_cmd`` and ``delta_rate`` are their derivatives through a first-order filter of time constant
  :data:`TAU_F` (one state each): the replayed commands are piecewise constant, so a raw derivative
  would be a train of impulses. ``s`` is the distance travelled, ∫|v| dt (one state).
* ``f_drive`` is the drive's force over the mass, clamp(Kv·(v_cmd − v/(1 − slip)), ±mu·m·g)/m.
* ``sgnv`` is the direction of motion smoothed through rest, clamp(v/v_min, −1, 1): a force against the
  motion (rolling resistance, an implement's draft) is a negative coefficient, and a standing vehicle is
  not pushed.
* ``onset_*`` is a feature switched on from one moment of the run, [t ≥ t₀]: a change mid-run (an
  implement lowered, a tank filled).
* ``ratelim`` is lim(δ, L) − δ: the steering angle through a rate limit of L rad/s (a state that follows
  δ within :data:`TAU_TRACK` and turns at most L fast), less the angle itself; a coefficient of 1 makes
  the steering a rate-limited one (a hydraulic actuator's flow limit).

t₀ and L are the block's *shapes* (:data:`SHAPES`): parameters that are not coefficients but shape some
features (``corr_onset_time``, ``corr_rate_limit``). Discovery finds them from the data (a scan,
discover.find_shape) and the fits hold them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict

from ...errors import DseError
from ...sweeps.fit import FitResult, Parameter

TAU_F = 0.1  # s: time constant of the filtered derivatives a_cmd and delta_rate (model.c's TAU_F)
TAU_TRACK = 0.01  # s: how fast the rate limiter follows the steering below its limit (model.c's TAU_TRACK)
PREFIX = "corr_"
STEP_FRACTION = 1e-3  # finite-difference step of a coefficient, as a fraction of its bound


class Shape(BaseModel):
    """A parameter of the block that is not a coefficient: it shapes some features (when they switch on, how
    fast the steering may turn). Discovery finds its value from the data; the fits hold it there."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str  # the FeatureInputs field that carries it
    variable: str  # the effects FMU's parameter
    symbol: str  # in readable text, until its value is known
    unit: str
    default: float  # the FMU's start value
    key: str  # the name of its value in a discovered term's JSON


SHAPES: dict[str, Shape] = {
    s.name: s
    for s in [
        Shape(name="onset", variable="corr_onset_time", symbol="t₀", unit="s", default=0.0, key="onset_time"),
        Shape(
            name="rate_limit",
            variable="corr_rate_limit",
            symbol="L",
            unit="rad/s",
            default=1.0,
            key="rate_limit",
        ),
    ]
}


class CorrectionChannel(BaseModel):
    """What a channel's terms add to."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str
    target: str  # the left-hand side in readable text
    unit: str
    scale: float  # the largest correction the channel should make, in its unit: bounds coefficients
    searched: bool = True  # offered to discovery by default
    description: str


class Feature(BaseModel):
    """A function of the model's state and commands, as the C block evaluates it."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str  # the suffix of the parameter's name
    symbol: str  # in readable text; "1" for the constant; "{}" where its shape's value goes
    unit: str
    typical: (
        float  # an RMS size on Robotti manoeuvres (estimate): bounds a coefficient when no runs are given
    )
    shape: str | None = None  # the SHAPES entry its column depends on


class CorrectionTerm(BaseModel):
    """One coefficient of the block: ``channel += coefficient × feature``."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    channel: str
    feature: str

    @property
    def variable(self) -> str:
        """The effects FMU's parameter for this term's coefficient."""
        return f"{PREFIX}{self.channel}_{self.feature}"

    @property
    def channel_info(self) -> CorrectionChannel:
        return CHANNELS[self.channel]

    @property
    def feature_info(self) -> Feature:
        return FEATURES[self.feature]


def _f(name: str, symbol: str, unit: str, typical: float, shape: str | None = None) -> Feature:
    return Feature(name=name, symbol=symbol, unit=unit, typical=typical, shape=shape)


FEATURES: dict[str, Feature] = {
    f.name: f
    for f in [
        _f("1", "1", "1", 1.0),
        _f("v", "v", "m/s", 1.5),
        _f("v2", "v²", "m²/s²", 2.5),
        _f("verr", "(v_cmd − v)", "m/s", 0.1),
        _f("acmd", "a_cmd", "m/s²", 0.2),
        _f("cospsi", "cos ψ", "1", 0.7),
        _f("sinpsi", "sin ψ", "1", 0.7),
        _f("cos2psi", "cos 2ψ", "1", 0.7),
        _f("sin2psi", "sin 2ψ", "1", 0.7),
        _f("s", "s", "m", 60.0),
        _f("absvr", "|v·r|", "m/s²", 0.2),
        _f("fdrive", "F_drive/m", "m/s²", 0.3),
        _f("sgnv", "sgn v", "1", 0.8),
        _f("onset_sgnv", "[t ≥ {}]·sgn v", "1", 0.5, "onset"),
        _f("onset_fdrive", "[t ≥ {}]·F_drive/m", "m/s²", 0.2, "onset"),
        _f("delta", "δ", "rad", 0.1),
        _f("ddelta", "δ̇", "rad/s", 0.03),
        _f("ddeltav", "δ̇/max(v, v_min)", "rad/m", 0.03),
        _f("vdelta", "v·δ", "m·rad/s", 0.15),
        _f("r", "r", "rad/s", 0.1),
        _f("ratelim", "(lim(δ, {}) − δ)", "rad", 0.02, "rate_limit"),
        _f("vr", "v·r", "m·rad/s²", 0.15),
    ]
}

CHANNELS: dict[str, CorrectionChannel] = {
    c.name: c
    for c in [
        CorrectionChannel(
            name="acc",
            target="d(v)/dt",
            unit="m/s²",
            scale=2.0,
            description="added to the longitudinal acceleration d(vx)/dt",
        ),
        CorrectionChannel(
            name="steer",
            target="δ",
            unit="rad",
            scale=0.2,
            description=(
                "added to the steering angle after the actuators, positive = right, like steering_offset"
            ),
        ),
        CorrectionChannel(
            name="yaw",
            target="d(r)/dt",
            unit="rad/s²",
            scale=1.0,
            searched=False,
            description="added to the yaw acceleration (quasi-statically it cannot be told from steer, "
            "so discovery leaves it out by default)",
        ),
        CorrectionChannel(
            name="gps_along",
            target="gps_along",
            unit="m",
            scale=2.0,
            description="added to the antenna's position forward of the reference point, like antenna_x",
        ),
        CorrectionChannel(
            name="gps_cross",
            target="gps_cross",
            unit="m",
            scale=2.0,
            description="added to the antenna's position left of the reference point, like antenna_y",
        ),
    ]
}

_GPS = ("1", "cospsi", "sinpsi", "cos2psi", "sin2psi", "v")
_BY_CHANNEL: dict[str, tuple[str, ...]] = {
    "acc": (
        "1",
        "v",
        "v2",
        "verr",
        "acmd",
        "cospsi",
        "sinpsi",
        "s",
        "absvr",
        "fdrive",
        "sgnv",
        "onset_sgnv",
        "onset_fdrive",
    ),
    "steer": ("1", "delta", "ddelta", "ddeltav", "vdelta", "v", "r", "ratelim"),
    "yaw": ("1", "delta", "vdelta", "r", "vr"),
    "gps_along": _GPS,
    "gps_cross": _GPS,
}

# Every term, in the FMU's order (value references follow gps_y's: model.c's CORR_TERMS, the description).
TERMS: tuple[CorrectionTerm, ...] = tuple(
    CorrectionTerm(channel=c, feature=f) for c, fs in _BY_CHANNEL.items() for f in fs
)
_BY_VARIABLE: dict[str, CorrectionTerm] = {t.variable: t for t in TERMS}


def variables() -> list[str]:
    """Every coefficient's parameter name, in FMU order."""
    return [t.variable for t in TERMS]


def shape_of(t: CorrectionTerm) -> Shape | None:
    """The shape a term's column depends on (found from the data), or None."""
    return SHAPES[t.feature_info.shape] if t.feature_info.shape else None


def is_shape(variable: str) -> bool:
    return variable.rsplit(".", 1)[-1] in {s.variable for s in SHAPES.values()}


def shape_values(values: Mapping[str, float]) -> dict[str, float]:
    """The shapes among parameter values (with or without the instance prefix): shape variable -> value."""
    return {k.rsplit(".", 1)[-1]: float(v) for k, v in values.items() if is_shape(k)}


def searched_terms() -> tuple[CorrectionTerm, ...]:
    """The terms discovery tries by default (the yaw channel is in the FMU but not searched)."""
    return tuple(t for t in TERMS if CHANNELS[t.channel].searched)


def term(variable: str) -> CorrectionTerm:
    """The term of a parameter name, with or without its instance prefix (``vehicle.corr_acc_v``)."""
    name = variable.rsplit(".", 1)[-1]
    if name not in _BY_VARIABLE:
        raise DseError(f"{variable!r} is not a correction term: they are {', '.join(_BY_VARIABLE)}")
    return _BY_VARIABLE[name]


def is_correction(variable: str) -> bool:
    return variable.rsplit(".", 1)[-1] in _BY_VARIABLE


def bound(t: CorrectionTerm, rms: float | None = None) -> float:
    """|coefficient| ≤ channel scale / feature RMS: no term may move its channel by more than the scale
    on these runs. ``rms`` is the feature's RMS over the runs; the typical size when absent or zero."""
    size = rms if rms is not None and math.isfinite(rms) and rms > 0 else t.feature_info.typical
    return t.channel_info.scale / size


def parameter(t: CorrectionTerm, vehicle: str, rms: float | None = None) -> Parameter:
    """The fit's parameter for a term: absent (0) within symmetric bounds, a step of 1e-3 of the bound (where
    a fit starts it is the engine's: term_search.started)."""
    b = bound(t, rms)
    return Parameter(f"{vehicle}.{t.variable}", 0.0, -b, b, STEP_FRACTION * b)


def _number(value: float) -> str:
    return f"{value:.3g}"


def _symbol(t: CorrectionTerm, shapes: Mapping[str, float]) -> str:
    """The feature's symbol, its shape's value written in when ``shapes`` (variable -> value) has it."""
    shape = shape_of(t)
    if shape is None:
        return t.feature_info.symbol
    value = shapes.get(shape.variable)
    return t.feature_info.symbol.format(shape.symbol if value is None else f"{value:.4g} {shape.unit}")


def readable_term(
    t: CorrectionTerm,
    value: float,
    interval: tuple[float, float] | None = None,
    shapes: Mapping[str, float] = {},
) -> str:
    """``d(v)/dt += -0.31·v [-0.34, -0.28]``: one term as an engineer writes it (``shapes``: their values)."""
    symbol = _symbol(t, shapes)
    text = f"{t.channel_info.target} += {_number(value)}" + ("" if symbol == "1" else f"·{symbol}")
    if interval is not None:
        text += f" [{_number(interval[0])}, {_number(interval[1])}]"
    return text


def readable(values: Mapping[str, float]) -> list[str]:
    """One line per channel, its nonzero terms summed in FMU order, e.g. ``d(v)/dt += -0.31·v + 0.05·a_cmd``.
    Keys are parameter names, with or without the instance prefix (a shape, when present, is written into
    the terms it shapes); other keys are ignored."""
    by_channel: dict[str, list[str]] = {}
    chosen = {term(k).variable: v for k, v in values.items() if is_correction(k) and v != 0.0}
    shapes = shape_values(values)
    for t in TERMS:
        if t.variable not in chosen:
            continue
        value, symbol = chosen[t.variable], _symbol(t, shapes)
        factor = _number(abs(value)) + ("" if symbol == "1" else f"·{symbol}")
        parts = by_channel.setdefault(t.channel, [])
        parts.append(
            ("-" if value < 0 else "") + factor if not parts else ("- " if value < 0 else "+ ") + factor
        )
    return [f"{CHANNELS[c].target} += {' '.join(parts)}" for c, parts in by_channel.items()]


@dataclass(frozen=True)
class FeatureInputs:
    """The states and commands the features are made of, as equal-length arrays (one row per sample)."""

    v: np.ndarray  # longitudinal speed [m/s]
    psi: np.ndarray  # heading [rad]
    r: np.ndarray  # yaw rate [rad/s]
    s: np.ndarray  # distance travelled [m]
    v_cmd: np.ndarray  # speed set-point as acted on [m/s]
    a_cmd: np.ndarray  # its filtered derivative [m/s²]
    delta: np.ndarray  # steering angle as acted on, positive = right [rad]
    delta_rate: np.ndarray  # its filtered derivative [rad/s]
    f_drive: np.ndarray  # drive force over mass [m/s²]
    v_min: float = 0.5  # the vehicle's v_min: floor of the speed that divides delta_rate
    t: np.ndarray | None = (
        None  # time since the run's start [s]; None: onset features on throughout, no rate limit
    )
    onset: float = SHAPES["onset"].default  # t₀ [s], when the onset_* features switch on
    rate_limit: float = SHAPES["rate_limit"].default  # L [rad/s], the ratelim feature's limit


def _after(x: FeatureInputs) -> np.ndarray:
    """[t ≥ t₀]: 1 from the onset time on (throughout when no time is given), as the C block switches it."""
    if x.t is None:
        return np.ones_like(np.asarray(x.v, dtype=float))
    return (np.asarray(x.t, dtype=float) >= x.onset).astype(float)


def _rate_limited(x: FeatureInputs) -> np.ndarray:
    """The steering through the rate limit (the steering itself when no time is given)."""
    delta = np.asarray(x.delta, dtype=float)
    return delta if x.t is None else rate_limited(np.asarray(x.t, dtype=float), delta, x.rate_limit)


def rate_limited(t: np.ndarray, u: np.ndarray, limit: float, tau: float = TAU_TRACK) -> np.ndarray:
    """The C block's rate limiter, y' = clamp((u − y)/tau, ±limit) from y = 0, in closed form for ``u`` held
    from each time of ``t`` to the next: at the limit y moves linearly until it is within limit·tau of u,
    then it closes the rest exponentially. Returns y at ``t``."""
    y = np.zeros(len(t))
    state, edge = 0.0, limit * tau
    for k in range(1, len(t)):
        h, target = float(t[k] - t[k - 1]), float(u[k - 1])
        error = target - state
        if abs(error) > edge:
            ramp = (abs(error) - edge) / limit
            if h <= ramp:
                state += math.copysign(limit * h, error)
                y[k] = state
                continue
            error, h = math.copysign(edge, error), h - ramp
        state = target - error * math.exp(-h / tau)
        y[k] = state
    return y


def _feature(name: str, x: FeatureInputs) -> np.ndarray:
    v = np.asarray(x.v, dtype=float)
    match name:
        case "1":
            return np.ones_like(v)
        case "v":
            return v
        case "v2":
            return v * v
        case "verr":
            return np.asarray(x.v_cmd, dtype=float) - v
        case "acmd":
            return np.asarray(x.a_cmd, dtype=float)
        case "cospsi":
            return np.cos(x.psi)
        case "sinpsi":
            return np.sin(x.psi)
        case "cos2psi":
            return np.cos(2.0 * np.asarray(x.psi, dtype=float))
        case "sin2psi":
            return np.sin(2.0 * np.asarray(x.psi, dtype=float))
        case "s":
            return np.asarray(x.s, dtype=float)
        case "absvr":
            return np.abs(v * x.r)
        case "fdrive":
            return np.asarray(x.f_drive, dtype=float)
        case "sgnv":
            return np.clip(v / x.v_min, -1.0, 1.0)
        case "onset_sgnv":
            return _after(x) * np.clip(v / x.v_min, -1.0, 1.0)
        case "onset_fdrive":
            return _after(x) * np.asarray(x.f_drive, dtype=float)
        case "delta":
            return np.asarray(x.delta, dtype=float)
        case "ddelta":
            return np.asarray(x.delta_rate, dtype=float)
        case "ddeltav":
            return np.asarray(x.delta_rate, dtype=float) / np.maximum(v, x.v_min)
        case "vdelta":
            return v * x.delta
        case "r":
            return np.asarray(x.r, dtype=float)
        case "ratelim":
            return _rate_limited(x) - np.asarray(x.delta, dtype=float)
        case "vr":
            return v * x.r
    raise DseError(f"unknown correction feature {name!r}")


def features(x: FeatureInputs, terms: Iterable[CorrectionTerm] = TERMS) -> dict[str, np.ndarray]:
    """Each term's feature column, keyed by its parameter name: the regression's
    Θ, with model.c's definitions."""
    return {t.variable: _feature(t.feature, x) for t in terms}


def filtered_rate(
    t_cmd: np.ndarray, u: np.ndarray, t: np.ndarray, tau: float = TAU_F
) -> tuple[np.ndarray, np.ndarray]:
    """The C block's filtered derivative of a piecewise-constant command, in closed form.

    The command is ``u[k]`` from ``t_cmd[k]`` on and 0 before the first (as the vehicle holds it); the
    filter state w follows dw/dt = (u − w)/tau from w = 0, and the rate is (u − w)/tau. Returns the
    filtered command w and the rate at the times ``t`` (shift ``t`` by a time offset before calling).
    """
    t_cmd, u, t = (np.asarray(a, dtype=float) for a in (t_cmd, u, t))
    # The state just before each command switches in, one segment at a time (exact between switches).
    w_at = np.empty(len(t_cmd))
    w, held, since = 0.0, 0.0, t_cmd[0] if len(t_cmd) else 0.0
    for k, tk in enumerate(t_cmd):
        w = held + (w - held) * math.exp(-(tk - since) / tau)
        w_at[k], held, since = w, u[k], tk
    k = np.searchsorted(t_cmd, t + 1e-9 * (1.0 + np.abs(t)), side="right") - 1
    before = k < 0
    kk = np.where(before, 0, k)
    u_now = np.where(before, 0.0, u[kk] if len(u) else 0.0)
    w_start = np.where(before, 0.0, w_at[kk] if len(u) else 0.0)
    elapsed = np.where(before, 0.0, t - (t_cmd[kk] if len(t_cmd) else 0.0))
    w_now = u_now + (w_start - u_now) * np.exp(-elapsed / tau)
    return w_now, (u_now - w_now) / tau


def distance(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """s = ∫|v| dt from the first sample (trapezoids), as the C block's distance state."""
    a = np.abs(np.asarray(v, dtype=float))
    steps = np.diff(np.asarray(t, dtype=float)) * 0.5 * (a[1:] + a[:-1])
    return np.concatenate([[0.0], np.cumsum(steps)])


def terms_json(fit: FitResult) -> list[dict[str, Any]]:
    """The discovered terms of a fit as the JSON's ``terms``: readable text,
    parameter, value, ~95 % interval."""
    interval = fit.interval()
    shapes = shape_values(fit.point)
    out = []
    for name, value in fit.values.items():
        if is_correction(name):
            t = term(name)
            low, high = interval[name]
            shape = shape_of(t)
            out.append(
                {
                    "text": readable_term(t, value, (low, high), shapes),
                    "variable": t.variable,
                    "value": value,
                    "interval": [low, high],
                }
                | ({shape.key: shapes[shape.variable]} if shape and shape.variable in shapes else {})
            )
    return out
