"""Bounds the master holds a model-exchange instance's states within: ``state_max(tanks.x1)``.

Why: real processes have hard limits their first model leaves out: a tank that overflows, a stroke
that ends at a stop, a store that fills. The master integrates a model-exchange (ME) FMU itself, so,
as it adds derivative terms (derivative_terms.py), it can hold a state at a bound without any change
to the FMU, and a study can state, fit and prove the bound from recordings.

Three parameters, each named for what it does and to which state:

* ``state_max(INSTANCE.STATE)``, an upper bound B: while the state is at or above B, a derivative
  that would raise it further is set to 0, so the state stays at B and falls as soon as the FMU's
  derivative turns negative (a full tank whose inflow exceeds its outflow);
* ``state_min(INSTANCE.STATE)``, a lower bound, alike (an end stop, an empty store);
* ``state_overflow(INSTANCE.STATE, OTHER)``, a fraction f: of the rate a bound of STATE removes, f is
  added to the derivative of OTHER, a state of the same instance (the overflow of one tank falling
  into another; the rest, 1 − f, leaves the model).

A bound's neutral value is no bound at all (±inf, which a fit uses and nobody writes), an overflow's
0; at its neutral value a limit is not applied, so the run is bit for bit the run without it. The
limits act after the derivative terms, state by state in the state vector's order (an overflow into a
state that is itself at its bound is then removed there too).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from ..errors import DseError
from .values import split_named

Kind = Literal["max", "min", "overflow"]
NEUTRAL: dict[str, float] = {"max": math.inf, "min": -math.inf, "overflow": 0.0}
UNITS = {"max": "the state's unit", "min": "the state's unit", "overflow": "1"}
_BOUND = re.compile(r"^state_(max|min)\(\s*(?:([^\s.()]+)\.)?([^\s,()]+)\s*\)$")
_OVERFLOW = re.compile(r"^state_overflow\(\s*(?:([^\s.()]+)\.)?([^\s,()]+)\s*,\s*([^\s,()]+)\s*\)$")


@dataclass(frozen=True)
class StateLimit:
    """One limit parameter, parsed from its name. ``instance`` is None when the name leaves it out (one FMU);
    ``to`` is the state an overflow passes into."""

    kind: Kind
    instance: str | None
    state: str
    to: str | None = None

    @property
    def target(self) -> str:
        return f"{self.instance}.{self.state}" if self.instance else self.state

    @property
    def name(self) -> str:
        return f"state_{self.kind}({self.target}" + (f", {self.to})" if self.kind == "overflow" else ")")


def parse(name: str) -> StateLimit | None:
    """The limit a parameter's name declares, or None for any other name."""
    if match := _BOUND.match(name):
        return StateLimit(match[1], match[2], match[3])  # type: ignore[arg-type]
    if match := _OVERFLOW.match(name):
        return StateLimit("overflow", match[1], match[2], match[3])
    if name.startswith(("state_max(", "state_min(", "state_overflow(")):
        raise DseError(
            f"{name}: a state limit is named state_max(INSTANCE.STATE), state_min(INSTANCE.STATE) or "
            "state_overflow(INSTANCE.STATE, OTHER_STATE), e.g. state_max(tanks.x1)"
        )
    return None


def limit_name(kind: Kind, instance: str, state: str, to: str | None = None) -> str:
    """``max``, ``tanks``, ``x1`` -> ``state_max(tanks.x1)``."""
    return StateLimit(kind, instance, state, to).name


def split(values: Mapping[str, object]) -> tuple[dict[str, object], dict[StateLimit, float]]:
    """A run's values: all others, and the limits away from their neutral values."""
    plain, limits = split_named(values, parse, "a state limit's value", allow=_neutral)
    for limit, value in limits.items():
        if limit.kind == "overflow" and not 0.0 <= value <= 1.0:
            raise DseError(
                f"{limit.name}: an overflow is the fraction of the rate passed on, from 0 to 1 "
                f"(got {value:g})"
            )
    return plain, {limit: value for limit, value in limits.items() if value != NEUTRAL[limit.kind]}


def _neutral(limit: StateLimit, value: float) -> bool:
    """A bound of ±inf (no bound) is the one value past finite numbers a limit takes."""
    return value == NEUTRAL[limit.kind]


def check(limit: StateLimit, instance: str, interface: str, states: Sequence[str]) -> None:
    """That the master can apply ``limit`` to ``instance``: a model-exchange one, with the states it names
    (``states``: the instance's, derivative_terms.states_of)."""
    if interface != "me":
        raise DseError(
            f"{limit.name}: instance {instance!r} is run as co-simulation: it integrates its own states, "
            "so the master cannot hold them at a bound (give the instance interface: me in the "
            "multi-model, if its FMU offers model exchange)"
        )
    for state in (limit.state, limit.to):
        if state is not None and state not in states:
            raise DseError(
                f"{limit.name}: instance {instance!r} has no continuous state {state!r} "
                f"(its states: {', '.join(states) or 'none'})"
            )
    if limit.to == limit.state:
        raise DseError(f"{limit.name}: an overflow passes into another state than its own")


@dataclass(frozen=True)
class Row:
    """The limits of one state, as the integrator applies them: bounds, and where its overflow goes."""

    state: int
    low: float = -math.inf
    high: float = math.inf
    to: int = -1  # the state index an overflow passes into; -1: none
    fraction: float = 0.0


def rows(states: Sequence[str], limits: Mapping[StateLimit, float]) -> tuple[Row, ...]:
    """One row per bounded state, in the state vector's order; an overflow without a bound does nothing."""
    found: dict[int, dict[str, float]] = {}
    for limit, value in limits.items():
        entry = found.setdefault(states.index(limit.state), {})
        if limit.kind == "overflow":
            entry.update(to=states.index(limit.to), fraction=value)  # type: ignore[arg-type]
        else:
            entry["high" if limit.kind == "max" else "low"] = value
    return tuple(
        Row(index, **entry)
        for index, entry in sorted(found.items())  # type: ignore[arg-type]
        if "low" in entry or "high" in entry
    )


def hold(rows: Sequence[Row], x: Sequence[float], dx: Any) -> None:
    """Each bounded state's derivative, set to 0 where it would carry the state past its bound, with the
    given fraction of what was removed passed on (native_me.c does the same, operation for operation)."""
    for row in rows:
        rate, value = dx[row.state], x[row.state]
        if (value >= row.high and rate > 0.0) or (value <= row.low and rate < 0.0):
            dx[row.state] = 0.0
            if row.to >= 0:
                dx[row.to] += row.fraction * rate
