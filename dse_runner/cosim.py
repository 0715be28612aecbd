"""The co-simulation master: fixed-step Jacobi over any number of FMUs.

Two stages, so that checking is done once and running is cheap:

* :func:`make_plan` resolves a multi-model against its FMUs' model
  descriptions: every ``instance.variable`` named in connections, values and
  the track is checked (unknown names get close matches suggested), and value
  references are looked up once.
* :func:`run` co-simulates a plan with given values from ``start`` to
  ``stop``. At each communication point every FMU's connected inputs are set
  from the outputs of the previous point, then every FMU steps. This is the
  same Jacobi scheme libcosim's fixed-step algorithm uses. The step loop only
  calls the FMUs through buffers prepared before it starts.
"""

from __future__ import annotations

import ctypes
import difflib
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from fmpy.fmi2 import fmi2True, fmi2ValueReference

from . import fmu as fmus
from .build import resolve_fmu
from .errors import DseError
from .multimodel import MultiModel, Value, split_ref

FMI_WARNING = 1


class CosimError(DseError):
    """An FMU failed or diverged during a co-simulation."""

    def __init__(self, message: str, instance: str | None = None):
        super().__init__(message)
        self.instance = instance  # the instance that failed, when one did


@dataclass(frozen=True)
class Variable:
    instance: str
    name: str
    vr: int
    type: str  # Real, Integer, Boolean, String
    causality: str
    low: float | None = None  # the declared min and max, if any
    high: float | None = None

    @property
    def ref(self) -> str:
        return f"{self.instance}.{self.name}"


@dataclass(frozen=True)
class Plan:
    """A multi-model whose every name has been checked against its FMUs."""

    multimodel: MultiModel
    fmu_paths: dict[str, Path]
    variables: dict[str, dict[str, Variable]]  # instance -> name -> variable, read once
    models: dict[str, str]  # instance -> model name, for messages
    outputs: dict[str, tuple[Variable, ...]]  # Real outputs per instance: recorded and connectable
    connections: tuple[tuple[Variable, Variable], ...]
    track: tuple[str, str] | None

    @property
    def recorded(self) -> tuple[str, ...]:
        return tuple(v.ref for vs in self.outputs.values() for v in vs)

    def variable(self, ref: str, purpose: str) -> Variable:
        return lookup(self.variables, self.models, ref, purpose)


@dataclass(frozen=True)
class Trajectory:
    """Outputs at the communication points: ``values[k, j]`` is ``names[j]`` at ``time[k]``."""

    time: np.ndarray
    names: tuple[str, ...]
    values: np.ndarray
    track: tuple[str, str] | None = None

    def column(self, name: str) -> np.ndarray:
        try:
            return self.values[:, self.names.index(name)]
        except ValueError:
            raise DseError(f"the trajectory has no column {name!r}; it has {', '.join(self.names)}") from None

    def xy(self) -> tuple[np.ndarray, np.ndarray]:
        """The simulated position compared with GPS fixes."""
        if self.track is None:
            raise DseError("the multi-model names no 'track' outputs (x, y) to compare with GPS")
        return self.column(self.track[0]), self.column(self.track[1])

    def to_csv(self, path: Path) -> None:
        header = ",".join(("time", *self.names))
        np.savetxt(path, np.column_stack([self.time, self.values]), delimiter=",", header=header,
                   comments="", fmt="%.10g")


def lookup(variables: dict[str, dict[str, Variable]], models: dict[str, str], ref: str,
           purpose: str) -> Variable:
    """Resolve ``instance.variable``; the error names it and suggests near names."""
    try:
        instance, name = split_ref(ref)
    except ValueError as e:
        raise DseError(f"{purpose}: {e}") from None
    if instance not in variables:
        raise DseError(f"{purpose}: {ref!r} names instance {instance!r}, but the multi-model has "
                       f"{', '.join(sorted(variables))}{_did_you_mean(instance, variables)}")
    variable = variables[instance].get(name)
    if variable is None:
        raise DseError(f"{purpose}: unknown variable {ref!r}: instance {instance!r} ({models[instance]}) "
                       f"has no variable {name!r}{_did_you_mean(name, variables[instance])}")
    return variable


def _did_you_mean(name: str, options) -> str:
    close = difflib.get_close_matches(name, list(options), n=3)
    return f" (did you mean {', '.join(close)}?)" if close else ""


def make_plan(multimodel: MultiModel) -> Plan:
    """Build FMUs if needed and check every name the multi-model uses."""
    fmu_paths = {name: resolve_fmu(multimodel.fmu_path(name)) for name in multimodel.fmus}
    descriptions = {name: fmus.describe(path) for name, path in fmu_paths.items()}
    variables = {name: {v.name: _variable(name, v) for v in d.modelVariables} for name, d in descriptions.items()}
    models = {name: d.modelName for name, d in descriptions.items()}
    outputs = {name: tuple(v for v in vs.values() if v.causality == "output" and v.type == "Real")
               for name, vs in variables.items()}
    connections, fed = [], {}
    for source_ref, target_refs in multimodel.connections.items():
        source = lookup(variables, models, source_ref, "connection")
        if source.causality != "output" or source.type != "Real":
            raise DseError(f"connection: {source_ref!r} must be a Real output (it is a "
                           f"{source.type} {source.causality})")
        for target_ref in target_refs:
            target = lookup(variables, models, target_ref, "connection")
            if target.causality != "input" or target.type != "Real":
                raise DseError(f"connection {source_ref} -> {target_ref}: the target must be a Real "
                               f"input (it is a {target.type} {target.causality})")
            if target_ref in fed:
                raise DseError(f"connection: input {target_ref!r} is fed by both {fed[target_ref]} "
                               f"and {source_ref}")
            fed[target_ref] = source_ref
            connections.append((source, target))
    for ref in multimodel.scenario:
        check_settable(lookup(variables, models, ref, "scenario"))
    for ref, value in multimodel.parameters.items():
        check_value(lookup(variables, models, ref, "parameters"), value)
    track = _track(multimodel, variables, models, outputs)
    return Plan(multimodel, fmu_paths, variables, models, outputs, tuple(connections), track)


def _variable(instance: str, v) -> Variable:
    """Our record of an FMPy ScalarVariable: what setting and checking a value needs."""
    declared = v.declaredType

    def bound(name: str) -> float | None:
        text = getattr(v, name, None) or (getattr(declared, name, None) if declared is not None else None)
        return float(text) if text not in (None, "") else None

    return Variable(instance, v.name, v.valueReference, v.type, v.causality, bound("min"), bound("max"))


def _track(multimodel: MultiModel, variables, models, outputs) -> tuple[str, str] | None:
    """The declared track outputs, or the only instance with Real outputs x and y."""
    if multimodel.track is not None:
        refs = (multimodel.track.x, multimodel.track.y)
        for ref in refs:
            if lookup(variables, models, ref, "track").causality != "output":
                raise DseError(f"track: {ref!r} is not an output")
        return refs
    candidates = [name for name, vs in outputs.items() if {"x", "y"} <= {v.name for v in vs}]
    return (f"{candidates[0]}.x", f"{candidates[0]}.y") if len(candidates) == 1 else None


def check_settable(variable: Variable) -> None:
    if variable.causality not in ("parameter", "input"):
        raise DseError(f"{variable.ref!r} is a {variable.causality}, not a parameter or input: "
                       "it cannot be set")


def check_value(variable: Variable, value: Value) -> Value:
    """``value`` as the FMU takes it, checked: settable, of the variable's type, within its declared
    min and max. Errors name the variable, the value and the rule."""
    check_settable(variable)
    value = _coerce(variable, value)
    if variable.type in ("Real", "Integer"):
        if variable.low is not None and value < variable.low:
            raise DseError(f"{variable.ref} = {value:g} is below its declared min {variable.low:g}")
        if variable.high is not None and value > variable.high:
            raise DseError(f"{variable.ref} = {value:g} is above its declared max {variable.high:g}")
    return value


def _coerce(variable: Variable, value: Value) -> Value:
    """Check a value against the variable's type, so the FMU never sees a wrong one."""
    kind = variable.type
    if kind == "String":
        return str(value)
    if isinstance(value, str):
        try:
            value = float(value) if kind == "Real" else int(value)
        except ValueError:
            raise DseError(f"{variable.ref}: {value!r} is not a valid {kind}") from None
    if kind == "Real":
        if not math.isfinite(float(value)):
            raise DseError(f"{variable.ref}: {value!r} is not a finite number")
        return float(value)
    if kind == "Boolean":
        return bool(value)
    if not math.isfinite(float(value)) or float(value) != int(value):
        raise DseError(f"{variable.ref}: {value!r} is not an Integer")
    return int(value)


def _set_values(instance: fmus.Instance, values: list[tuple[Variable, Value]]) -> None:
    setters = {"Real": instance.slave.setReal, "Integer": instance.slave.setInteger,
               "Boolean": instance.slave.setBoolean, "String": instance.slave.setString}
    for variable, value in values:
        setters[variable.type]([variable.vr], [value])


class _Stepper:
    """One instance's buffers for the step loop, prepared once per run."""

    def __init__(self, instance: fmus.Instance, offset: int, n_outputs: int, signals: np.ndarray,
                 inputs: list[tuple[int, int]]):
        slave = instance.slave
        self.instance = instance
        self.component = slave.component
        self.do_step = slave.dll.fmi2DoStep  # FMPy set their ctypes signatures
        self.get_real = slave.dll.fmi2GetReal
        self.set_real = slave.dll.fmi2SetReal
        self.n_out = n_outputs
        self.out_vr = (fmi2ValueReference * max(n_outputs, 1))()
        address = signals.ctypes.data + offset * signals.itemsize
        self.out_values = (ctypes.c_double * max(n_outputs, 1)).from_address(address)
        self.n_in = len(inputs)
        self.in_vr = (fmi2ValueReference * max(self.n_in, 1))(*[vr for vr, _ in inputs])
        self.in_values = (ctypes.c_double * max(self.n_in, 1))()
        self.in_view = np.frombuffer(self.in_values, dtype=np.float64)[: self.n_in]
        self.gather = np.array([index for _, index in inputs], dtype=np.intp)

    def fail(self, call: str, t: float) -> CosimError:
        return CosimError(self.instance.explain(f"{call} failed at t={t:.6g}"), self.instance.name)


def run(plan: Plan, values: dict[str, Value], start: float, stop: float, step: float,
        timeout: float | None = None) -> Trajectory:
    """Co-simulate ``plan`` from ``start`` to ``stop`` with communication step ``step``.

    ``timeout`` bounds the wall time of the step loop in seconds; it is checked
    between steps, so it stops a slow simulation, not one hung inside an FMU."""
    if not (stop > start):
        raise DseError(f"stop time {stop} must be after start time {start}")
    if not (step > 0 and math.isfinite(step)):
        raise DseError(f"communication step must be > 0, got {step}")
    settings = _resolve_values(plan, values)
    n_steps = max(1, math.ceil((stop - start) / step - 1e-9))
    times = start + step * np.arange(n_steps + 1)
    times[-1] = stop

    names = plan.recorded
    signals = np.zeros(len(names))
    record = np.empty((n_steps + 1, len(names)))
    index = {ref: i for i, ref in enumerate(names)}
    feeds: dict[str, list[tuple[int, int]]] = {name: [] for name in plan.fmu_paths}
    for source, target in plan.connections:
        feeds[target.instance].append((target.vr, index[source.ref]))

    instances = {name: fmus.acquire(name, fmus.load(path)) for name, path in plan.fmu_paths.items()}
    steppers, offset = [], 0
    for name, instance in instances.items():
        stepper = _Stepper(instance, offset, len(plan.outputs[name]), signals, feeds[name])
        for i, variable in enumerate(plan.outputs[name]):
            stepper.out_vr[i] = variable.vr
        steppers.append(stepper)
        offset += len(plan.outputs[name])

    current = None
    try:
        for name, instance in instances.items():
            current = instance
            instance.slave.setupExperiment(startTime=start)
            _set_values(instance, settings.get(name, []))
            instance.slave.enterInitializationMode()
        _exchange(steppers, signals, start, inputs=True)
        for instance in instances.values():
            current = instance
            instance.slave.exitInitializationMode()
        current = None
        _exchange(steppers, signals, start, inputs=False)
        record[0] = signals
        deadline = time.perf_counter() + timeout if timeout else math.inf
        _step_loop(steppers, times, signals, record, deadline)
        for instance in instances.values():
            current = instance
            instance.slave.terminate()
    except CosimError as e:
        if e.instance is not None:
            fmus.discard(instances[e.instance])
        raise
    except Exception as e:  # FMPy's FMICallException from a set-up call
        if current is None:
            raise
        message = current.explain(str(e).rstrip("."))
        fmus.discard(current)
        raise CosimError(message, current.name) from None
    _check_finite(names, times, record)
    return Trajectory(times, names, record, plan.track)


def _resolve_values(plan: Plan, values: dict[str, Value]) -> dict[str, list[tuple[Variable, Value]]]:
    """Group values by instance, each checked against its variable's type."""
    grouped: dict[str, list[tuple[Variable, Value]]] = {}
    for ref, value in values.items():
        variable = plan.variable(ref, "setting")
        grouped.setdefault(variable.instance, []).append((variable, check_value(variable, value)))
    return grouped


def _exchange(steppers: list[_Stepper], signals: np.ndarray, t: float, inputs: bool) -> None:
    """Outside the loop: read every output, and with ``inputs`` also feed the connections."""
    for s in steppers:
        if s.n_out and s.get_real(s.component, s.out_vr, s.n_out, s.out_values) > FMI_WARNING:
            raise s.fail("fmi2GetReal", t)
    if inputs:
        for s in steppers:
            if s.n_in:
                np.take(signals, s.gather, out=s.in_view)
                if s.set_real(s.component, s.in_vr, s.n_in, s.in_values) > FMI_WARNING:
                    raise s.fail("fmi2SetReal", t)


def _step_loop(steppers: list[_Stepper], times: np.ndarray, signals: np.ndarray,
               record: np.ndarray, deadline: float) -> None:
    """The hot loop: no buffer is created here, only FMI calls through prepared ones."""
    feeding = [s for s in steppers if s.n_in]
    reading = [s for s in steppers if s.n_out]
    take, clock = np.take, time.perf_counter
    for k, (t, t_next) in enumerate(zip(times[:-1].tolist(), times[1:].tolist()), start=1):
        h = t_next - t
        if not k & 63 and clock() > deadline:
            raise CosimError(f"timeout: the simulation was stopped at t={t:.6g} of {times[-1]:.6g} s")
        for s in feeding:
            take(signals, s.gather, out=s.in_view)
            if s.set_real(s.component, s.in_vr, s.n_in, s.in_values) > FMI_WARNING:
                raise s.fail("fmi2SetReal", t)
        for s in steppers:
            if s.do_step(s.component, t, h, fmi2True) > FMI_WARNING:
                raise s.fail("fmi2DoStep", t)
        for s in reading:
            if s.get_real(s.component, s.out_vr, s.n_out, s.out_values) > FMI_WARNING:
                raise s.fail("fmi2GetReal", t_next)
        record[k] = signals


def _check_finite(names: tuple[str, ...], times: np.ndarray, record: np.ndarray) -> None:
    bad = ~np.isfinite(record)
    if bad.any():
        row, column = np.argwhere(bad)[0]
        raise CosimError(f"{names[column]} became non-finite at t={times[row]:.6g}: the "
                         "simulation diverged")
