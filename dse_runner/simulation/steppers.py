"""Steppers: one FMU instance as the master loop drives it, whatever its FMI version and interface.

The master (cosim.py) asks every instance for the same few things, in the
order FMPy and the standard use: set up the experiment, set values, enter and
exit initialization, step from one communication point to
the next, read and write typed values through prepared buffers, terminate.
Each FMI version and interface answers in its own small class, side by side
as FMPy keeps ``simulateCS`` and ``simulateME``:

* :class:`CoSimulation2`: FMI 2.0 co-simulation, ``fmi2DoStep``;
* :class:`CoSimulation3`: FMI 3.0 co-simulation, ``fmi3DoStep``;
* :class:`ModelExchange`: FMI 2.0 or 3.0 model exchange, integrated over each
  communication step by FMPy's solvers (model_exchange.py).

The hot loop calls ``step.call(*step.before, t, h, *step.after)`` and the
typed accessors' ctypes functions directly: no Python method sits between
the loop and the FMU for co-simulation.

An FMU may ask to end the run early, each version its own way (FMI 2.0: fmi2DoStep returns fmi2Discard
and fmi2Terminated reads true; FMI 3.0: fmi3DoStep's terminateSimulation; model exchange: the event
update's terminateSimulation); ``asked_to_stop`` says whether it did and the time the run reached, as
FMPy's ``simulate_fmu`` reads them, and the master ends the run there (cosim.py).
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from fmpy.fmi2 import fmi2LastSuccessfulTime, fmi2Terminated, fmi2True

from .fmu import Instance
from .variables import Value, Variable

FMI_WARNING = 1  # statuses above this are failures, in FMI 2 and 3 alike
FMI_DISCARD = 2  # a step not taken whole: how an FMI 2.0 FMU asks to stop, when fmi2Terminated says so

# FMI 2 reads and writes one C type per family.
_FMI2 = {
    "float": ("Real", ctypes.c_double),
    "integer": ("Integer", ctypes.c_int),
    "boolean": ("Boolean", ctypes.c_int),
    "string": ("String", ctypes.c_char_p),
}

# FMI 3 has a function and a C type per type; enumerations travel as Int64.
_FMI3 = {
    "Float64": ctypes.c_double,
    "Float32": ctypes.c_float,
    "Int8": ctypes.c_int8,
    "UInt8": ctypes.c_uint8,
    "Int16": ctypes.c_int16,
    "UInt16": ctypes.c_uint16,
    "Int32": ctypes.c_int32,
    "UInt32": ctypes.c_uint32,
    "Int64": ctypes.c_int64,
    "UInt64": ctypes.c_uint64,
    "Boolean": ctypes.c_bool,
    "String": ctypes.c_char_p,
}


@dataclass(frozen=True)
class Access:
    """How to read and write one group of variables of one C type: functions, arguments and buffer."""

    get: Callable[..., int]
    set: Callable[..., int]
    ctype: Any
    name: str  # for messages: fmi2GetReal, fmi3GetFloat64...


class Stepper:
    """The contract: what the master needs of an instance (subclasses fill it per FMI version)."""

    call: Callable[..., int]  # the step function: call(*before, t, h, *after) -> status
    fmi_version = 2  # the calling convention of its functions (the native loop calls them)
    step_convention = 2  # that of ``call``: fmi2DoStep's or fmi3DoStep's shape
    integrates = False  # the master integrates it (model exchange), and initialises it in Python
    watches_steps = False  # asked_to_stop is asked after every step, not only after one above FMI_WARNING
    before: tuple = ()
    after: tuple = ()
    step_name = "doStep"

    def __init__(self, instance: Instance, tolerance: float | None = None, set_stop_time: bool = True):
        self.instance = instance
        self.name = instance.name
        self.tolerance = tolerance
        self.set_stop_time = set_stop_time  # FMPy's default: the FMU is told when the experiment ends

    def stop_time(self, stop: float) -> float | None:
        """The stop time the FMU is told, or None where the multi-model says not to tell it."""
        return stop if self.set_stop_time else None

    def access(self, variable: Variable) -> Access:
        raise NotImplementedError

    def handle(self) -> Any:
        return self.instance.slave.component

    def args(self, access: Access, vrs, n: int, buffer) -> tuple:
        """The arguments of a get or set call on ``n`` values."""
        return (self.handle(), vrs, n, buffer)

    def set_values(self, values: list[tuple[Variable, Value]]) -> None:
        """Values before initialization (parameters, start values), through the FMU's typed setters."""
        for variable, value in values:
            access, buffer, args = self._setter(variable)
            buffer[0] = str(value).encode("utf-8") if access.ctype is ctypes.c_char_p else value
            if access.set(*args) > FMI_WARNING:
                raise RuntimeError(
                    f"{access.name.replace('Get', 'Set')} of {variable.name} = {value!r} failed"
                )

    def _setter(self, variable: Variable) -> tuple[Access, Any, tuple]:
        """A variable's access, one-value buffer and call arguments, made once: a sweep sets the same
        ones every run."""
        setters = self.__dict__.setdefault("_setters", {})
        found = setters.get(variable)
        if found is None:
            access = self.access(variable)
            buffer = (access.ctype * 1)()
            found = setters[variable] = (
                access,
                buffer,
                self.args(access, (ctypes.c_uint32 * 1)(variable.vr), 1, buffer),
            )
        return found

    def setup(self, start: float, stop: float) -> None:
        """The experiment, before any value is set (FMI 2's fmi2SetupExperiment: an FMU may load its
        defaults there, so values set earlier would be lost). FMI 3 takes the times on entering
        initialization instead."""

    def enter_initialization(self, start: float, stop: float) -> None:
        raise NotImplementedError

    def exit_initialization(self) -> None:
        self.instance.slave.exitInitializationMode()

    def asked_to_stop(self, status: int, t: float, t_next: float) -> float | None:
        """After a step from ``t`` to ``t_next`` that returned ``status``: the time the run reached if the FMU
        asked to end it, else None (and a status above FMI_WARNING is then a failure)."""
        return None

    def step_failure(self) -> Exception | None:
        """Why the native loop's call of ``call`` failed, where the stepper knows more than its status."""
        return None

    def terminate(self) -> None:
        self.instance.slave.terminate()


class CoSimulation2(Stepper):
    """FMI 2.0 co-simulation."""

    def __init__(self, instance: Instance, tolerance: float | None = None, set_stop_time: bool = True):
        super().__init__(instance, tolerance, set_stop_time)
        dll = instance.slave.dll
        self.call = dll.fmi2DoStep  # FMPy set its ctypes signature
        self.before, self.after = (instance.slave.component,), (fmi2True,)
        self.step_name = "fmi2DoStep"

    def access(self, variable: Variable) -> Access:
        kind, ctype = _FMI2[variable.family]
        dll = self.instance.slave.dll
        return Access(getattr(dll, f"fmi2Get{kind}"), getattr(dll, f"fmi2Set{kind}"), ctype, f"fmi2Get{kind}")

    def setup(self, start: float, stop: float) -> None:
        self.instance.slave.setupExperiment(
            tolerance=self.tolerance, startTime=start, stopTime=self.stop_time(stop)
        )

    def enter_initialization(self, start: float, stop: float) -> None:
        self.instance.slave.enterInitializationMode()

    def asked_to_stop(self, status: int, t: float, t_next: float) -> float | None:
        """fmi2Discard with fmi2Terminated true, as FMPy's simulate_fmu reads it: the run reached
        fmi2LastSuccessfulTime (``t`` where the FMU cannot say). Any other Discard is a failure."""
        if status != FMI_DISCARD:
            return None
        slave = self.instance.slave
        try:
            if not slave.getBooleanStatus(fmi2Terminated):
                return None
        except Exception:  # noqa: BLE001  (FMPy's FMICallException: the FMU has no such status)
            return None
        try:
            return float(slave.getRealStatus(fmi2LastSuccessfulTime))
        except Exception:  # noqa: BLE001  (as above)
            return t


class CoSimulation3(Stepper):
    """FMI 3.0 co-simulation: typed access per type, and doStep reports a request to terminate."""

    fmi_version = step_convention = 3
    watches_steps = True

    def __init__(self, instance: Instance, tolerance: float | None = None, set_stop_time: bool = True):
        super().__init__(instance, tolerance, set_stop_time)
        slave = instance.slave
        self.flags = [ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool(), ctypes.c_double()]
        self.call = slave.dll.fmi3DoStep
        self.before = (slave.component,)
        self.after = (True, *(ctypes.byref(f) for f in self.flags))
        self.step_name = "fmi3DoStep"

    def access(self, variable: Variable) -> Access:
        kind = "Int64" if variable.type == "Enumeration" else variable.type
        dll = self.instance.slave.dll
        return Access(
            getattr(dll, f"fmi3Get{kind}"), getattr(dll, f"fmi3Set{kind}"), _FMI3[kind], f"fmi3Get{kind}"
        )

    def args(self, access: Access, vrs, n: int, buffer) -> tuple:
        return (self.handle(), vrs, n, buffer, n)  # FMI 3 also counts values (arrays)

    def enter_initialization(self, start: float, stop: float) -> None:
        self.instance.slave.enterInitializationMode(
            tolerance=self.tolerance, startTime=start, stopTime=self.stop_time(stop)
        )

    def asked_to_stop(self, status: int, t: float, t_next: float) -> float | None:
        """terminateSimulation after a step that succeeded, as FMPy's simulate_fmu reads it: the run reached
        ``t_next`` (early return is not allowed, as in FMPy)."""
        return t_next if status <= FMI_WARNING and self.flags[1].value else None


class ModelExchange(Stepper):
    """FMI 2.0 or 3.0 model exchange: each communication step is integrated by FMPy's solvers, or with
    ``native`` by the same CVode in C (native_me.py), which the native loop steps like doStep."""

    integrates = True

    def __init__(
        self,
        instance: Instance,
        tolerance: float | None = None,
        set_stop_time: bool = True,
        solver: str = "cvode",
        euler_step: float | None = None,
        terms: Mapping | None = None,
        native: bool = False,
    ):
        super().__init__(instance, tolerance, set_stop_time)
        from .derivative_terms import Corrector
        from .model_exchange import ModelExchangeStepper

        description = instance.fmu.description
        self.integrator = ModelExchangeStepper(
            instance.slave,
            description,
            solver=solver,
            tolerance=tolerance,
            euler_step=euler_step,
            set_stop_time=set_stop_time,
            corrector=Corrector.of(description, terms) if terms else None,
        )
        if native:
            from .native_me import NativeIntegrator

            self.integrator.native = NativeIntegrator(
                instance.slave, description, tolerance, self.integrator.corrector
            )
        self.fmi_version = instance.fmu.version  # of its getters and setters; its step is ours
        self.stopped_at: float | None = None  # where the FMU asked to stop, in the Python integrator
        self.step_name = "the integration"
        self._typed = CoSimulation2 if instance.fmu.version == 2 else CoSimulation3
        c = self.integrator.native
        self.call, self.before, self.after = (
            (c.function, (c.address,), (1,)) if c else (self._do_step, (), ())
        )

    def _do_step(self, t: float, h: float) -> int:
        """Integrate from ``t`` by ``h``: 0, or FMI_DISCARD where the FMU asked to stop (at ``stopped_at``);
        any failure raises ModelExchangeError with what went wrong."""
        from .model_exchange import TerminationAsked

        try:
            self.integrator.do_step(t, h)
        except TerminationAsked as e:
            self.stopped_at = e.time
            return FMI_DISCARD
        return 0

    def asked_to_stop(self, status: int, t: float, t_next: float) -> float | None:
        """The event update's (or completedIntegratorStep's) terminateSimulation: the run reached the time
        of that event."""
        native = self.integrator.native
        if native is not None:
            return native.asked_to_stop() if status > FMI_WARNING else None
        return self.stopped_at if status == FMI_DISCARD else None

    def access(self, variable: Variable) -> Access:
        return self._typed.access(self, variable)  # the same get/set functions as co-simulation

    def args(self, access: Access, vrs, n: int, buffer) -> tuple:
        return self._typed.args(self, access, vrs, n, buffer)

    def setup(self, start: float, stop: float) -> None:
        self.integrator.setup(start, stop)

    def enter_initialization(self, start: float, stop: float) -> None:
        self.integrator.enter_initialization(start, stop)

    def exit_initialization(self) -> None:
        self.integrator.exit_initialization()

    def terminate(self) -> None:
        self.integrator.terminate()

    def step_failure(self) -> Exception | None:
        return self.integrator.native.failure() if self.integrator.native else None

    def use_terms(self, terms: Mapping) -> None:
        """This run's coefficients of the derivative terms the stepper was made with."""
        from .derivative_terms import Corrector

        self.integrator.use_coefficients(Corrector.of(self.instance.fmu.description, terms))


def stepper(instance: Instance, settings, terms: Mapping | None = None, native: bool = False) -> Stepper:
    """The stepper for an instance's FMI version and interface, with its multi-model settings; ``terms``:
    derivative terms (derivative_terms.py) to add while integrating a model-exchange instance; ``native``:
    a model-exchange instance is integrated in C, for the native loop (native_me.eligible says when)."""
    tolerance = settings.tolerance if settings is not None else None
    set_stop_time = settings.set_stop_time if settings is not None else True
    if instance.fmu.interface == "me":
        solver = settings.solver if settings is not None else "cvode"
        euler_step = settings.euler_step if settings is not None else None
        return ModelExchange(instance, tolerance, set_stop_time, solver, euler_step, terms, native)
    if terms:
        raise ValueError(
            f"instance {instance.name} is co-simulation: the master cannot add to its derivatives"
        )
    return (CoSimulation2 if instance.fmu.version == 2 else CoSimulation3)(instance, tolerance, set_stop_time)
