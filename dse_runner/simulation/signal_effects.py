"""Effects on a signal outside any FMU: a delay, a first-order lag, a gain, an offset, and the hard
nonlinearities of actuators and sensors: saturation, a dead zone, backlash, a rate limit, a square term.

Why: what a model most often misses between its inputs and what the real system
received (a late or sluggish actuator, a miscalibrated command) and between its
outputs and what a sensor recorded (a late, filtered, scaled or biased
measurement) can be stated and fitted for any FMU without changing it. The
master applies an input effect to a scenario's input signal before the FMU sees
it, and an output effect to a simulated signal before an objective compares it
with its recording; diagnosis offers them as its model-independent hypotheses.

An effect is a parameter of a study like any other, named for what it does
and to which signal: ``input_delay(vehicle.delta_f)``, ``output_gain(tank.level)``
(:data:`EFFECTS`). A sweep varies it, a search or a fit tunes it, the store
keeps it as a column; ``simulate`` takes it among its values. An input effect
acts on a signal a scenario drives, an output effect on any recorded signal.

Each effect wraps a signal and is a signal itself: anything with ``at(t)``, as
trajectory.Series is, so effects compose and the step loop samples them as it
samples a recorded input. At its neutral value (delay 0, lag 0, gain 1, offset
0, no bound, no dead zone, no backlash, no rate limit, no square term) an effect
returns the signal's own values unchanged, bit for bit, so a hypothesis that is
absent changes nothing.

The hard ones:

* ``max`` and ``min`` clip the signal at a bound (an actuator that saturates, a
  sensor at the end of its range); neutral ±inf, which a fit uses and nobody writes;
* ``deadzone`` w: nothing passes while |u| ≤ w, then u − w·sign(u) (a valve or a pump
  that needs some voltage before it moves);
* ``backlash`` w: the output follows only once the input has moved more than w
  from where it last pushed (play in a gear), starting at the signal's first value;
* ``rate`` r: the output follows at most r per second (a slew-limited actuator);
  neutral +inf;
* ``square`` q: u + q·u², with gain and offset a polynomial map (an uncalibrated
  sensor or a nonlinear actuator characteristic).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

from ..errors import DseError
from .values import split_named

Kind = Literal["delay", "lag", "backlash", "deadzone", "rate", "square", "gain", "offset", "max", "min"]
NEUTRAL: dict[str, float] = {  # also the order they apply in
    "delay": 0.0,
    "lag": 0.0,
    "backlash": 0.0,
    "deadzone": 0.0,
    "rate": math.inf,
    "square": 0.0,
    "gain": 1.0,
    "offset": 0.0,
    "max": math.inf,
    "min": -math.inf,
}
EFFECTS = tuple(f"{side}_{kind}" for side in ("input", "output") for kind in NEUTRAL)  # input_delay, ...
UNITS = {
    "delay": "s",
    "lag": "s",
    "backlash": "the signal's unit",
    "deadzone": "the signal's unit",
    "rate": "the signal's unit per s",
    "square": "1 / the signal's unit",
    "gain": "1",
    "offset": "the signal's unit",
    "max": "the signal's unit",
    "min": "the signal's unit",
}
NON_NEGATIVE = ("delay", "lag", "backlash", "deadzone", "rate")
_NAME = re.compile(rf"^(input|output)_({'|'.join(NEUTRAL)})\((.+)\)$")


@dataclass(frozen=True)
class Effect:
    """One effect parameter, parsed from its name: ``input_lag(vehicle.delta_f)``."""

    side: Literal["input", "output"]
    kind: Kind
    target: str  # instance.variable

    @property
    def id(self) -> str:
        return f"{self.side}_{self.kind}"

    @property
    def name(self) -> str:
        return f"{self.id}({self.target})"


def parse(name: str) -> Effect | None:
    """The effect a parameter's name declares, or None for an FMU variable."""
    match = _NAME.match(name)
    return Effect(match[1], match[2], match[3]) if match else None  # type: ignore[arg-type]


def split(values: Mapping[str, object]) -> tuple[dict[str, object], dict[Effect, float]]:
    """A run's values: those for FMU variables, and the effects (only those away from neutral)."""
    plain, effects = split_named(values, parse, "an effect", allow=lambda e, v: v == NEUTRAL[e.kind])
    for effect, value in effects.items():
        if effect.kind in NON_NEGATIVE and value < 0:
            raise DseError(
                f"{effect.name}: a {effect.kind} cannot be negative ({value:g} {UNITS[effect.kind]})"
            )
    return plain, {effect: value for effect, value in effects.items() if value != NEUTRAL[effect.kind]}


class Signal(Protocol):
    """What an effect wraps: a signal that can be sampled at any times (trajectory.Series, or an effect)."""

    def at(self, t: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class Sampled:
    """A signal known at increasing times, linear in between and held beyond its ends: a simulated output."""

    time: np.ndarray
    values: np.ndarray

    def at(self, t: np.ndarray) -> np.ndarray:
        return np.interp(t, self.time, self.values)


@dataclass(frozen=True)
class Delayed:
    """The signal ``delay`` seconds late; before the signal starts it holds its first value."""

    signal: Signal
    delay: float

    def at(self, t: np.ndarray) -> np.ndarray:
        return self.signal.at(np.asarray(t, dtype=float) - self.delay)


@dataclass(frozen=True)
class Scaled:
    """gain · signal + offset."""

    signal: Signal
    gain: float = 1.0
    offset: float = 0.0

    def at(self, t: np.ndarray) -> np.ndarray:
        values = self.signal.at(t)
        if self.gain != 1.0:
            values = self.gain * values
        return values + self.offset if self.offset != 0.0 else values


@dataclass(frozen=True)
class Lagged:
    """The signal through a first-order lag of time constant ``tau``, y' = (u − y) / tau, starting at rest
    on the signal's value at the first time asked.

    Solved exactly between the times asked, for an input linear in between. Each call starts afresh at its
    first time: the master asks once for every communication point of a run."""

    signal: Signal
    tau: float

    def at(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        u = self.signal.at(t)
        if self.tau <= 0.0 or t.size < 2:
            return u
        return first_order_lag(t, u, self.tau)


def first_order_lag(t: np.ndarray, u: np.ndarray, tau: float) -> np.ndarray:
    """y' = (u − y) / tau with y(t0) = u(t0), for u linear between its samples: exact at every sample.

    Between samples the input is u_k + m·s (m its slope), whose response from y_k after s is
    u_k + m·s − m·tau + (y_k − u_k + m·tau)·exp(−s/tau)."""
    dt = np.diff(t)
    decay = np.exp(-dt / tau)
    slope = np.diff(u) / np.where(dt > 0, dt, 1.0)
    y = np.empty_like(u, dtype=float)
    y[0] = u[0]
    for k in range(len(dt)):  # a recursion: each sample starts from the last
        drift = slope[k] * tau
        y[k + 1] = u[k + 1] - drift + (y[k] - u[k] + drift) * decay[k]
    return y


@dataclass(frozen=True)
class Mapped:
    """A static map of the signal's values (a clip, a dead zone, a square term)."""

    signal: Signal
    kind: Kind
    value: float

    def at(self, t: np.ndarray) -> np.ndarray:
        u = self.signal.at(t)
        if self.kind == "max":
            return np.minimum(u, self.value)
        if self.kind == "min":
            return np.maximum(u, self.value)
        if self.kind == "deadzone":
            return np.sign(u) * np.maximum(np.abs(u) - self.value, 0.0)
        return u + self.value * u * u  # square


@dataclass(frozen=True)
class Tracked:
    """The signal followed by something with memory, at the times asked: through play of ``backlash`` (the
    output moves only once the input is more than that from it), or at most ``rate`` per second. Each call
    starts afresh on the signal's value at its first time, as Lagged does."""

    signal: Signal
    kind: Kind
    value: float

    def at(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        u = self.signal.at(t)
        if t.size < 2:
            return u
        return backlash(u, self.value) if self.kind == "backlash" else rate_limited(t, u, self.value)


def backlash(u: np.ndarray, width: float) -> np.ndarray:
    """y follows u with play ``width``: y stays while |u − y| ≤ width / 2, else it is dragged along."""
    y = np.empty_like(u, dtype=float)
    y[0], half = u[0], 0.5 * width
    for k in range(1, len(u)):  # a recursion: each sample starts from the last
        y[k] = min(max(y[k - 1], u[k] - half), u[k] + half)
    return y


def rate_limited(t: np.ndarray, u: np.ndarray, rate: float) -> np.ndarray:
    """y follows u, changing by at most ``rate`` per second between the times asked."""
    y = np.empty_like(u, dtype=float)
    y[0] = u[0]
    limits = rate * np.diff(t)
    for k in range(1, len(u)):
        y[k] = y[k - 1] + min(max(u[k] - y[k - 1], -limits[k - 1]), limits[k - 1])
    return y


def apply(signal: Signal, kind: Kind, value: float) -> Signal:
    """``signal`` under one effect at ``value``; the signal itself at the neutral value."""
    if value == NEUTRAL[kind]:
        return signal
    if kind == "delay":
        return Delayed(signal, value)
    if kind == "lag":
        return Lagged(signal, value)
    if kind in ("backlash", "rate"):
        return Tracked(signal, kind, value)
    if kind in ("deadzone", "square", "max", "min"):
        return Mapped(signal, kind, value)
    if kind == "gain":
        return Scaled(signal, gain=value)
    return Scaled(signal, offset=value)


def in_order(effects: Mapping[Effect, float]) -> list[tuple[Effect, float]]:
    """Effects on one signal apply in NEUTRAL's order, whatever order they are given in: the signal is
    delayed, lagged, passed through backlash, a dead zone and a rate limit, mapped by u + square·u², then
    scaled by the gain, shifted by the offset and clipped to max and min (a sensor's range is the last
    thing its reading meets). Delay and lag commute; the rest do not."""
    order = list(NEUTRAL)
    return sorted(effects.items(), key=lambda item: order.index(item[0].kind))


def on_inputs(
    series: Mapping[str, Signal], times: np.ndarray, effects: Mapping[Effect, float]
) -> dict[str, np.ndarray]:
    """The input signals the input ``effects`` change, sampled at ``times``: what the FMUs receive
    instead of the scenario's own signals."""
    changed: dict[str, Signal] = {}
    for effect, value in in_order(effects):
        if effect.side != "input":
            continue
        if effect.target not in series:
            driven = ", ".join(series) or "none"
            raise DseError(
                f"{effect.name}: {effect.target} is not an input the scenario drives (driven: {driven})"
            )
        changed[effect.target] = apply(changed.get(effect.target, series[effect.target]), effect.kind, value)
    return {ref: signal.at(times) for ref, signal in changed.items()}


def on_outputs(time: np.ndarray, column, effects: Mapping[Effect, float]) -> dict[str, np.ndarray]:
    """The recorded signals the output ``effects`` change, as a sensor under them would have recorded
    them; ``column(name)`` gives a simulated signal."""
    changed: dict[str, np.ndarray] = {}
    for effect, value in in_order(effects):
        if effect.side == "output":
            values = changed.get(effect.target)
            values = column(effect.target) if values is None else values
            changed[effect.target] = on_output(time, np.asarray(values, dtype=float), effect.kind, value)
    return changed


def on_output(time: np.ndarray, values: np.ndarray, kind: Kind, value: float) -> np.ndarray:
    """A simulated output as a sensor under the effect would have recorded it, at the simulation's times."""
    if value == NEUTRAL[kind]:
        return values
    return apply(Sampled(time, values), kind, value).at(time)
