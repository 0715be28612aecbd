"""A model-exchange instance integrated in C (native_me.c), so that the native loop steps it like any FMU.

model_exchange.py integrates with FMPy's CVodeSolver, whose right-hand side is a Python callback: with
a cheap FMU that callback costs several times the model. native_me.c makes the same SUNDIALS calls
(the libraries FMPy ships, whose functions this module hands over) with the same options, and the same
FMU calls in the same order, so a run is bit-identical to the Python one; ModelExchangeStepper still
sets the instance up, initialises and terminates it, and words every failure here as it does its own.

It takes the instances it can match exactly: under CVode (Euler stays in Python), with inputs that are
numbers (an input change is seen by reading the inputs back and comparing them); derivative terms
(derivative_terms.py) are added in C as Corrector.add adds them.
"""

from __future__ import annotations

import ctypes
from functools import cache
from typing import Any

import numpy as np

from .derivative_terms import FUNCTIONS as TERM_FUNCTIONS
from .derivative_terms import Corrector
from .model_exchange import DEFAULT_TOLERANCE, MAX_EVENT_ITERATIONS, ModelExchangeError, input_groups
from .native import library

# native_me.c's FMU functions (its enum), by FMI version: FMPy's names, which its messages use.
FUNCTIONS = {
    2: (
        "fmi2SetTime",
        "fmi2SetContinuousStates",
        "fmi2GetContinuousStates",
        "fmi2GetDerivatives",
        "fmi2GetEventIndicators",
        "fmi2GetNominalsOfContinuousStates",
        "fmi2CompletedIntegratorStep",
        "fmi2EnterEventMode",
        "fmi2NewDiscreteStates",
        "fmi2EnterContinuousTimeMode",
    ),
    3: (
        "fmi3SetTime",
        "fmi3SetContinuousStates",
        "fmi3GetContinuousStates",
        "fmi3GetContinuousStateDerivatives",
        "fmi3GetEventIndicators",
        "fmi3GetNominalsOfContinuousStates",
        "fmi3CompletedIntegratorStep",
        "fmi3EnterEventMode",
        "fmi3UpdateDiscreteStates",
        "fmi3EnterContinuousTimeMode",
    ),
}
# The C type an input getter fills (model_exchange.input_groups names FMPy's getters), and whether its
# values compare as numbers; a getter not here (strings) keeps the instance in Python.
GETTERS = {
    2: {
        "getReal": (ctypes.c_double, True),
        "getInteger": (ctypes.c_int, False),
        "getBoolean": (ctypes.c_int, False),
    },
    3: {
        "getFloat64": (ctypes.c_double, True),
        "getFloat32": (ctypes.c_float, True),
        "getBoolean": (ctypes.c_bool, False),
        **{
            f"get{t}": (getattr(ctypes, f"c_{t.lower()}"), False)
            for t in ("Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64")
        },
    },
}
TERM_INPUTS = {2: "fmi2GetReal", 3: "fmi3GetFloat64"}  # what reads the real inputs derivative terms use
(OK, FMU_CALL, CALLBACK_CALL, SOLVER, TERMINATE_ASKED, UNSETTLED, OFF_GRID, BAD_STEP, NO_MEMORY) = range(9)
STAGES = (
    "exiting initialization mode",
    "handling an input change",
    "integrating",
    "completing an integrator step",
)
INTEGRATING = 2
# The SUNDIALS functions native_me.c calls, in its Sundials structure's order.
SUNDIALS = (
    "SUNContext_Create",
    "SUNContext_Free",
    "SUNContext_PushErrHandler",
    "SUNContext_ClearErrHandlers",
    "N_VNew_Serial",
    "N_VDestroy_Serial",
    "N_VGetArrayPointer",
    "CVodeCreate",
    "CVodeInit",
    "CVodeSVtolerances",
    "CVodeRootInit",
    "SUNDenseMatrix",
    "SUNLinSol_Dense",
    "CVodeSetLinearSolver",
    "CVodeSetMaxStep",
    "CVodeSetMaxNumSteps",
    "CVodeSetNoInactiveRootWarn",
    "CVodeSetUserData",
    "CVode",
    "CVodeReInit",
    "CVodeFree",
    "SUNLinSolFree",
    "SUNMatDestroy",
    "CVodeSetMaxHnilWarns",
)


def _fields(*groups: tuple[Any, str]) -> list[tuple[str, Any]]:
    """ctypes fields from (type, "name name ...") groups, in order: read like native_me.c's declarations."""
    return [(name, kind) for kind, names in groups for name in names.split()]


P, I32, I64, F64 = ctypes.c_void_p, ctypes.c_int32, ctypes.c_int64, ctypes.c_double


class Sundials(ctypes.Structure):
    _fields_ = _fields((P, " ".join(SUNDIALS)))


class Inputs(ctypes.Structure):
    _fields_ = _fields((P, "fn"), (I64, "n"), (P, "vrs now before"), (I32, "size floating"))


class Failure(ctypes.Structure):
    _fields_ = _fields(
        (I32, "code stage function status"),
        (F64, "start to"),
        (I32, "solver_code"),
        (ctypes.c_char * 64, "solver_module solver_file"),
        (ctypes.c_char * 256, "solver_message"),
    )


class MeUnit(ctypes.Structure):
    _fields_ = _fields(
        (P, "sun"),
        (P * len(FUNCTIONS[2]), "fn"),
        (P, "component inputs terms factors limits term_inputs term_states"),
        (I32, "n_terms n_limits n_inputs version needs_completed discrete"),
        (I64, "nx nz"),
        (F64, "tolerance max_step time next_event"),
        (I32, "next_defined"),
        (P * 6, "solver"),
        (Failure, "failure"),
    )  # solver: CVode's, which only C touches


def _limit_rows(corrector: Corrector) -> np.ndarray:
    """The corrector's state limits as native_me.c's rows (at least one row, so that C has an address)."""
    rows = [(r.state, r.low, r.high, r.to, r.fraction) for r in corrector.limits]
    return np.array(rows or [(0, -np.inf, np.inf, -1, 0.0)], dtype=float).reshape(-1, 5)


def _address(function: Any) -> int:
    return ctypes.cast(function, ctypes.c_void_p).value


@cache
def _sundials() -> Sundials | None:
    """FMPy's SUNDIALS functions, or None where FMPy ships no build (model exchange then stays in Python)."""
    try:
        from fmpy.sundials import libraries
    except (ImportError, OSError):
        return None
    libs = [
        libraries.sundials_core,
        libraries.sundials_nvecserial,
        libraries.sundials_sunmatrixdense,
        libraries.sundials_sunlinsoldense,
        libraries.sundials_cvode,
    ]

    def found(name: str) -> int | None:
        return next((_address(getattr(lib, name)) for lib in libs if hasattr(lib, name)), None)

    addresses = {name: found(name) for name in SUNDIALS}
    return None if None in addresses.values() else Sundials(**addresses)


def _inputs(description: Any, version: int) -> list[tuple[str, list[int], Any, bool]] | None:
    """The inputs' groups as model_exchange reads them back, with their C types; None if one cannot be
    compared in C (a string, an array, a clock)."""
    groups = input_groups(description)
    if groups is None or any(getter not in GETTERS[version] for getter, _ in groups):
        return None
    return [(getter, vrs, *GETTERS[version][getter]) for getter, vrs in groups]


@cache  # asked every run; a loaded FMU keeps its description
def eligible(description: Any, solver: str) -> bool:
    """Whether native_me.c integrates this ME instance exactly as model_exchange.py would."""
    version = 3 if description.fmiVersion.startswith("3.") else 2
    return solver == "cvode" and _inputs(description, version) is not None and _sundials() is not None


class NativeIntegrator:
    """One ME instance's C integrator: its functions and buffers, laid out once and started every run."""

    def __init__(
        self, model: Any, description: Any, tolerance: float | None, corrector: Corrector | None = None
    ) -> None:
        self.version = 3 if description.fmiVersion.startswith("3.") else 2
        self.dll = model.dll
        groups = _inputs(description, self.version)
        # the C getters, in native_me.c's order after its FMU functions: each input group's, then the terms'
        self.getters = [f"fmi{self.version}G{getter[1:]}" for getter, *_ in groups] + [
            TERM_INPUTS[self.version]
        ]
        self._buffers: list = []  # kept alive while C points at them
        inputs = [
            self._group(name, vrs, ctype, floating)
            for name, (_, vrs, ctype, floating) in zip(self.getters, groups)
        ]
        self.inputs = (Inputs * len(inputs))(*inputs)
        self.sundials = _sundials()
        states = description.numberOfContinuousStates
        self.unit = MeUnit(
            sun=ctypes.addressof(self.sundials),
            component=model.component,
            inputs=ctypes.addressof(self.inputs),
            n_inputs=len(inputs),
            version=self.version,
            needs_completed=bool(description.modelExchange.needsCompletedIntegratorStep),
            discrete=states == 0,
            nx=max(states, 1),
            nz=description.numberOfEventIndicators,
            tolerance=tolerance or DEFAULT_TOLERANCE,
        )
        for i, name in enumerate(FUNCTIONS[self.version]):
            self.unit.fn[i] = _address(getattr(self.dll, name))
        self.address = ctypes.addressof(self.unit)
        self.function = library().dse_me_step  # the unit's step, in fmi2DoStep's shape
        if corrector is not None:
            self._terms(corrector, states)

    def _group(self, getter: str, vrs: list[int], ctype: Any, floating: bool = True) -> Inputs:
        """A group of inputs read back through ``getter``, with buffers for
        this step's and the last values."""
        n = len(vrs)
        held = [(ctypes.c_uint32 * n)(*vrs), (ctype * n)(), (ctype * n)()]
        self._buffers.append(held)
        return Inputs(
            fn=_address(getattr(self.dll, getter)),
            n=n,
            vrs=ctypes.addressof(held[0]),
            now=ctypes.addressof(held[1]),
            before=ctypes.addressof(held[2]),
            size=ctypes.sizeof(ctype),
            floating=floating,
        )

    def _terms(self, corrector: Corrector, states: int) -> None:
        """The corrector's terms as C rows of factors, and the real inputs they read."""
        inputs = [name for name, _ in corrector.inputs]
        codes = {None: 0, **{name: i + 1 for i, name in enumerate(TERM_FUNCTIONS)}}
        factors, rows = [], []  # native_me.c's rows: (state, first factor, factors, coefficient) and factors
        for state, term, coefficient in corrector.rows:
            rows.append((state, len(factors), len(term.factors), coefficient))
            factors += [
                (
                    f.variable not in corrector.states,
                    corrector.states.index(f.variable)
                    if f.variable in corrector.states
                    else inputs.index(f.variable),
                    codes[f.function],
                    f.power,
                    f.width,
                )
                for f in term.factors
            ]
        self.terms = np.array(rows, dtype=float).reshape(-1, 4)
        self.factors = np.array(factors or [(0, 0, 0, 1, 1.0)], dtype=float).reshape(-1, 5)
        self.limits = _limit_rows(corrector)
        self.term_states = np.zeros(max(states, 1))
        unit = self.unit
        unit.terms, unit.factors, unit.n_terms = self.terms.ctypes.data, self.factors.ctypes.data, len(rows)
        unit.limits, unit.n_limits = self.limits.ctypes.data, len(corrector.limits)
        unit.term_states = self.term_states.ctypes.data
        if inputs:
            self.term_inputs = self._group(
                TERM_INPUTS[self.version], [vr for _, vr in corrector.inputs], ctypes.c_double
            )
            unit.term_inputs = ctypes.addressof(self.term_inputs)

    def coefficients(self, corrector: Corrector) -> None:
        """A run's coefficients, widths and limits for the same terms and bounded
        states (a fit changes only those)."""
        self.terms[:, 3] = [coefficient for _, _, coefficient in corrector.rows]
        # a factor's width is a run's too (derivative_width), though cosim keys a layout by the terms' names,
        # which write it
        self.factors[:, 4] = [f.width for _, term, _ in corrector.rows for f in term.factors] or [1.0]
        self.limits[: len(corrector.limits)] = _limit_rows(corrector)[: len(corrector.limits)]

    def start(self, time: float, stop: float, next_event: float | None) -> None:
        """A new solver at ``time`` after initialization (the old one freed), as _make_solver builds it."""
        unit = self.unit
        unit.time, unit.max_step = time, (stop - time) / 50.0
        unit.next_defined, unit.next_event = next_event is not None, next_event or 0.0
        if library().dse_me_start(self.address) != 0:
            raise self.failure()

    def end(self) -> None:
        library().dse_me_end(self.address)

    def __del__(self) -> None:  # a run that failed, or an instance discarded, leaves its solver to free here
        self.end()

    def asked_to_stop(self) -> float | None:
        """After a failed step: the time of the event where the FMU asked to end the run, if that was why."""
        f = self.unit.failure
        return f.start if f.code == TERMINATE_ASKED else None

    def failure(self) -> ModelExchangeError:
        """What went wrong in C, worded as ModelExchangeStepper words it."""
        f = self.unit.failure
        name = [*FUNCTIONS[self.version], *self.getters][f.function]
        called = _fmu_failure(name, f.status)
        if f.code in (TERMINATE_ASKED, UNSETTLED, OFF_GRID, BAD_STEP):
            return ModelExchangeError(
                {
                    TERMINATE_ASKED: f"the FMU requested termination at t={f.start:.9g}",
                    UNSETTLED: (
                        f"the event iteration at t={f.start:.9g} did "
                        f"not settle in {MAX_EVENT_ITERATIONS} rounds"
                    ),
                    OFF_GRID: f"do_step at t={f.to:.9g} but the instance is at t={f.start:.9g}",
                    BAD_STEP: f"communication step must be > 0, got {f.to} at t={f.start:.9g}",
                }[f.code]
            )
        if f.code == CALLBACK_CALL:
            return ModelExchangeError(f"{called} while integrating from t={f.start:.9g} to t={f.to:.9g}")
        if f.code == SOLVER and f.stage == INTEGRATING:
            reason = (
                f"CVode error (code {f.solver_code}) in module {f.solver_module.decode()}, function "
                f"{f.solver_file.decode()}: {f.solver_message.decode()}"
            )
        else:
            reason = {SOLVER: "Call to CVode failed", NO_MEMORY: "out of memory"}.get(f.code, called)
        reason = " ".join(reason.split()).rstrip(".")
        if f.stage == INTEGRATING:
            return ModelExchangeError(
                f"the cvode solver failed between t={f.start:.9g} and t={f.to:.9g}: {reason}"
            )
        return ModelExchangeError(f"{STAGES[f.stage]} at t={f.start:.9g}: {reason}")


def _fmu_failure(function: str, status: int) -> str:
    """FMPy's words for a failed call, without the full stop (model_exchange._reason)."""
    from fmpy.fmi1 import FMICallException

    return str(FMICallException(function=function, status=status)).rstrip(".")
