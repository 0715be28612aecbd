"""The master's step loop in C: one call per simulation instead of Python per step.

A design study runs the same co-simulation thousands of times, and with
cheap FMUs the Python loop (cosim.py) costs far more per step than the FMUs
do. ``native_loop.c`` does the same steps in the same order through the same
FMU functions, so the trajectories are bit-identical; cosim.py still loads,
instantiates, initialises, terminates and words every error, and hands this
module its prepared reads and feeds.

The library is compiled with the system C compiler on first use and cached by
a hash of its source, as our FMUs are (build.py). Without a compiler the
Python loop runs instead, after a one-line notice. A model-exchange instance
under CVode is integrated in C too (native_me.py) and stepped here like any
FMU, with its derivative terms; one under Euler keeps the plan in the Python loop.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from .build import default_cache_dir

SOURCES = (Path(__file__).with_name("native_loop.c"), Path(__file__).with_name("native_me.c"))  # native_me.py
CFLAGS = ("-O3", "-std=c11", "-fPIC", "-shared")  # -O3: unswitches the loop's invariant branches

# C type codes of native_loop.c, by the ctypes type a buffer holds (FMI 2's Integer and Boolean are int).
CTYPES = {
    ctypes.c_double: 0,
    ctypes.c_float: 1,
    ctypes.c_int8: 2,
    ctypes.c_uint8: 3,
    ctypes.c_int16: 4,
    ctypes.c_uint16: 5,
    ctypes.c_int32: 6,
    ctypes.c_uint32: 7,
    ctypes.c_int64: 8,
    ctypes.c_uint64: 9,
    ctypes.c_bool: 10,
    ctypes.c_int: 11,
}
CONVERSIONS = {"none": 0, "round": 1, "threshold": 2}
(
    DONE,
    FEED_FAILED,
    STEP_FAILED,
    READ_FAILED,
    TIMEOUT,
    DIVERGED,
    UNFIT,
    TERMINATE,
    TEXT_READ_FAILED,
    TEXT_FEED_FAILED,
    NO_MEMORY,
    LIFECYCLE_FAILED,
    VALUE_FAILED,
) = range(13)
# The FMI functions of a unit's set-up and end (LIFECYCLE_FAILED's group indexes these), by FMI version.
LIFECYCLE = {
    2: ("fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate"),
    3: (None, "fmi3EnterInitializationMode", "fmi3ExitInitializationMode", "fmi3Terminate"),
}


class NativeLoopWarning(UserWarning):
    """The native loop cannot be built here; the Python loop runs instead."""


# How native_loop.c's Group, TextRead and TextFeed begin: the FMU function, the instance it is called on, and
# the FMI version, whose calling convention the loop follows (its transfer()).
CALLED = [("fn", ctypes.c_void_p), ("component", ctypes.c_void_p), ("version", ctypes.c_int32)]


class Group(ctypes.Structure):
    _fields_ = CALLED + [
        ("ctype", ctypes.c_int32),
        ("conv", ctypes.c_int32),
        ("unit", ctypes.c_int32),
        ("threshold", ctypes.c_double),
        ("low", ctypes.c_double),
        ("above", ctypes.c_double),
        ("n", ctypes.c_int64),
        ("vrs", ctypes.c_void_p),
        ("index", ctypes.c_void_p),
        ("buffer", ctypes.c_void_p),
    ]


class Unit(ctypes.Structure):
    _fields_ = [
        ("step", ctypes.c_void_p),
        ("component", ctypes.c_void_p),
        ("version", ctypes.c_int32),
        ("unit", ctypes.c_int32),
    ]


class Lifecycle(ctypes.Structure):
    _fields_ = [
        ("setup", ctypes.c_void_p),
        ("enter", ctypes.c_void_p),
        ("exit", ctypes.c_void_p),
        ("terminate", ctypes.c_void_p),
        ("tolerance_defined", ctypes.c_int32),
        ("tolerance", ctypes.c_double),
        ("stop_defined", ctypes.c_int32),
    ]


class TextRead(ctypes.Structure):
    _fields_ = CALLED + [
        ("unit", ctypes.c_int32),
        ("n", ctypes.c_int64),
        ("vrs", ctypes.c_void_p),
        ("buffer", ctypes.c_void_p),
        ("first", ctypes.c_int64),
    ]


class TextFeed(ctypes.Structure):
    _fields_ = CALLED + [
        ("unit", ctypes.c_int32),
        ("vr", ctypes.c_uint32),
        ("target", ctypes.c_int32),
        ("source", ctypes.c_int64),
    ]


class Call(ctypes.Structure):
    """dse_loop's arguments in one block (native_loop.c): the fixed ones are filled once per Program."""

    _fields_ = [
        ("units", ctypes.c_void_p),
        ("lifecycle", ctypes.c_void_p),
        ("feeds", ctypes.c_void_p),
        ("reads", ctypes.c_void_p),
        ("values", ctypes.c_void_p),
        ("text_reads", ctypes.c_void_p),
        ("text_feeds", ctypes.c_void_p),
        ("initial_texts", ctypes.c_void_p),
        ("times", ctypes.c_void_p),
        ("steps", ctypes.c_void_p),
        ("external", ctypes.c_void_p),
        ("signals", ctypes.c_void_p),
        ("record", ctypes.c_void_p),
        ("text_offsets", ctypes.c_void_p),
        ("out", ctypes.c_void_p),
        ("seconds", ctypes.c_double),
        ("n_texts", ctypes.c_int64),
        ("n_times", ctypes.c_int64),
        ("n_recorded", ctypes.c_int64),
        ("n_external", ctypes.c_int64),
        ("n_units", ctypes.c_int32),
        ("n_feeds", ctypes.c_int32),
        ("n_reads", ctypes.c_int32),
        ("n_text_reads", ctypes.c_int32),
        ("n_text_feeds", ctypes.c_int32),
        ("n_values", ctypes.c_int32),
    ]


class Outcome(ctypes.Structure):
    _fields_ = [
        ("code", ctypes.c_int32),
        ("unit", ctypes.c_int32),
        ("group", ctypes.c_int32),
        ("element", ctypes.c_int32),
        ("k", ctypes.c_int64),
        ("t", ctypes.c_double),
        ("value", ctypes.c_double),
        ("arena", ctypes.c_void_p),
        ("arena_used", ctypes.c_int64),
    ]


def _compiler() -> str | None:
    return os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")


def _build(compiler: str, target: Path) -> None:
    """Compile under a temporary name and rename: processes building at once never load half a file."""
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as work:
        partial = Path(work) / target.name
        done = subprocess.run(
            [compiler, *CFLAGS, "-o", str(partial), *map(str, SOURCES), "-lm"],
            capture_output=True,
            text=True,
            check=False,
        )
        if done.returncode != 0:
            raise OSError(
                done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "the compiler failed"
            )
        os.replace(partial, target)


@cache
def library() -> ctypes.CDLL | None:
    """The compiled loop (built on first use, cached by source hash), or None after a notice."""
    compiler = _compiler()
    if compiler is None:
        warnings.warn(
            "no C compiler (cc) found: the co-simulation master runs its Python loop, several times "
            "slower on cheap FMUs",
            NativeLoopWarning,
            stacklevel=2,
        )
        return None
    try:
        digest = hashlib.sha256(
            b"".join(p.read_bytes() for p in SOURCES) + " ".join(CFLAGS).encode()
        ).hexdigest()[:16]
        path = default_cache_dir().parent / "native" / f"loop-{digest}.so"
        if not path.is_file():
            _build(compiler, path)
        lib = ctypes.CDLL(str(path))
    except OSError as e:
        warnings.warn(
            f"the native co-simulation loop could not be built ({e}): the master runs its Python loop",
            NativeLoopWarning,
            stacklevel=2,
        )
        return None
    lib.dse_run.argtypes = [ctypes.c_void_p]
    lib.dse_run.restype = ctypes.c_int
    lib.dse_free.argtypes = [ctypes.c_void_p]
    lib.dse_free.restype = None
    lib.dse_me_start.argtypes = lib.dse_me_end.argtypes = [ctypes.c_void_p]
    lib.dse_me_start.restype, lib.dse_me_end.restype = ctypes.c_int, None
    lib.dse_me_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
    lib.dse_me_step.restype = ctypes.c_int
    return lib


def _writable_address(array: np.ndarray) -> int:
    """The C address of a writable C-contiguous array, through the buffer protocol: a third of what
    numpy's ``.ctypes.data`` costs, which counts in a run of a few tens of microseconds. (A buffer
    has no first byte to take when nothing is recorded.)"""
    return ctypes.addressof(ctypes.c_char.from_buffer(array)) if array.nbytes else array.ctypes.data


def _address(obj: Any) -> int | None:
    """The C address of a ctypes array or function, or of a numpy array."""
    if obj is None:
        return None
    if isinstance(obj, np.ndarray):
        return obj.ctypes.data
    if isinstance(obj, ctypes.Array):
        return ctypes.addressof(obj)
    return ctypes.cast(obj, ctypes.c_void_p).value


def _limits(ctype) -> tuple[float, float]:
    """[low, above): the whole numbers a rounded value may take in an integer buffer (cosim._rounder)."""
    if ctype in (ctypes.c_double, ctypes.c_float, ctypes.c_bool):
        return 0.0, 0.0
    limits = np.iinfo(np.dtype(ctype))
    return float(limits.min), limits.max + 1.0


def _group(
    call, args: tuple, unit: int, version: int, ctype, index: np.ndarray | None, conversion=None
) -> Group:
    low, above = _limits(ctype)
    return Group(
        fn=_address(call),
        component=args[0],
        version=version,
        ctype=CTYPES[ctype],
        conv=CONVERSIONS[conversion.kind] if conversion is not None else 0,
        unit=unit,
        threshold=conversion.threshold if conversion is not None else 0.0,
        low=low,
        above=above,
        n=args[2],
        vrs=_address(args[1]),
        index=_address(index),
        buffer=_address(args[3]),
    )


class Program:
    """A plan's units as the C loop takes them: flat arrays of C structures pointing at the units'
    functions and buffers, and the call's arguments in one block; made once per set of FMU instances
    (cosim._prepare) and reused, so that a run fills in only its own arguments."""

    def __init__(self, units: list, signals: np.ndarray, n_recorded: int) -> None:
        self.units = units
        self.steps = (Unit * len(units))(
            *[
                Unit(
                    step=_address(u.stepper.call),
                    component=u.stepper.before[0],
                    version=u.stepper.step_convention,
                    unit=i,
                )
                for i, u in enumerate(units)
            ]
        )
        self.feeds = [(i, f) for i, u in enumerate(units) for f in u.feeds]
        self.reads = [(i, r) for i, u in enumerate(units) for r in u.reads]
        self.feed_groups = (Group * len(self.feeds))(
            *[
                _group(f.call, f.args, i, units[i].stepper.fmi_version, f.ctype, f.gather, f.conversion)
                for i, f in self.feeds
            ]
        )
        self.read_groups = (Group * len(self.reads))(
            *[
                _group(r.call, r.args, i, units[i].stepper.fmi_version, r.ctype, r.columns)
                for i, r in self.reads
            ]
        )
        self.texts = [(i, u.texts) for i, u in enumerate(units) if u.texts is not None]
        firsts = np.cumsum([0] + [len(x.names) for _, x in self.texts])
        self.text_names = [name for _, x in self.texts for name in x.names]
        self.text_reads = (TextRead * len(self.texts))(
            *[
                TextRead(
                    fn=_address(x.call),
                    component=x.args[0],
                    version=units[i].stepper.fmi_version,
                    unit=i,
                    n=x.args[2],
                    vrs=_address(x.args[1]),
                    buffer=_address(x.buffer),
                    first=int(firsts[j]),
                )
                for j, (i, x) in enumerate(self.texts)
            ]
        )
        index = {id(u.stepper): i for i, u in enumerate(units)}
        self.text_feeds = [
            (i, target, variable) for j, (i, x) in enumerate(self.texts) for target, variable, _ in x.feeds
        ]
        self.text_source_names = [x.names[k] for _, x in self.texts for _, _, k in x.feeds]
        self.text_feed_structs = (TextFeed * len(self.text_feeds))(
            *[
                TextFeed(
                    fn=_address(target.access(variable).set),
                    component=target.handle(),
                    version=target.fmi_version,
                    unit=i,
                    vr=variable.vr,
                    target=index[id(target)],
                    source=int(firsts[j]) + k,
                )
                for j, (i, x) in enumerate(self.texts)
                for target, variable, k in x.feeds
            ]
        )
        self.signals = signals
        # Without strings (whose first values Python keeps) or model exchange (whose initialization Python
        # does: model_exchange.py), the loop also sets the units up and ends them.
        self.sets_up = not self.text_names and not any(u.stepper.integrates for u in units)
        self.lifecycle = (
            (Lifecycle * len(units))(*[_lifecycle(u.stepper) for u in units]) if self.sets_up else None
        )
        self.outcome = Outcome()
        self.value_groups: dict[
            tuple, Values | None
        ] = {}  # the variables a run sets -> their groups (values_of)
        self.given: Values | None = None  # the groups the current run's values went into
        self.call = Call(
            units=_address(self.steps),
            lifecycle=_address(self.lifecycle),
            n_units=len(units),
            feeds=_address(self.feed_groups),
            n_feeds=len(self.feeds),
            reads=_address(self.read_groups),
            n_reads=len(self.reads),
            text_reads=_address(self.text_reads),
            n_text_reads=len(self.texts),
            text_feeds=_address(self.text_feed_structs),
            n_text_feeds=len(self.text_feeds),
            n_texts=len(self.text_names),
            signals=_address(signals),
            n_recorded=n_recorded,
            out=ctypes.addressof(self.outcome),
        )
        self.call_address = ctypes.addressof(self.call)
        self._times: np.ndarray | None = None  # the time grid and input signals the block points at now
        self._steps: np.ndarray | None = None
        self._external: np.ndarray | None = None


class Values:
    """The values of a run as C groups, one per unit and setter, with buffers that Python fills each run;
    made once per set of variables (a sweep sets the same ones every run)."""

    def __init__(self, units: list, settings: dict[str, list]) -> None:
        index = {u.stepper.name: i for i, u in enumerate(units)}
        groups: dict[tuple[int, str], list] = {}  # (unit, setter) -> its variables
        places = []  # each value's group and position, in the order ``settings`` gives them
        for name, values in settings.items():
            step = units[index[name]].stepper
            for variable, _ in values:
                key = (index[name], step.access(variable).name)
                places.append((key, len(groups.setdefault(key, []))))
                groups[key].append(variable)
        self.members = list(groups.items())  # ((unit, setter), [variable, ...]) per group, for messages
        self.views, made = [], []
        for (i, _), members in self.members:
            step = units[i].stepper
            access = step.access(members[0])
            vrs = (ctypes.c_uint32 * len(members))(*[v.vr for v in members])
            buffer = (access.ctype * len(members))()
            made.append(
                _group(
                    access.set,
                    step.args(access, vrs, len(members), buffer),
                    i,
                    step.fmi_version,
                    access.ctype,
                    None,
                )
            )
            self.views.append(
                (
                    vrs,
                    buffer,
                    np.ctypeslib.as_array(buffer)
                    if access.ctype is not ctypes.c_bool
                    else np.frombuffer(buffer, dtype=np.bool_),
                )
            )
        self.groups = (Group * len(made))(*made)
        order = {key: g for g, key in enumerate(groups)}
        self.slots = [(self.views[order[key]][2], j) for key, j in places]  # where each value goes
        self.address = ctypes.addressof(self.groups)

    def fill(self, settings: dict[str, list]) -> None:
        """This run's values into the buffers (the same variables, in the same order, as when made)."""
        slots = iter(self.slots)
        for values in settings.values():
            for _, value in values:
                view, j = next(slots)
                view[j] = value

    def failed(self, group: int) -> tuple[int, list]:
        """The unit and the variables of a group whose setter failed."""
        (unit, _), members = self.members[group]
        return unit, members


def values_of(program: Program, units: list, settings: dict[str, list]) -> bool:
    """Hand the run's values to the C call, which then sets each unit up and its values in FMPy's order;
    False (and nothing handed) where a value is a string, which Python sets."""
    key = tuple([id(v) for values in settings.values() for v, _ in values])  # the plan keeps its variables
    values = program.value_groups.get(key, False)
    if values is False:
        strings = any(v.family == "string" for values in settings.values() for v, _ in values)
        values = program.value_groups[key] = None if strings else Values(units, settings)
    call = program.call
    if values is None:
        call.values, call.n_values = None, 0
        return False
    values.fill(settings)
    call.values, call.n_values = values.address, len(values.groups)
    program.given = values
    return True


def step_loop(
    program: Program,
    times: np.ndarray,
    steps: np.ndarray,
    external: np.ndarray | None,
    record: np.ndarray,
    texts: dict[str, list[str]],
    timeout: float | None,
) -> Outcome:
    """Run points 1.. of ``times`` in C into ``record``, stepping by ``steps`` (the step reaching each point);
    the string outputs are appended to ``texts``.
    With ``program.sets_up``, the C call also sets the units up (point 0, row 0 of ``record``) before
    and terminates them after, as cosim.py's Python otherwise does. ``times``, ``steps`` and ``external``
    must be C-contiguous float64 and stay unchanged while the program uses
    them: a sweep passes the same arrays run after run, and their addresses are taken only when they
    change (numpy's ``.ctypes`` costs about a microsecond each)."""
    call = program.call
    if times is not program._times:
        call.times, call.n_times, program._times = times.ctypes.data, len(times), times
    if steps is not program._steps:
        call.steps, program._steps = steps.ctypes.data, steps
    if external is not program._external:
        call.external = _address(external)
        call.n_external = external.shape[1] if external is not None else 0
        program._external = external
    n_texts = call.n_texts
    if n_texts:
        initial = (ctypes.c_char_p * n_texts)(
            *[texts[name][-1].encode("utf-8") for name in program.text_names]
        )
        offsets = np.zeros((len(times), n_texts), dtype=np.int64)
        call.initial_texts, call.text_offsets = _address(initial), offsets.ctypes.data
    call.record, call.seconds = _writable_address(record), timeout or 0.0
    library().dse_run(program.call_address)
    outcome = program.outcome
    if outcome.arena:
        try:
            if n_texts:
                _decode(program, outcome, offsets, texts)
        finally:
            library().dse_free(outcome.arena)
    return outcome


def _lifecycle(stepper) -> Lifecycle:
    """A co-simulation unit's set-up and end functions, from the library FMPy loaded."""
    dll = stepper.instance.slave.dll
    setup, enter, exit_, terminate = (
        _address(getattr(dll, name)) if name else None for name in LIFECYCLE[stepper.fmi_version]
    )
    tolerance = stepper.tolerance
    return Lifecycle(
        setup=setup,
        enter=enter,
        exit=exit_,
        terminate=terminate,
        tolerance_defined=tolerance is not None,
        tolerance=tolerance or 0.0,
        stop_defined=stepper.set_stop_time,
    )


def _decode(program: Program, outcome: Outcome, offsets: np.ndarray, texts: dict[str, list[str]]) -> None:
    """The string outputs the loop kept, one per communication point, appended to ``texts``."""
    arena = ctypes.string_at(outcome.arena, outcome.arena_used)
    rows = offsets[1 : outcome.k + (outcome.code == DONE)]
    for j, name in enumerate(program.text_names):
        texts[name].extend(arena[o : arena.index(b"\0", o)].decode("utf-8", "replace") for o in rows[:, j])
