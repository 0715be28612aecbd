"""Objectives: the numbers a simulation is scored by, declared as data.

In space.yaml an objective is one of (docs/space.md):

* ``{signal: tank.level, reduce: max}``: a reduction of one recorded signal
  over the simulated time: final, min, max, mean (time average),
  sample_mean (the mean of the communication-point samples, as INTO-CPS computes it), integral,
  rms, changes (how often the value changes), time_above / time_below a
  ``threshold``, or settling_time (when it last enters a band around its
  target). With ``target: 1.5`` the reduction applies to the signal's
  deviation from 1.5 (``{signal: tank.level, target: 1.5, reduce: rms}`` is
  the rms deviation); settling_time's target is by default the final value;
* ``{signal: msd.x, recorded: x, metric: rmse}``: a signal against a column
  of the scenario's recording, at the recorded sample times: rmse, mae,
  max_abs, sum_squares, or residuals (every error, a vector: what least squares fits; a space whose
  only objective it is ranks by its sum of squares, added as ``<name>_sum_squares``);
* ``{script: metrics/settle.py, args: [...]}``: a Python 3 script run in a
  subprocess with INTO-CPS's calling convention (scripts.py);
* a name: an objective a plug-in registers in the entry-point group
  ``dse_runner.objectives`` (the field-data kind registers the paper's
  ``cross_track_error`` and its kin), or ``module:function``.

A named objective is held to the contract :class:`Objective`: called as
``objective(trajectory, scenario)`` with the whole result: ``trajectory.time``,
``trajectory.column(name)`` for every recorded output, and the scenario (its
inputs, parameters and recording). It returns a number, or, if its ``vector``
is true, one number per sample (stored as a list; rankings cannot use it). A
plain function is one too, marked ``function.vector = True`` for a vector.

Every value must be a finite number: anything else fails the task with a
message naming the objective, never a result row holding NaN.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from importlib.metadata import EntryPoint
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, Discriminator, Tag, TypeAdapter, ValidationError, model_validator

from .. import plugins
from ..errors import DseError, format_validation_error
from ..schema import Strict
from .scripts import Script, run_scripts

if TYPE_CHECKING:
    from .scenario import Scenario
    from .trajectory import Trajectory


Reduction = Literal[
    "final",
    "min",
    "max",
    "mean",
    "sample_mean",
    "integral",
    "rms",
    "changes",
    "time_above",
    "time_below",
    "settling_time",
]


class Reduce(BaseModel):
    """One signal reduced to a number over the simulated time."""

    model_config = Strict
    signal: str
    reduce: Reduction
    threshold: float | None = None  # time_above, time_below
    target: float | None = None  # reduce signal - target; settling_time's default: the final value
    tolerance: float = 0.02  # settling_time: the band is tolerance x |target - initial value| ...
    band: float | None = None  # ... unless an absolute half-width is given

    @model_validator(mode="after")
    def _options(self) -> Reduce:
        if self.reduce in ("time_above", "time_below") and self.threshold is None:
            raise ValueError(f"reduce: {self.reduce} needs a 'threshold'")
        if self.threshold is not None and self.reduce not in ("time_above", "time_below"):
            raise ValueError(f"'threshold' applies to time_above and time_below, not {self.reduce}")
        if self.reduce != "settling_time" and self.band is not None:
            raise ValueError(f"'band' applies to settling_time, not {self.reduce}")
        if self.reduce in ("time_above", "time_below", "changes") and self.target is not None:
            raise ValueError(f"'target' does not apply to {self.reduce}")
        return self


class Fit(BaseModel):
    """One signal against a recorded column, at the recorded times within the simulation."""

    model_config = Strict
    signal: str
    recorded: str
    metric: Literal["rmse", "mae", "max_abs", "sum_squares", "residuals"] = "rmse"  # residuals: a vector


def _objective_kind(value: Any) -> str | None:
    """Which form an objective's entry has, by its keys: a wrong entry is then
    judged against that form only."""
    if isinstance(value, str):
        return "name"
    if isinstance(value, Script) or (isinstance(value, Mapping) and "script" in value):
        return "script"
    if isinstance(value, Fit) or (isinstance(value, Mapping) and ("recorded" in value or "metric" in value)):
        return "fit"
    if isinstance(value, Reduce) or (isinstance(value, Mapping) and ("reduce" in value or "signal" in value)):
        return "reduce"  # a signal with neither a recording nor a reduction: what it lacks is named
    return None


# A registered name or module:function, or one of the three mappings; a wrong entry gives the messages of the
# form its keys choose, not one per form.
ObjectiveSpec = Annotated[
    Annotated[Reduce, Tag("reduce")]
    | Annotated[Fit, Tag("fit")]
    | Annotated[Script, Tag("script")]
    | Annotated[str, Tag("name")],
    Discriminator(
        _objective_kind,
        custom_error_type="objective",
        custom_error_message="expected a name, {signal, reduce}, {signal, recorded, metric} "
        "or {script, args}",
    ),
]


def normalise(
    objectives: list[str] | Mapping[str, ObjectiveSpec | Mapping[str, Any]],
) -> dict[str, ObjectiveSpec]:
    """name -> spec; a plain list names registered objectives or import paths by themselves. A spec given
    as a plain mapping (``simulate(objectives={"peak": {"signal": ..., "reduce": "max"}})``, as space.yaml
    writes it) is read as space.yaml's would be."""
    if isinstance(objectives, Mapping):
        return {name: _parsed(name, spec) for name, spec in objectives.items()}
    return {name: name for name in objectives}


def from_command_line(items: Sequence[str]) -> dict[str, ObjectiveSpec]:
    """``--objective`` values: a registered name or ``module:function`` as they are, or a spec as space.yaml
    writes one, in YAML's flow form: ``{signal: tank.level, recorded: level, metric: rmse}`` (named
    ``level_rmse``: the recorded column, or the signal, and the metric or reduction) or
    ``{peak: {signal: tank.level, reduce: max}}`` (named as written)."""
    import yaml

    found: dict[str, ObjectiveSpec] = {}
    for item in items:
        if not item.lstrip().startswith("{"):
            found[item] = item
            continue
        try:
            data = yaml.safe_load(item)
        except yaml.YAMLError as e:
            raise DseError(f"--objective {item!r}: not a YAML mapping: {str(e).splitlines()[0]}") from None
        if not isinstance(data, dict):
            raise DseError(
                f"--objective {item!r}: give a name, module:function, or a mapping such as "
                "'{signal: inst.var, recorded: column, metric: rmse}'"
            )
        if len(data) == 1 and isinstance(next(iter(data.values())), dict):  # {name: {...}}
            ((name, spec),) = data.items()
            found[str(name)] = _parsed(str(name), spec)
            continue
        try:
            spec = TypeAdapter(ObjectiveSpec).validate_python(data)
        except ValidationError as e:
            raise DseError(format_validation_error(f"--objective {item}", e)) from None
        found[_named(spec)] = spec
    return found


def _named(spec: ObjectiveSpec) -> str:
    """A spec's name when the command line gives none: what it reads and how it scores it."""
    if isinstance(spec, Fit):
        return f"{spec.recorded}_{spec.metric}"
    if isinstance(spec, Reduce):
        return f"{spec.signal.rsplit('.', 1)[-1]}_{spec.reduce}"
    return "script"


def _parsed(name: str, spec: ObjectiveSpec | Mapping[str, Any]) -> ObjectiveSpec:
    if not isinstance(spec, Mapping):
        return spec
    try:
        return TypeAdapter(ObjectiveSpec).validate_python(dict(spec))
    except ValidationError as e:
        raise DseError(format_validation_error(f"objectives.{name}", e)) from None


# ---- reductions ----------------------------------------------------------------------------------


def _span(time: np.ndarray) -> float:
    return float(time[-1] - time[0])


def _integral(time: np.ndarray, values: np.ndarray) -> float:
    return float(np.trapezoid(values, time))


def _time_where(time: np.ndarray, holds: np.ndarray) -> float:
    """Time during which a condition holds, each value held until the next communication point."""
    return float(np.sum(np.diff(time)[holds[:-1]]))


def _settling_time(time: np.ndarray, values: np.ndarray, spec: Reduce) -> float:
    """Time from the start until the signal last enters its band and stays;
    the whole span if it never does."""
    target = values[-1] if spec.target is None else spec.target
    band = spec.band if spec.band is not None else spec.tolerance * abs(target - values[0])
    outside = np.flatnonzero(np.abs(values - target) > band)
    if outside.size == 0:
        return 0.0
    last = outside[-1]
    return _span(time) if last == len(values) - 1 else float(time[last + 1] - time[0])


REDUCTIONS: dict[str, Callable[[np.ndarray, np.ndarray, Reduce], float]] = {
    "final": lambda t, v, s: float(v[-1]),
    "min": lambda t, v, s: float(v.min()),
    "max": lambda t, v, s: float(v.max()),
    "mean": lambda t, v, s: _integral(t, v) / _span(t),
    "sample_mean": lambda t, v, s: float(np.mean(v)),
    "integral": lambda t, v, s: _integral(t, v),
    "rms": lambda t, v, s: float(np.sqrt(_integral(t, v * v) / _span(t))),
    "changes": lambda t, v, s: float(np.count_nonzero(np.diff(v))),
    "time_above": lambda t, v, s: _time_where(t, v > s.threshold),
    "time_below": lambda t, v, s: _time_where(t, v < s.threshold),
    "settling_time": _settling_time,
}

METRICS: dict[str, Callable[[np.ndarray], float]] = {
    "rmse": lambda e: float(np.sqrt(np.mean(e * e))),
    "mae": lambda e: float(np.mean(np.abs(e))),
    "max_abs": lambda e: float(np.max(np.abs(e))),
    "sum_squares": lambda e: float(np.sum(e * e)),  # what least squares minimises, summed over scenarios
    "residuals": lambda e: e,  # simulated minus recorded at each sample: what least squares fits
}


def reduce(spec: Reduce, trajectory, scenario) -> float:
    values = trajectory.column(spec.signal)
    if spec.target is not None and spec.reduce != "settling_time":
        values = values - spec.target
    return REDUCTIONS[spec.reduce](trajectory.time, values, spec)


def fit(spec: Fit, trajectory, scenario) -> float:
    if scenario.recorded is None:
        raise DseError(f"scenario {scenario.name} has no recording to compare {spec.signal} with")
    t, recorded = scenario.recorded.samples(spec.recorded)
    time = trajectory.time
    inside = (t >= time[0]) & (t <= time[-1] + 1e-9)
    if not inside.any():
        raise DseError(
            f"scenario {scenario.name}: no recorded {spec.recorded} sample lies within the "
            f"simulated time {time[0]:g}..{time[-1]:g} s"
        )
    errors = np.interp(t[inside], time, trajectory.column(spec.signal)) - recorded[inside]
    return METRICS[spec.metric](errors)


# ---- named objectives: plug-ins and import paths --------------------------------------------------


class Objective(ABC):
    """A named objective: the contract of the entry-point group ``dse_runner.objectives`` (whose entries
    name an instance of a subclass, or a plain function) and of a user's ``module:function``.

    Lifecycle: the name is looked up when the space is read (so that an unknown one fails before any
    task), and its ``vector`` decides whether rankings may use it. Then, on the worker, after every
    simulation of a task, the objective is called once with the task's trajectory and scenario, looked
    up again by name there (objectives travel as names, never pickled). It returns a finite number, or,
    if ``vector``, a sequence of finite numbers (one per sample: what least squares fits); anything
    else fails that task with a message naming the objective.

    Optional part: ``vector`` (False: one number)."""

    vector: bool = False

    @abstractmethod
    def __call__(self, trajectory: Trajectory, scenario: Scenario) -> float | Sequence[float]:
        """The objective's value for one simulated task."""


@dataclass(frozen=True)
class FunctionObjective(Objective):
    """A plain function held to the contract, as docs/space.md promises users: ``function.vector = True``
    (read once, here) marks a vector."""

    function: Callable[[Trajectory, Scenario], float | Sequence[float]]
    vector: bool = False

    def __call__(self, trajectory: Trajectory, scenario: Scenario) -> float | Sequence[float]:
        return self.function(trajectory, scenario)


def as_objective(found: Any, where: str) -> Objective:
    """What a name stands for, as an :class:`Objective`: itself, or a plain function wrapped."""
    if isinstance(found, Objective):
        return found
    if callable(found) and not isinstance(found, type):
        return FunctionObjective(found, bool(getattr(found, "vector", False)))
    raise DseError(f"objective {where} is neither a dse_runner Objective nor a function but {found!r:.80}")


GROUP = "dse_runner.objectives"


def registered() -> dict[str, Objective]:
    """Objectives installed packages register (entry-point group ``dse_runner.objectives``)."""
    return {name: _registered(entry) for name, entry in plugins.entries(GROUP).items()}


@functools.cache
def _registered(entry: EntryPoint) -> Objective:
    """One registered objective, loaded and wrapped once: a sweep looks its objectives up at every run."""
    return as_objective(plugins.loaded(entry, f"objective {entry.name!r}"), f"{entry.name!r} ({entry.value})")


def function(name: str) -> Objective:
    """A registered objective's name, or ``module:function`` for a user's own."""
    entry = plugins.entries(GROUP).get(name)
    if entry is not None:
        return _registered(entry)
    module_name, colon, function_name = name.partition(":")
    if not colon:
        available = ", ".join(registered()) or "none installed"
        raise DseError(
            f"unknown objective {name!r}: use {{signal, reduce}}, {{signal, recorded, metric}}, "
            f"a registered name ({available}) or an import path 'module:function'"
        )
    try:
        module = importlib.import_module(module_name)
    except ImportError as e:
        raise DseError(f"objective {name!r}: cannot import {module_name!r}: {e}") from None
    found = getattr(module, function_name, None)
    if not callable(found):
        raise DseError(f"objective {name!r}: {module_name} has no function {function_name!r}")
    return as_objective(found, repr(name))


def checked(name: str) -> Objective:
    """A named objective that can be called as the contract calls it, ``objective(trajectory, scenario)``:
    a function with another signature is an error now (when a space loads, when a run is prepared), not a
    TypeError in every task of a sweep."""
    found = function(name)
    call = found.function if isinstance(found, FunctionObjective) else found.__call__
    try:
        signature = inspect.signature(call)
    except (TypeError, ValueError):  # a builtin without one: it will speak for itself
        return found
    try:
        signature.bind(None, None)
    except TypeError as e:
        label = getattr(call, "__qualname__", name)
        raise DseError(
            f"objective {name!r}: {label}{signature} cannot be called as an objective is, with "
            f"(trajectory, scenario): {e}"
        ) from None
    return found


def is_vector(spec: ObjectiveSpec) -> bool:
    if isinstance(spec, Fit):
        return spec.metric == "residuals"
    return isinstance(spec, str) and function(spec).vector


def signals(spec: ObjectiveSpec) -> tuple[str, ...]:
    """The signals a declared objective reads: they must be recorded."""
    if isinstance(spec, Script):
        return tuple(spec.columns.values())
    return (spec.signal,) if isinstance(spec, (Reduce, Fit)) else ()


def load_scripts(
    objectives: Mapping[str, ObjectiveSpec], base: Path, source: str
) -> dict[str, ObjectiveSpec]:
    """The objectives with every script read (relative to ``base``), so that they travel to workers."""
    return {
        name: spec.loaded(base, f"{source}: objectives.{name}") if isinstance(spec, Script) else spec
        for name, spec in objectives.items()
    }


def compute(spec: ObjectiveSpec, trajectory, scenario) -> Any:
    if isinstance(spec, Reduce):
        return reduce(spec, trajectory, scenario)
    if isinstance(spec, Fit):
        return fit(spec, trajectory, scenario)
    return function(spec)(trajectory, scenario)


def evaluate(objectives: Mapping[str, ObjectiveSpec], trajectory, scenario) -> dict[str, float | list[float]]:
    """Every objective's value; a value that is not a finite number is an error naming the objective,
    so a NaN never reaches a result row with an ok status. Scripts run last, all in one folder,
    and see the other values in its objectives.json."""
    if not objectives:  # a plain run: nothing to score
        return {}
    results: dict[str, float | list[float]] = {}
    scripts = {name: spec for name, spec in objectives.items() if isinstance(spec, Script)}
    for name, spec in objectives.items():
        if name in scripts:
            continue
        value = compute(spec, trajectory, scenario)
        vector = is_vector(spec)
        try:
            number = np.asarray(value, dtype=float) if vector else float(value)
        except (TypeError, ValueError):
            raise DseError(f"objective {name!r} returned {value!r}, not a number") from None
        if not (np.all(np.isfinite(number)) if vector else math.isfinite(number)):
            raise DseError(
                f"objective {name!r} is not a finite number on scenario {scenario.name} ({value!r:.80})"
            )
        results[name] = number.tolist() if vector else number
    if scripts:
        results.update(run_scripts(scripts, trajectory, scenario.data, results))
    return {name: results[name] for name in objectives}
