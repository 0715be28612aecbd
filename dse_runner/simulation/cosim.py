"""The co-simulation master: fixed-step Jacobi over any number of FMUs of any FMI version and interface.

Two stages, so that checking is done once and running is cheap:

* plan.py's ``make_plan`` resolves a multi-model against its FMUs' model
  descriptions once: every name checked, every connection's conversion fixed.
* :func:`run` co-simulates a plan with given values (and input signals)
  from ``start`` to ``stop``. At each communication point every FMU's
  connected inputs are set from the outputs of the previous point, then
  every FMU steps. This is the same Jacobi scheme libcosim's fixed-step
  algorithm uses. The step loop only calls the FMUs through buffers prepared
  before it starts; a connection that needs no conversion costs none.

Every output of a numeric type (and every other variable an objective asks
for) is recorded as a float64 column; booleans as 0/1. String outputs are
recorded as text.

An FMU that asks to end the run early (steppers.py's ``asked_to_stop``) ends it where it says, as FMPy's
``simulate_fmu`` does: every output is read once more there, the FMUs are terminated, and the trajectory
holds the run up to that time with its :class:`~.trajectory.Stop`.
"""

from __future__ import annotations

import ctypes
import functools
import math
import os
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from fmpy.fmi1 import FMICallException

from ..errors import DseError
from . import fmu as fmus
from . import isolation, native, native_me
from .plan import Plan
from .steppers import FMI_WARNING, Stepper, stepper
from .trajectory import CosimError, Series, Stop, Trajectory
from .variables import (
    Conversion,
    Value,
    Variable,
    check_value,
    with_article,
)

# ---- running -------------------------------------------------------------------------------------


@dataclass
class _Read:
    """One group of outputs of one C type, read after each step into ``signals``."""

    call: Callable[..., int]
    args: tuple
    name: str
    copy: Callable[[], Any] | None  # moves values into ``signals`` when the buffer is not a view of it
    ctype: Any = None
    columns: np.ndarray | None = None  # where ``copy`` moves them (native.py does the same in C)


@dataclass
class _Feed:
    """One group of inputs of one C type and conversion, written before each step."""

    call: Callable[..., int]
    args: tuple
    name: str
    fill: Callable[[], Any]  # gathers (and converts) the sources' values into the buffer
    ctype: Any = None
    gather: np.ndarray | None = None  # which signals ``fill`` gathers (native.py does the same in C)
    conversion: Conversion = field(default_factory=Conversion)
    targets: tuple[Variable, ...] = ()


@dataclass
class _Texts:
    """String outputs of one instance, and the string inputs they feed."""

    call: Callable[..., int]
    args: tuple
    buffer: Any
    names: list[str]
    feeds: list[tuple[Stepper, Variable, int]]  # target, its variable, index into ``buffer``


@dataclass
class _Unit:
    stepper: Stepper
    reads: list[_Read]
    feeds: list[_Feed]
    texts: _Texts | None = None

    def fail(self, call: str, t: float) -> CosimError:
        instance = self.stepper.instance
        return CosimError(instance.explain(f"{call} failed at t={t:.6g}"), instance.name)


def _buffer_view(buffer, ctype) -> np.ndarray:
    return (
        np.ctypeslib.as_array(buffer) if ctype is not ctypes.c_bool else np.frombuffer(buffer, dtype=np.bool_)
    )


def _reads(step: Stepper, variables: tuple[Variable, ...], signals: np.ndarray, offset: int) -> list[_Read]:
    """Output groups by C type; float64 ones are read straight into ``signals``."""
    reads = []
    for group in _by_access(step, variables):
        access, members = group
        n = len(members)
        vrs = (ctypes.c_uint32 * n)(*[v.vr for v in members])
        columns = [offset + variables.index(v) for v in members]
        contiguous = columns == list(range(columns[0], columns[0] + n))
        if access.ctype is ctypes.c_double and contiguous:
            buffer = (ctypes.c_double * n).from_address(signals.ctypes.data + columns[0] * signals.itemsize)
            copy, where = None, None
        else:
            buffer = (access.ctype * n)()
            view, where = _buffer_view(buffer, access.ctype), np.array(columns, dtype=np.int64)
            copy = functools.partial(signals.__setitem__, where, view)
        reads.append(
            _Read(access.get, step.args(access, vrs, n, buffer), access.name, copy, access.ctype, where)
        )
    return reads


def _by_access(step: Stepper, variables: Iterable[Variable]) -> list[tuple[Any, list[Variable]]]:
    groups: dict[str, tuple[Any, list[Variable]]] = {}
    for v in variables:
        access = step.access(v)
        groups.setdefault(access.name, (access, []))[1].append(v)
    return list(groups.values())


def _feeds(step: Stepper, links: list[tuple[Variable, int, Conversion]], signals: np.ndarray) -> list[_Feed]:
    """Input groups by C type and conversion; a plain float64 group is one ndarray.take into the buffer."""
    groups: dict[tuple, list[tuple[Variable, int]]] = {}
    for target, index, conv in links:
        groups.setdefault((step.access(target).name, conv), []).append((target, index))
    feeds = []
    for (_, conv), members in groups.items():
        access = step.access(members[0][0])
        n = len(members)
        vrs = (ctypes.c_uint32 * n)(*[t.vr for t, _ in members])
        buffer = (access.ctype * n)()
        view, gather = _buffer_view(buffer, access.ctype), np.array([i for _, i in members], dtype=np.int64)
        targets = tuple(t for t, _ in members)
        feeds.append(
            _Feed(
                access.set,
                step.args(access, vrs, n, buffer),
                access.name.replace("Get", "Set"),
                _filler(signals, gather, view, conv, list(targets)),
                access.ctype,
                gather,
                conv,
                targets,
            )
        )
    return feeds


class _Unfit(Exception):
    """A rounded value its integer target's C type cannot hold; the caller adds the time."""


def _filler(
    signals: np.ndarray, gather: np.ndarray, view: np.ndarray, conv: Conversion, targets: list[Variable]
) -> Callable[[], Any]:
    """The cheapest way to move the sources' values into the buffer with the conversion asked for."""
    if conv.kind == "round":
        return _rounder(signals, gather, view, targets)
    if conv.kind == "threshold":
        return lambda: view.__setitem__(slice(None), signals[gather] > conv.threshold)
    if view.dtype == np.float64:
        return functools.partial(signals.take, gather, out=view)  # ndarray.take: no Python frame per call
    return lambda: view.__setitem__(slice(None), signals[gather])


def _rounder(
    signals: np.ndarray, gather: np.ndarray, view: np.ndarray, targets: list[Variable]
) -> Callable[[], None]:
    """Round into an integer buffer, refusing what its C type cannot hold: numpy would wrap it (or
    NaN) into a wrong value silently."""
    limits = np.iinfo(view.dtype)
    low, above = float(limits.min), limits.max + 1.0  # not max: Int64's rounds up to 2^63 as a float

    def fill() -> None:
        rounded = np.rint(signals[gather])
        fits = (rounded >= low) & (rounded < above)
        if not fits.all():
            j = int(np.argmin(fits))
            raise _Unfit(unfit_message(targets[j], signals[gather[j]]))
        view[:] = rounded

    return fill


def unfit_message(target: Variable, value: float) -> str:
    return f"{target.ref} is fed {value:g}, which rounded does not fit {with_article(target.type)}"


def run(
    plan: Plan,
    values: Mapping[str, Value],
    start: float,
    stop: float,
    step: float,
    timeout: float | None = None,
    inputs: Mapping[str, Series] | None = None,
    loop: str | None = None,
) -> Trajectory:
    """Co-simulate ``plan`` from ``start`` to ``stop`` with communication step ``step``.

    ``values`` are set before initialization; ``inputs`` are signals fed to
    input variables at every communication point. ``timeout`` bounds the wall
    time of the step loop in seconds; it is checked between steps, so it stops
    a slow simulation, not one hung inside an FMU. ``loop``: "native" (the C
    loop, native.py; the default) or "python" (the reference); default: the
    environment's ``DSE_RUNNER_LOOP``, else native. Running the same experiment
    many times, :func:`prepare` it once and call :meth:`Runner.run`."""
    return prepare(plan, start, stop, step, inputs).run(values, timeout, loop)


def prepare(
    plan: Plan, start: float, stop: float, step: float, inputs: Mapping[str, Series] | None = None
) -> Runner:
    """``plan`` on one time grid with its input signals sampled and checked: ready to run with any values."""
    times = _time_grid(start, stop, step)
    series = _resolve_inputs(plan, inputs or {}, times)
    external = np.column_stack(list(series.values())) if series else None
    return Runner(plan, times, series, external, _step_sizes(start, stop, step, plan.multimodel.step_sizes))


@dataclass(frozen=True)
class Runner:
    """One experiment of a plan (time grid and input signals), run again and again with new values:
    what a sweep does, so everything that does not depend on the values is done once, in :func:`prepare`."""

    plan: Plan
    times: np.ndarray
    series: dict[str, np.ndarray]  # input signals at the communication points
    external: np.ndarray | None  # the same, one column each, as the loops read them
    steps: np.ndarray  # the communication step that reaches each point (0 at the first): _step_sizes
    # derivative terms (derivative_terms.py) per model-exchange instance: term -> coefficient
    terms: Mapping[str, Mapping] = field(default_factory=dict)

    def with_inputs(self, changed: Mapping[str, np.ndarray]) -> Runner:
        """The same runner feeding some input signals changed (input effects, signal_effects.py)."""
        if not changed:
            return self
        series = {**self.series, **changed}
        return replace(self, series=series, external=np.column_stack(list(series.values())))

    def with_terms(self, terms: Mapping[str, Mapping]) -> Runner:
        """The same runner adding derivative terms to model-exchange instances (instance -> term ->
        coefficient); derivative_terms.check has checked each against its instance."""
        return replace(self, terms={**self.terms, **terms}) if terms else self

    def check(self, values: Mapping[str, Value]) -> None:
        """Every value named, settable and of its variable's type: an error names it before anything runs."""
        _resolve_values(self.plan, values)

    def run(
        self,
        values: Mapping[str, Value],
        timeout: float | None = None,
        loop: str | None = None,
        fresh_process: bool = False,
    ) -> Trajectory:
        """Co-simulate with ``values`` set before initialization (see :func:`run`): here, its instances reused
        through reset, or with ``fresh_process`` in a process of its own (an instance that cannot be trusted
        with a second run in one: lifecycle.py decides, and the caller keeps its verdict)."""
        if not fresh_process or isolation.in_child():  # reused instances, or this process is the fresh one
            return _run_here(self, values, timeout, loop)
        plan = self.plan
        fmus_used = [(path, plan.interfaces[name]) for name, path in plan.fmu_paths.items()]
        for path, interface in fmus_used:
            fmus.load(path, interface)  # extracted, and warned about, once in this process
        kill_after = timeout + isolation.KILL_GRACE if timeout else None  # hung inside an FMU call
        return isolation.run(_run_here, self, values, timeout, loop, preload=fmus_used, kill_after=kill_after)


def _run_here(
    runner: Runner, values: Mapping[str, Value], timeout: float | None, loop: str | None
) -> Trajectory:
    """One run in this process, its instances reused through reset; in the order FMPy and the standard
    call an FMU: set-up with the times, values, initialization, steps, termination."""
    plan, times, external = runner.plan, runner.times, runner.external
    settings = _resolve_values(plan, values)
    names = plan.recorded
    instances = {
        name: fmus.acquire(name, fmus.load(path, plan.interfaces[name]))
        for name, path in plan.fmu_paths.items()
    }
    use_native = _native(loop) and _integrable(plan, instances)
    prepared = _prepare(plan, instances, runner.series, use_native, runner.terms)
    units, signals, program = prepared.units, prepared.signals, prepared.program
    texts = {v.ref: [] for vs in plan.texts.values() for v in vs}
    record = np.empty((len(times), len(names)))
    start, stop = float(times[0]), float(times[-1])
    current = None
    try:
        native_setup = program is not None and program.sets_up
        if not (native_setup and native.values_of(program, units, settings)):  # else the C call does this
            for unit in units:
                current = unit
                unit.stepper.setup(start, stop)
                unit.stepper.set_values(settings.get(unit.stepper.name, ()))
        current = None
        if native_setup:  # the C call (sets up and sets the values,) initialises, runs and ends the units
            outcome = native.step_loop(program, times, runner.steps, external, record, texts, timeout)
            stopped = _where_stopped(outcome, program, units, times, names, record, texts)
            if stopped is None:
                return Trajectory(times, names, record, texts)
        else:
            for unit in units:
                current = unit
                unit.stepper.enter_initialization(start, stop)
            _exchange(units, signals, external, 0, texts, start, feed=True)
            for unit in units:
                current = unit
                unit.stepper.exit_initialization()
            current = None
            _exchange(units, signals, external, 0, texts, start, feed=False)
            record[0] = signals[: len(names)]
            if program is not None:
                outcome = native.step_loop(program, times, runner.steps, external, record, texts, timeout)
                stopped = _where_stopped(outcome, program, units, times, names, record, texts)
            else:
                deadline = time.perf_counter() + timeout if timeout else math.inf
                stopped = _step_loop(units, times, runner.steps, signals, external, record, texts, deadline)
        if stopped is not None:  # as FMPy records it: every output once more, where the run stopped
            _read_row(units, signals, record, texts, *stopped)
        for unit in units:
            current = unit
            unit.stepper.terminate()
    except CosimError as e:
        if e.instance is not None:
            fmus.discard(instances[e.instance])
        raise
    except Exception as e:  # FMPy's FMICallException from a set-up call, or the integrator's error
        if current is None:
            raise
        message = current.stepper.instance.explain(str(e).rstrip("."))
        fmus.discard(current.stepper.instance)
        raise CosimError(message, current.stepper.name) from None
    if stopped is not None:
        trajectory = _up_to(Trajectory(times, names, record, texts), *stopped)
        _check_finite(names, trajectory.time, trajectory.values)
        return trajectory
    if program is None:  # the C loop checked every point
        _check_finite(names, times, record)
    return Trajectory(times, names, record, texts)


def _read_row(
    units: list[_Unit],
    signals: np.ndarray,
    record: np.ndarray,
    texts: dict[str, list[str]],
    k: int,
    stop: Stop,
) -> None:
    """Every output read into row ``k`` of ``record`` (and ``texts``), where an FMU asked to stop."""
    for unit in units:
        _read(unit, stop.time, texts)
    record[k] = signals[: record.shape[1]]


def _up_to(trajectory: Trajectory, k: int, stop: Stop) -> Trajectory:
    """The run up to where an FMU asked to stop, on the way to point ``k``: points 0..k-1, then the values
    read at the stop, at its time (which may lie between points, as FMI 2's fmi2LastSuccessfulTime
    does), as FMPy's simulate_fmu keeps them. A stop that got no further than point k-1 ends there: its
    row is not repeated."""
    times = trajectory.time
    at = min(max(stop.time, float(times[k - 1])), float(times[k]))
    n = k + 1 if at > times[k - 1] else k
    kept = np.array(times[:n])
    if n > k:
        kept[k] = at
    texts = {name: values[:n] for name, values in trajectory.texts.items()}
    return Trajectory(
        kept, trajectory.names, trajectory.values[:n], texts, Stop(stop.instance, float(kept[-1]))
    )


LOOPS = ("native", "python")


def _native(loop: str | None) -> bool:
    """Whether the C loop may run: asked for (or by default) and built."""
    loop = loop or os.environ.get("DSE_RUNNER_LOOP") or "native"
    if loop not in LOOPS:
        raise DseError(f"loop {loop!r}: expected one of {', '.join(LOOPS)} (DSE_RUNNER_LOOP)")
    return loop == "native" and native.library() is not None


def _integrable(plan: Plan, instances: dict[str, fmus.Instance]) -> bool:
    """Whether C integrates every model-exchange instance exactly as FMPy's solvers would (native_me.py):
    a plan with one it cannot runs in the Python loop."""
    settings = plan.multimodel.settings
    return all(
        native_me.eligible(instance.fmu.description, settings(name).solver if settings(name) else "cvode")
        for name, instance in instances.items()
        if plan.interfaces[name] == "me"
    )


@dataclass
class _Prepared:
    """A plan's units laid out for one set of instances, and the signals they read and write."""

    plan: Plan
    instances: tuple[fmus.Instance, ...]
    units: list[_Unit]
    signals: np.ndarray
    program: native.Program | None  # the C loop's view of the units; None: the Python loop runs


_PREPARED: dict[tuple, _Prepared] = {}
KEEP_PREPARED = 16  # plans x instance sets a process keeps laid out


def _prepare(
    plan: Plan,
    instances: dict[str, fmus.Instance],
    series: dict[str, np.ndarray],
    use_native: bool,
    terms: Mapping[str, Mapping] | None = None,
) -> _Prepared:
    """The units of this plan and these instances: laid out once for the native loop and reused while
    the instances are (a sweep runs one plan thousands of times), so a cheap run costs little Python. With
    derivative terms, the same terms (a fit's runs) reuse the layout with this run's coefficients."""
    chosen = tuple(instances.values())
    terms = terms or {}
    shape = tuple((name, tuple(t.name for t in ts)) for name, ts in terms.items())
    key = (id(plan), tuple(map(id, chosen)), tuple(series), use_native, shape)
    kept = _PREPARED.get(key)
    if kept is not None and kept.plan is plan and kept.instances == chosen:  # instances compare by identity
        kept.signals.fill(0.0)
        for unit in kept.units:
            if unit.stepper.name in terms:
                unit.stepper.use_terms(terms[unit.stepper.name])
        return kept
    names = plan.recorded
    sources = {ref: i for i, ref in enumerate(names)}
    sources.update({ref: len(names) + j for j, ref in enumerate(series)})
    signals = np.zeros(len(names) + len(series))
    units = _units(plan, instances, signals, sources, series, terms, use_native)
    prepared = _Prepared(
        plan, chosen, units, signals, native.Program(units, signals, len(names)) if use_native else None
    )
    if (
        use_native
    ):  # the Python loop's model-exchange steppers hold FMPy's solver: those are made anew each run
        while len(_PREPARED) >= KEEP_PREPARED:
            _PREPARED.pop(next(iter(_PREPARED)))
        _PREPARED[key] = prepared
    return prepared


def _where_stopped(
    outcome,
    program,
    units: list[_Unit],
    times: np.ndarray,
    names: tuple[str, ...],
    record: np.ndarray,
    texts: dict[str, list[str]],
) -> tuple[int, Stop] | None:
    """Where the C loop stopped early: an FMU that asked to stop (the point it was stepping to, and the
    stop), as the Python loop returns it; else the error the Python loop raises there. None: it ran to
    the end."""
    code, k, t = outcome.code, outcome.k, outcome.t
    if code == native.TERMINATE:
        return k, Stop(units[outcome.unit].stepper.name, t)
    if code == native.STEP_FAILED:
        step = units[outcome.unit].stepper
        at = step.asked_to_stop(outcome.element, t, float(times[k]))
        if at is not None:
            return k, Stop(step.name, at)
    if code == native.TIMEOUT:
        raise CosimError(f"timeout: the simulation was stopped at t={t:.6g} of {times[-1]:.6g} s")
    if code == native.DIVERGED:
        _check_finite(names, times[: k + 1], record[: k + 1])
    if code in (native.FEED_FAILED, native.UNFIT):
        i, feed = program.feeds[outcome.group]
        if code == native.UNFIT:
            raise CosimError(f"{unfit_message(feed.targets[outcome.element], outcome.value)} at t={t:.6g}")
        raise units[i].fail(feed.name, t)
    if code == native.READ_FAILED:
        i, read = program.reads[outcome.group]
        raise units[i].fail(read.name, t)
    if code == native.STEP_FAILED:
        step = units[outcome.unit].stepper
        raise step.step_failure() or units[outcome.unit].fail(step.step_name, t)
    if code == native.TEXT_READ_FAILED:
        raise units[outcome.unit].fail("getString", t)
    if code == native.TEXT_FEED_FAILED:
        _, target, variable = program.text_feeds[outcome.group]
        value = texts[program.text_source_names[outcome.group]][-1].encode("utf-8")
        failed = f"{target.access(variable).name.replace('Get', 'Set')} of {variable.name} = {value!r} failed"
        raise CosimError(target.instance.explain(f"{failed} at t={t:.6g}"), target.name)
    if code == native.VALUE_FAILED:
        unit, members = program.given.failed(outcome.group)
        step = units[unit].stepper
        setter = step.access(members[0]).name.replace("Get", "Set")
        given = program.given.views[outcome.group][2]
        what = ", ".join(f"{v.name} = {given[j].item()!r}" for j, v in enumerate(members))
        raise CosimError(step.instance.explain(f"{setter} of {what} failed"), step.name)
    if code == native.LIFECYCLE_FAILED:
        step = units[outcome.unit].stepper
        call = native.LIFECYCLE[step.fmi_version][outcome.group]
        failed = str(FMICallException(function=call, status=outcome.element)).rstrip(".")  # as FMPy words it
        raise CosimError(step.instance.explain(failed), step.name)
    if code != native.DONE:
        raise CosimError(f"the native loop ran out of memory at t={t:.6g}")
    return None


@functools.lru_cache(maxsize=64)
def _time_grid(start: float, stop: float, step: float) -> np.ndarray:
    """The communication points, made once per (start, stop, step) and read-only: trajectories share it."""
    if not (math.isfinite(start) and math.isfinite(stop) and stop > start):
        raise DseError(f"stop time {stop} must be after start time {start}")
    if not (step > 0 and math.isfinite(step)):
        raise DseError(f"communication step must be > 0, got {step}")
    n_steps = max(1, math.ceil((stop - start) / step - 1e-9))
    times = start + step * np.arange(n_steps + 1)
    times[-1] = stop
    times.flags.writeable = False
    return times


@functools.lru_cache(maxsize=64)
def _step_sizes(start: float, stop: float, step: float, told: str = "difference") -> np.ndarray:
    """The step size an FMU is told on its way to each point of ``_time_grid`` (0 at the first), as the
    multi-model's ``step_sizes`` says: the difference of the two points (FMPy's), or the nominal ``step``
    (INTO-CPS's master's), which rounding makes differ in the last bit (0.4 - 0.30000000000000004 is
    0.09999999999999998). A shorter last step to the stop time is the difference either way."""
    times = _time_grid(start, stop, step)
    steps = np.diff(times, prepend=times[0])
    if told == "nominal":
        steps[1:-1] = step
        if math.isclose(steps[-1], step, rel_tol=1e-9):
            steps[-1] = step
    steps.flags.writeable = False
    return steps


def _units(
    plan: Plan,
    instances: dict[str, fmus.Instance],
    signals: np.ndarray,
    sources: dict[str, int],
    series: dict[str, np.ndarray],
    terms: Mapping[str, Mapping],
    use_native: bool = False,
) -> list[_Unit]:
    """Every instance's stepper with its prepared reads and feeds (and, model exchange, its derivative terms,
    or with ``use_native`` its integrator in C)."""
    steppers = {
        name: stepper(instance, plan.multimodel.settings(name), terms.get(name), use_native)
        for name, instance in instances.items()
    }
    feeds: dict[str, list[tuple[Variable, int, Conversion]]] = {name: [] for name in instances}
    for link in plan.links:
        if link.source.family != "string":
            feeds[link.target.instance].append((link.target, sources[link.source.ref], link.conversion))
    for ref in series:
        target = plan.variable(ref, "scenario input")
        feeds[target.instance].append((target, sources[ref], Conversion()))
    units, offset = [], 0
    for name, step in steppers.items():
        reads = _reads(step, plan.outputs[name], signals, offset) if plan.outputs[name] else []
        units.append(_Unit(step, reads, _feeds(step, feeds[name], signals)))
        offset += len(plan.outputs[name])
    for unit in units:
        unit.texts = _text_unit(unit.stepper, plan, steppers)
    return units


def _text_unit(step: Stepper, plan: Plan, steppers: dict[str, Stepper]) -> _Texts | None:
    outputs = plan.texts[step.name]
    if not outputs:
        return None
    access = step.access(outputs[0])
    n = len(outputs)
    vrs = (ctypes.c_uint32 * n)(*[v.vr for v in outputs])
    buffer = (ctypes.c_char_p * n)()
    feeds = [
        (steppers[link.target.instance], link.target, outputs.index(link.source))
        for link in plan.links
        if link.source in outputs
    ]
    return _Texts(access.get, step.args(access, vrs, n, buffer), buffer, [v.ref for v in outputs], feeds)


def _exchange(
    units: list[_Unit],
    signals: np.ndarray,
    external: np.ndarray | None,
    k: int,
    texts: dict[str, list[str]],
    t: float,
    feed: bool,
) -> None:
    """Outside the loop: read every output, and with ``feed`` also set every connected input."""
    for unit in units:
        _read(unit, t, texts if not feed else None)
    if feed:
        _feed_all(units, signals, external, k, t)


def _read(unit: _Unit, t: float, texts: dict[str, list[str]] | None) -> None:
    for read in unit.reads:
        if read.call(*read.args) > FMI_WARNING:
            raise unit.fail(read.name, t)
        if read.copy is not None:
            read.copy()
    if unit.texts is not None:
        if unit.texts.call(*unit.texts.args) > FMI_WARNING:
            raise unit.fail("getString", t)
        if texts is not None:
            for name, raw in zip(unit.texts.names, unit.texts.buffer):
                texts[name].append((raw or b"").decode("utf-8", "replace"))


def _feed(unit: _Unit, t: float) -> None:
    for feed in unit.feeds:
        try:
            feed.fill()
        except _Unfit as e:
            raise CosimError(f"{e} at t={t:.6g}") from None
        if feed.call(*feed.args) > FMI_WARNING:
            raise unit.fail(feed.name, t)


def _feed_texts(texts: _Texts, t: float) -> None:
    """String connections: the source's last value, copied before the target steps."""
    for target, variable, index in texts.feeds:
        try:
            target.set_values([(variable, (texts.buffer[index] or b"").decode("utf-8", "replace"))])
        except RuntimeError as e:
            raise CosimError(target.instance.explain(f"{e} at t={t:.6g}"), target.name) from None


def _step_loop(
    units: list[_Unit],
    times: np.ndarray,
    steps: np.ndarray,
    signals: np.ndarray,
    external: np.ndarray | None,
    record: np.ndarray,
    texts: dict[str, list[str]],
    deadline: float,
) -> tuple[int, Stop] | None:
    """The hot loop: no buffer is created here, only FMI calls through prepared ones, read from flat
    lists so that a step costs no Python call beyond the FMI calls and the fills that need one. Returns
    where an FMU asked to stop (the point the run was stepping to, and the stop), or None at the end."""
    n = record.shape[1]
    steppers = [u.stepper for u in units]
    watched = [s for s in steppers if s.watches_steps]
    plain = external is None and all(u.texts is None for u in units)  # only numeric connections to feed
    feeds = [(f.fill, f.call, f.args, unit, f.name) for unit in units for f in unit.feeds]
    reads = [(r.call, r.args, r.copy, unit, r.name) for unit in units for r in unit.reads]
    clock = time.perf_counter
    points = zip(times[:-1].tolist(), times[1:].tolist(), steps[1:].tolist())
    for k, (t, t_next, h) in enumerate(points, start=1):
        if not k & 63 and clock() > deadline:
            raise CosimError(f"timeout: the simulation was stopped at t={t:.6g} of {times[-1]:.6g} s")
        if plain:
            for fill, call, args, unit, name in feeds:
                try:
                    fill()
                except _Unfit as e:  # no cost in the loop until raised
                    raise CosimError(f"{e} at t={t:.6g}") from None
                if call(*args) > FMI_WARNING:
                    raise unit.fail(name, t)
        else:
            _feed_all(units, signals, external, k - 1, t)
        for s in steppers:
            status = s.call(*s.before, t, h, *s.after)
            if status > FMI_WARNING:
                at = s.asked_to_stop(status, t, t_next)
                if at is None:
                    raise _fail_step(units, s, t)
                return k, Stop(s.name, at)
        for s in watched:  # after every unit has stepped, as the C loop checks
            at = s.asked_to_stop(0, t, t_next)
            if at is not None:
                return k, Stop(s.name, at)
        if plain:
            for call, args, copy, unit, name in reads:
                if call(*args) > FMI_WARNING:
                    raise unit.fail(name, t_next)
                if copy is not None:
                    copy()
        else:
            for unit in units:
                _read(unit, t_next, texts)
        record[k] = signals[:n]
    return None


def _feed_all(units: list[_Unit], signals: np.ndarray, external: np.ndarray | None, k: int, t: float) -> None:
    if external is not None:
        signals[-external.shape[1] :] = external[k]
    for unit in units:
        _feed(unit, t)
        if unit.texts is not None:
            _feed_texts(unit.texts, t)


def _fail_step(units: list[_Unit], s: Stepper, t: float) -> CosimError:
    return next(u for u in units if u.stepper is s).fail(s.step_name, t)


def _resolve_values(plan: Plan, values: Mapping[str, Value]) -> dict[str, list[tuple[Variable, Value]]]:
    """Group values by instance, each checked against its variable's type. An input a connection feeds
    takes no value: the connection would overwrite it before the first step."""
    grouped: dict[str, list[tuple[Variable, Value]]] = {}
    for ref, value in values.items():
        variable = plan.variable(ref, "setting")
        plan.check_not_fed(variable)
        grouped.setdefault(variable.instance, []).append((variable, check_value(variable, value)))
    return grouped


def _resolve_inputs(plan: Plan, inputs: Mapping[str, Series], times: np.ndarray) -> dict[str, np.ndarray]:
    """Each input signal sampled at the communication points, checked against its variable."""
    sampled = {}
    for ref, series in inputs.items():
        variable = plan.variable(ref, "scenario input")
        if variable.causality != "input":
            raise DseError(
                f"scenario input {ref!r} is {with_article(variable.causality)}, not an input: give it as a "
                "parameter instead"
            )
        try:
            plan.check_not_fed(variable)  # a space has said so before anything ran; a caller's own plan not
        except DseError as e:
            raise DseError(f"scenario input {ref!r}: {e}") from None
        values = series.at(times)
        if variable.family == "string":
            raise DseError(f"scenario input {ref!r} is a String; a CSV signal can feed numbers only")
        if variable.family != "float":
            for value in np.unique(values):
                check_value(variable, float(value))
        sampled[ref] = values
    return sampled


def _check_finite(names: tuple[str, ...], times: np.ndarray, record: np.ndarray) -> None:
    if np.isfinite(record).all():
        return
    bad = ~np.isfinite(record)
    if bad.any():
        row, column = np.argwhere(bad)[0]
        raise CosimError(f"{names[column]} became non-finite at t={times[row]:.6g}: the simulation diverged")
