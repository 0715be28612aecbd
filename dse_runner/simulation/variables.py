"""FMU variables and the values they take: types, checks and the rules of connections.

FMI 2.0 has four scalar types (Real, Integer, Boolean, String) plus
enumerations; FMI 3.0 has Float32/64, Int8..UInt64, Boolean, String,
Binary, Clock and enumerations. The master sorts them into four *families*
that decide what a value may be and how a connection converts it:

===========  ==================================  ===============================
family       types                               a value of it is
===========  ==================================  ===============================
float        Real, Float32, Float64              a finite number
integer      Integer, Int*, UInt*, Enumeration   a whole number
boolean      Boolean                             true or false (0 or 1)
string       String                              text
===========  ==================================  ===============================

Binary and Clock variables, and FMI 3 arrays, are none of these: they are
neither recorded nor connectable, and setting one is an error saying so.

Connections (docs/multimodel.md): a source feeds a target of its own family
unchanged; boolean feeds float or integer as 0/1; integer feeds float
exactly. A float or integer source feeds an integer target only with
``round: true`` and a boolean target only with a ``threshold`` (true when the
source is above it). Strings connect only to strings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Any

from pydantic import BeforeValidator

from ..errors import DseError

Value = float | int | bool | str

FAMILIES = {
    "Real": "float",
    "Float32": "float",
    "Float64": "float",
    "Integer": "integer",
    "Enumeration": "integer",
    **{f"{sign}Int{bits}": "integer" for sign in ("", "U") for bits in (8, 16, 32, 64)},
    "Boolean": "boolean",
    "String": "string",
}
SETTABLE = ("parameter", "input")

# What the C type of each integer type holds: ctypes would silently wrap anything else. FMI 2's
# Integer is 32-bit; enumerations are taken as FMI 3's Int64.
RANGES = {
    "Integer": (-(2**31), 2**31 - 1),
    "Enumeration": (-(2**63), 2**63 - 1),
    **{f"Int{bits}": (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) for bits in (8, 16, 32, 64)},
    **{f"UInt{bits}": (0, 2**bits - 1) for bits in (8, 16, 32, 64)},
}


def with_article(type_name: str) -> str:
    """'a Real', 'an Integer', 'a UInt16', 'an output': the article a name needs in a message."""
    return f"{'an' if type_name[:1] in 'AEIOaeiou' else 'a'} {type_name}"


def _plain_finite(value: Any) -> Any:
    """A number, a Boolean or a string, and not NaN or infinity: anything else is no value to give an FMU.
    Checked before the union, for one clear message instead of one per member."""
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{value} is not a finite number")
    if value is None:
        raise ValueError("no value given")
    if isinstance(value, (dict, list)):
        given = "mapping" if isinstance(value, dict) else "list"
        raise ValueError(f"expected a number, a Boolean or a string, not a {given}")  # noqa: TRY004  (pydantic)
    return value


FiniteValue = Annotated[Value, BeforeValidator(_plain_finite)]  # a value as files give it


def split_ref(ref: str) -> tuple[str, str]:
    """'vehicle.mass' -> ('vehicle', 'mass'); variable names may hold dots themselves."""
    instance, dot, variable = ref.partition(".")
    if not dot or not instance or not variable:
        raise ValueError(f"{ref!r} is not of the form instance.variable")
    return instance, variable


@dataclass(frozen=True)
class Variable:
    """What the master needs of one model variable: where it is, its type, and its bounds."""

    instance: str
    name: str
    vr: int
    type: str  # FMPy's type name: Real, Float64, Int32, Boolean, String, Enumeration...
    causality: str
    low: float | None = None  # the declared min and max, if any
    high: float | None = None
    scalar: bool = True  # FMI 3 arrays are not
    start: bool = False  # not a parameter or input, but its start value may be set before initialisation

    @property
    def ref(self) -> str:
        return f"{self.instance}.{self.name}"

    @property
    def family(self) -> str | None:
        """float, integer, boolean or string; None for what the master does not handle."""
        return FAMILIES.get(self.type) if self.scalar else None

    @property
    def numeric(self) -> bool:
        """Recorded as a number: floats, integers and booleans (as 0/1)."""
        return self.family in ("float", "integer", "boolean")


def describe_variable(instance: str, v) -> Variable:
    """Our record of an FMPy model variable."""
    declared = v.declaredType

    def bound(name: str) -> float | None:
        text = getattr(v, name, None)
        if text in (None, "") and declared is not None:
            text = getattr(declared, name, None)
        try:
            return float(text) if text not in (None, "") else None
        except (TypeError, ValueError):
            return None

    scalar = not getattr(v, "dimensions", None)
    return Variable(
        instance,
        v.name,
        v.valueReference,
        v.type,
        v.causality,
        bound("min"),
        bound("max"),
        scalar,
        start_settable(v),
    )


def start_settable(v) -> bool:
    """Whether FMI lets an importer set this output or local before initialisation: its start value is
    ``exact`` or ``approx`` and it is not a constant (a model-exchange state's initial value, for one). The
    master sets every value before initialisation, so it may set these too."""
    return (
        v.causality in ("output", "local")
        and getattr(v, "initial", None) in ("exact", "approx")
        and v.variability != "constant"
    )


def check_settable(variable: Variable) -> None:
    if variable.causality not in SETTABLE and not variable.start:
        raise DseError(
            f"{variable.ref!r} is {with_article(variable.causality)}, not a parameter or input, and "
            "its start value is not exact or approx: it cannot be set"
        )
    if variable.family is None:
        what = "an array" if not variable.scalar else with_article(variable.type)
        raise DseError(f"{variable.ref!r} is {what}, which dse-runner cannot set")


def check_value(variable: Variable, value: Value) -> Value:
    """``value`` as the FMU takes it, checked: settable, of the variable's type, within its declared
    min and max. Errors name the variable, the value and the rule."""
    check_settable(variable)
    value = coerce(variable, value)
    if variable.family in ("float", "integer"):
        if variable.low is not None and value < variable.low:
            raise DseError(f"{variable.ref} = {value:g} is below its declared min {variable.low:g}")
        if variable.high is not None and value > variable.high:
            raise DseError(f"{variable.ref} = {value:g} is above its declared max {variable.high:g}")
    return value


def coerce(variable: Variable, value: Value) -> Value:
    """A value of the variable's family, so the FMU never sees a wrong one."""
    family = variable.family
    if family == "string":
        return str(value)
    if isinstance(value, str):
        value = _parse(variable, value)
    if family == "boolean":
        if value in (0, 1):  # True, False, 0, 1, 0.0, 1.0
            return bool(value)
        raise DseError(f"{variable.ref}: {value!r} is not a Boolean (true, false, 0 or 1)")
    if isinstance(value, float) and not math.isfinite(value):
        raise DseError(f"{variable.ref}: {value!r} is not a finite number")
    if family == "float":
        return float(value)
    if isinstance(value, float) and not value.is_integer():  # an int stays exact: Int64 goes past 2^53
        raise DseError(
            f"{variable.ref}: {value!r} is not a whole number, as {with_article(variable.type)} must be"
        )
    value = int(value)
    low, high = RANGES.get(variable.type, (value, value))
    if not low <= value <= high:
        raise DseError(
            f"{variable.ref} = {value} does not fit {with_article(variable.type)} ({low} to {high})"
        )
    return value


def _parse(variable: Variable, text: str) -> Value:
    lowered = text.strip().lower()
    if variable.family == "boolean" and lowered in ("true", "false"):
        return lowered == "true"
    for number in (int, float):  # int first: float() would round a large Int64
        try:
            return number(text)
        except ValueError:
            pass
    raise DseError(f"{variable.ref}: {text!r} is not a valid {variable.type}")


@dataclass(frozen=True)
class Conversion:
    """How a connection turns its source's value into its target's: nothing, 0/1, rounding or a threshold."""

    kind: str = "none"  # none | round | threshold
    threshold: float = 0.0


def conversion(
    source: Variable, target: Variable, round_: bool = False, threshold: float | None = None
) -> Conversion:
    """The conversion the rules allow for ``source -> target``, or an error saying which option would."""
    s, t = source.family, target.family
    where = f"connection {source.ref} -> {target.ref}"
    if s is None or t is None:
        bad = source if s is None else target
        raise DseError(
            f"{where}: {bad.ref} is {'an array' if not bad.scalar else with_article(bad.type)}, "
            "which dse-runner cannot connect"
        )
    if round_ and threshold is not None:
        raise DseError(f"{where}: give either 'round' or 'threshold', not both")
    if "string" in (s, t):
        if s != t:
            raise DseError(
                f"{where}: {with_article(source.type)} cannot feed {with_article(target.type)}: "
                "strings connect only to strings"
            )
        return _no_option(where, round_, threshold)
    if t == "boolean" and s != "boolean":
        if threshold is None:
            raise DseError(
                f"{where}: {with_article(source.type)} feeds a Boolean only through a threshold: "
                "write {input: " + target.ref + ", threshold: 0.5} (true above it)"
            )
        return Conversion("threshold", float(threshold))
    if t == "integer" and s == "float":
        if not round_:
            raise DseError(
                f"{where}: {with_article(source.type)} feeds {with_article(target.type)} only "
                "when rounded: write {input: " + target.ref + ", round: true}"
            )
        return Conversion("round")
    return _no_option(where, round_, threshold)


def _no_option(where: str, round_: bool, threshold: float | None) -> Conversion:
    if round_ or threshold is not None:
        raise DseError(
            f"{where}: 'round' and 'threshold' apply only to a number feeding an integer "
            "or a Boolean; this connection needs neither"
        )
    return Conversion()
