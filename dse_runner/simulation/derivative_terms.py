"""Terms the master adds to a model-exchange instance's state derivatives:
``derivative_term(msd.der(v), x^3)``.

Why: the master integrates a model-exchange (ME) FMU itself, so it can add to the derivatives the FMU
returns before the solver uses them. A term missing from a model's equations (a hardening spring, a
friction, a drag) can then be stated, fitted and proven for any ME FMU without changing it, as
signal_effects.py does for what happens outside the equations. Diagnosis proposes such terms from what the
recordings leave unexplained (analysis/diagnose/term_hypotheses.py).

A parameter named ``derivative_term(INSTANCE.der(STATE), TERM)`` is the coefficient ``a`` of TERM in

    der(STATE) = (the FMU's derivative) + a · TERM(states, inputs)

while the master integrates INSTANCE. TERM is ``1`` or a product of factors joined by ``*``; a factor is
a state or a real input of the instance (its FMU name), optionally raised to a whole power (``x^3``), or
one of :data:`FUNCTIONS` of one, optionally divided by a width (``abs(v)``, ``tanh(v/0.05)``: a sign
smoothed over ±0.05). ``sign`` is −1, 0 or +1 (a dry, Coulomb friction); ``sqrt`` is the SIGNED square
root, √|x| with the sign of x (Torricelli's outflow through an opening, ∝ √level, stays defined when a
level or a pressure difference crosses zero). At coefficient 0 a term is not applied at all: the run is
bit for bit the run without it. A co-simulation instance integrates itself and is refused.

A companion parameter ``derivative_width(INSTANCE.der(STATE), TERM)`` fits the width of TERM's one factor
with a function: its value w (finite, > 0) replaces the width written in TERM (its default; none written
is 1) for the term parameter of the same target and TERM, so ``derivative_term(msd.der(v), tanh(v/0.05))``
at −0.3 with ``derivative_width(msd.der(v), tanh(v/0.05))`` at 0.01 adds −0.3 · tanh(v/0.01), exactly
as ``derivative_term(msd.der(v), tanh(v/0.01))`` at −0.3 would. The two are matched as parsed (the same
instance as written, state and term; spaces and the spelling of numbers aside). A companion needs its
term parameter among the same values (a space: among its parameters), whatever the coefficient; at
coefficient 0 the term is not applied and the companion is ignored (its value is still checked), so a
fit that moves both stays bit for bit the plain run wherever the coefficient is 0. :func:`split` applies
the companions: every caller sees DerivativeTerm objects whose factor has the width the run uses (and a
name that writes it).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import DseError
from . import state_limits
from .values import split_named

PREFIX = "derivative_term"
WIDTH_PREFIX = "derivative_width"  # a term's fitted width (module docstring)


def _sign(x: Any) -> Any:
    """−1, 0 or +1 by the sign of ``x`` (NaN stays NaN), as np.sign: -0.0 gives 0.0."""
    return 1.0 if x > 0 else -1.0 if x < 0 else 0.0 if x == 0 else x


def _signed_sqrt(x: Any) -> Any:
    """The SIGNED square root √|x| · sign(x), numpy's way: bit for bit the scalar's and native_me.c's
    copysign(sqrt(fabs(x)), x) (np.sign(x) * np.sqrt(np.abs(x)) would give 0.0 where they give -0.0)."""
    return np.copysign(np.sqrt(np.abs(x)), x)


# By name, in native_me.c's order of function codes (1 + the index here): new ones go at the end.
FUNCTIONS = {
    "abs": np.abs,
    "tanh": np.tanh,
    "sin": np.sin,
    "cos": np.cos,
    "sign": np.sign,
    "sqrt": _signed_sqrt,
}
_SCALAR = {
    "abs": abs,
    "tanh": math.tanh,
    "sin": math.sin,
    "cos": math.cos,
    "sign": _sign,
    "sqrt": lambda x: math.copysign(math.sqrt(abs(x)), x),
}  # the same on a float, without numpy's cost
_NAME = re.compile(rf"^({PREFIX}|{WIDTH_PREFIX})\(\s*(?:([^\s.()]+)\.)?der\((.+)\)\s*,\s*(.+?)\s*\)$")
_VARIABLE = r"[A-Za-z_][A-Za-z0-9_.\[\]]*"
_FACTOR = re.compile(
    rf"^(?:({_VARIABLE})|({'|'.join(FUNCTIONS)})\(\s*({_VARIABLE})\s*(?:/\s*([0-9.eE+-]+)\s*)?\))"
    r"(?:\^(\d+))?$"
)


@dataclass(frozen=True, order=True)
class Factor:
    """One factor of a term: ``function(variable / width) ^ power``, or ``variable ^ power`` without one."""

    variable: str
    function: str | None = None
    width: float = 1.0
    power: int = 1

    @property
    def text(self) -> str:
        inner = (
            self.variable
            if self.function is None
            else (
                f"{self.function}({self.variable})"
                if self.width == 1.0
                else f"{self.function}({self.variable}/{self.width!r})"
            )
        )
        return inner if self.power == 1 else f"{inner}^{self.power}"

    def value(self, values: Mapping[str, Any]) -> Any:
        v = values[self.variable]
        if self.function is not None:
            v = (_SCALAR if isinstance(v, float) else FUNCTIONS)[self.function](
                v / self.width if self.width != 1.0 else v
            )
        return v if self.power == 1 else v**self.power


@dataclass(frozen=True)
class Term:
    """A product of factors; no factor at all is the constant 1."""

    factors: tuple[Factor, ...] = ()

    @property
    def text(self) -> str:
        return "*".join(f.text for f in self.factors) or "1"

    @property
    def variables(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(f.variable for f in self.factors))

    def value(self, values: Mapping[str, Any]) -> Any:
        """The term at ``values`` (numbers or arrays by variable name)."""
        out: Any = 1.0
        for factor in self.factors:
            out = out * factor.value(values)
        return out


def parse_term(text: str) -> Term:
    """``x^2*tanh(v/0.05)`` -> a Term; an error says which factor it cannot read and what a factor is."""
    text = text.strip()
    if text == "1":
        return Term()
    factors = []
    for part in text.split("*"):
        match = _FACTOR.match(part.strip())
        if match is None:
            raise DseError(
                f"term {text!r}: cannot read the factor {part.strip()!r}; a factor is a state or input "
                f"(x), a power of one (x^3), or {', '.join(FUNCTIONS)} of one, optionally over a width "
                "(tanh(v/0.05))"
            )
        plain, function, inside, width, power = match.groups()
        try:
            width_value = float(width) if width else 1.0
        except ValueError:
            width_value = math.nan
        if not (math.isfinite(width_value) and width_value > 0):
            raise DseError(f"term {text!r}: the width in {part.strip()!r} must be a number > 0")
        exponent = int(power) if power else 1
        if exponent < 1:
            raise DseError(f"term {text!r}: the power in {part.strip()!r} must be 1 or more")
        factors.append(Factor(plain or inside, function, width_value, exponent))
    return Term(tuple(factors))


@dataclass(frozen=True)
class DerivativeTerm:
    """One term parameter, parsed from its name. ``instance`` is None when
    the name leaves it out (one FMU)."""

    instance: str | None
    state: str
    term: Term

    @property
    def target(self) -> str:
        return f"{self.instance}.der({self.state})" if self.instance else f"der({self.state})"

    @property
    def name(self) -> str:
        return f"{PREFIX}({self.target}, {self.term.text})"


def _read(name: str, prefix: str) -> DerivativeTerm | None:
    """The target and term a ``prefix(INSTANCE.der(STATE), TERM)`` name declares, or None for a name
    without that prefix; an error for one with it that cannot be read."""
    match = _NAME.match(name)
    if match is None or match[1] != prefix:
        if name.startswith(f"{prefix}("):
            example = "x^3" if prefix == PREFIX else "tanh(v/0.05)"
            raise DseError(
                f"{name}: a derivative {'term' if prefix == PREFIX else 'width'} is named "
                f"{prefix}(INSTANCE.der(STATE), TERM), e.g. {prefix}(msd.der(v), {example})"
            )
        return None
    _, instance, state, term = match.groups()
    try:
        return DerivativeTerm(instance, state.strip(), parse_term(term))
    except DseError as e:
        raise DseError(f"{name}: {e}") from None


def parse(name: str) -> DerivativeTerm | None:
    """The derivative term a parameter's name declares, or None for any other name (a width's too)."""
    return _read(name, PREFIX)


def term_name(instance: str, state: str, term: Term | str) -> str:
    """``msd``, ``v``, ``x^3`` -> ``derivative_term(msd.der(v), x^3)``."""
    return DerivativeTerm(instance, state, term if isinstance(term, Term) else parse_term(term)).name


@dataclass(frozen=True)
class DerivativeWidth:
    """A companion parameter, parsed from its name: the width of the one factor of ``term`` with a
    function (module docstring). ``term`` is its term parameter's, with the width written in the name."""

    term: DerivativeTerm

    @property
    def name(self) -> str:
        return f"{WIDTH_PREFIX}({self.term.target}, {self.term.term.text})"

    @property
    def factor(self) -> int:
        """The index of the factor whose width it sets (parse_width has checked there is exactly one)."""
        return next(i for i, f in enumerate(self.term.term.factors) if f.function is not None)

    def applied(self, width: float) -> DerivativeTerm:
        """Its term with that factor's width ``width``."""
        factors = list(self.term.term.factors)
        factors[self.factor] = replace(factors[self.factor], width=width)
        return replace(self.term, term=Term(tuple(factors)))


def parse_width(name: str) -> DerivativeWidth | None:
    """The companion width a parameter's name declares, or None for any other name; an error when its
    term has not exactly one factor with a function."""
    term = _read(name, WIDTH_PREFIX)
    if term is None:
        return None
    functions = [f.text for f in term.term.factors if f.function is not None]
    if len(functions) != 1:
        has = f"{len(functions)} ({', '.join(functions)})" if functions else "none"
        raise DseError(
            f"{name}: a width is that of the one factor of its term with a function "
            f"({', '.join(FUNCTIONS)}), and {term.term.text} has {has}"
        )
    return DerivativeWidth(term)


def width_name(instance: str, state: str, term: Term | str) -> str:
    """``msd``, ``v``, ``tanh(v/0.05)`` -> ``derivative_width(msd.der(v), tanh(v/0.05))``."""
    parsed = term if isinstance(term, Term) else parse_term(term)
    name = DerivativeWidth(DerivativeTerm(instance, state, parsed)).name
    parse_width(name)  # exactly one factor with a function, or the error saying so
    return name


def check_width(width: DerivativeWidth, value: float) -> None:
    """That ``value`` can be a width: finite (split_named has checked it is a number) and > 0."""
    if not (math.isfinite(value) and value > 0):
        raise DseError(f"{width.name}: a width is a finite number > 0, not {value!r}")


def split(values: Mapping[str, object]) -> tuple[dict[str, object], dict[DerivativeTerm, float]]:
    """A run's values: all others, and the derivative terms (only those with a coefficient other than 0),
    each with the width its companion gives (module docstring). A companion must have its term parameter
    among ``values`` (at any coefficient: at 0 the companion is ignored), and a term it gives a width must
    not then be another term parameter given as well."""
    plain, widths = split_named(values, parse_width, "a derivative term's width")
    plain, terms = split_named(plain, parse, "a derivative term's coefficient")
    for width, value in widths.items():
        check_width(width, value)
        if width.term not in terms:
            raise DseError(
                f"{width.name}: the values have no {width.term.name}, whose width it fits; give the "
                "coefficient too"
            )
    applied: dict[DerivativeTerm, float] = {}
    given: dict[DerivativeTerm, str] = {}  # an applied term -> the parameter that gave it
    for term, coefficient in terms.items():
        if coefficient == 0.0:
            continue
        width = DerivativeWidth(term)
        name = term.name
        if width in widths:
            term, name = width.applied(widths[width]), width.name
        if term in applied:
            raise DseError(f"{given[term]} and {name} both make the run add {term.name}; give it once")
        applied[term], given[term] = coefficient, name
    return plain, applied


# ---- what an instance offers: its states and its real inputs -----------------------------------------------


def states_of(description: Any) -> list[str]:
    """The continuous states' names, in the order of the state vector (the derivatives' order in the model
    description, FMI 2 and 3 alike)."""
    return [d.variable.derivative.name for d in description.derivatives if d.variable.derivative is not None]


def real_inputs_of(description: Any) -> dict[str, int]:
    """The instance's real (FMI 3: Float64) inputs by name -> value reference: what
    a term may read besides states."""
    return {
        v.name: v.valueReference
        for v in description.modelVariables
        if v.causality == "input" and v.type in ("Real", "Float64") and not getattr(v, "dimensions", None)
    }


def check(term: DerivativeTerm, instance: str, interface: str, description: Any) -> None:
    """That the master can apply ``term`` to ``instance``: a model-exchange one, with that state, and every
    variable of the term one of its states or real inputs."""
    if interface != "me":
        raise DseError(
            f"{term.name}: instance {instance!r} is run as co-simulation: it integrates its own states, "
            "so the master cannot add to their derivatives (give the instance interface: me in the "
            "multi-model, if its FMU offers model exchange)"
        )
    states = states_of(description)
    if term.state not in states:
        raise DseError(
            f"{term.name}: instance {instance!r} has no continuous state {term.state!r} "
            f"(its states: {', '.join(states) or 'none'})"
        )
    readable = [*states, *real_inputs_of(description)]
    for variable in term.term.variables:
        if variable not in readable:
            raise DseError(
                f"{term.name}: {variable!r} is not a state or real input of instance {instance!r} "
                f"(a term may read {', '.join(readable)})"
            )


# ---- what the stepper applies ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Corrector:
    """The terms and state limits (state_limits.py) of one instance, laid out for its integrator: ``add``
    adds the terms to the derivative vector, then holds the bounded states."""

    rows: tuple[tuple[int, Term, float], ...]  # state index, term, coefficient
    states: tuple[str, ...]
    inputs: tuple[tuple[str, int], ...]  # the real inputs the terms read: name, value reference
    limits: tuple[state_limits.Row, ...] = ()

    @classmethod
    def of(
        cls, description: Any, corrections: Mapping[DerivativeTerm | state_limits.StateLimit, float]
    ) -> Corrector:
        """``corrections``: derivative terms and state limits, each with its value."""
        states = states_of(description)
        terms = {t: a for t, a in corrections.items() if isinstance(t, DerivativeTerm)}
        limits = {t: a for t, a in corrections.items() if isinstance(t, state_limits.StateLimit)}
        read = {v for t in terms for v in t.term.variables}
        inputs = tuple((name, vr) for name, vr in real_inputs_of(description).items() if name in read)
        rows = tuple((states.index(t.state), t.term, a) for t, a in terms.items())
        return cls(rows, tuple(states), inputs, state_limits.rows(states, limits))

    @property
    def empty(self) -> bool:
        return not (self.rows or self.limits)

    def add(self, x: Sequence[float], inputs: Sequence[float], dx: Any) -> None:
        """dx[i] += each coefficient · its term at states ``x`` and ``inputs`` (in :attr:`inputs`' order),
        then the limits; ``dx`` anything indexable in place (the solver's ctypes pointer, an array)."""
        values = dict(zip(self.states, x))
        values.update(zip((name for name, _ in self.inputs), inputs))
        for index, term, coefficient in self.rows:
            dx[index] += coefficient * term.value(values)
        if self.limits:
            state_limits.hold(self.limits, x, dx)
