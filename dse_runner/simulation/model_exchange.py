"""Model-exchange FMUs stepped from communication point to communication point.

A model-exchange (ME) FMU has no ``doStep``: the importer integrates its states.
The co-simulation master drives every instance as a stepper, so this module
wraps an ME instance in one, integrating it with FMPy's own solvers (CVode from
SUNDIALS, or forward Euler) and handling time, state and step events the way
``fmpy.simulation.simulateME`` does. That way the same FMU gives the same answer
stand-alone in FMPy and inside a co-simulation.

Inputs are held constant over a step (zero-order hold). The master may set new
input values just before each step; when they differ from the values the solver
last started from, the start of the step is an input event as in ``simulateME``:
an event iteration, then a solver restart. Restarting only then matters: CVode
steps past each output point and interpolates back, so a changed input must
restart it, but restarting at every point costs accuracy (each restart begins
again at first order): over ten times the error of an uninterrupted run for the
mass-spring-damper over 500 steps.

Derivative terms (derivative_terms.py) are added here, to what the FMU's derivatives return, every time the
solver asks for them: the solver integrates the corrected equations. Without terms the solver calls the FMU
directly, as before.
"""

from __future__ import annotations

import ctypes
import functools
import math
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from ..errors import DseError
from .derivative_terms import Corrector

SOLVERS = ("cvode", "euler")
DEFAULT_TOLERANCE = 1e-5  # simulateME's default relative tolerance
MAX_EVENT_ITERATIONS = 1000


class ModelExchangeError(DseError):
    """An ME instance failed: an FMU error status, a solver failure, or the FMU asked to stop."""


class TerminationAsked(ModelExchangeError):
    """The FMU asked to end the run at ``time`` (terminateSimulation): a failure in initialization, and in a
    step the end of the run there (steppers.ModelExchange)."""

    def __init__(self, time: float):
        super().__init__(f"the FMU requested termination at t={time:.9g}")
        self.time = time


class _HeldInputs:
    """The input object FMPy's solvers call ``apply`` on. The master sets inputs itself
    before each step and they are held over it, so there is nothing to apply."""

    def apply(
        self, time: float, continuous: bool = True, discrete: bool = True, after_event: bool = False
    ) -> None:
        pass


@functools.cache
def _guarded_cvode() -> type:
    """FMPy's CVodeSolver with callbacks that stop CVode when the FMU fails.

    ctypes prints and swallows an exception raised inside a callback, so with the
    plain solver an FMU error status in fmi2GetDerivatives would let CVode go on
    with garbage. Here the callback keeps the exception and returns -1, which
    makes CVode stop with an error; the stepper then reports the FMU's failure.
    Imported lazily: loading SUNDIALS fails on platforms FMPy ships no build for.
    """
    from fmpy.sundials import CVodeSolver

    class GuardedCVode(CVodeSolver):
        failure: Exception | None = None

        def f(self, t, y, ydot, user_data):
            return self._guard(super().f, t, y, ydot, user_data)

        def g(self, t, y, gout, user_data):
            return self._guard(super().g, t, y, gout, user_data)

        def _guard(self, callback, *args) -> int:
            try:
                return callback(*args)
            except Exception as e:  # noqa: BLE001  (handed back to the stepper)
                self.failure = self.failure or e
                return -1

    return GuardedCVode


def _earliest(target: float, other: float | None) -> float:
    """``other`` if it comes clearly before ``target``; a near tie goes to ``target`` so
    steps land exactly on communication points."""
    if other is None or other > target or math.isclose(other, target):
        return target
    return other


def input_groups(description: Any) -> list[tuple[str, list[int]]] | None:
    """The inputs' value references grouped by the fmpy getter that reads them, or None
    if some input is of a kind we do not read back (an FMI 3 array, a binary, a clock)."""
    fmi2 = description.fmiVersion == "2.0"
    groups: dict[str, list[int]] = {}
    for variable in description.modelVariables:
        if variable.causality != "input":
            continue
        if variable.type in ("Binary", "Clock") or getattr(variable, "dimensions", None):
            return None
        getter = {
            "Real": "getReal",
            "Integer": "getInteger",
            "Enumeration": "getInteger" if fmi2 else "getInt64",
        }.get(variable.type, f"get{variable.type}")
        groups.setdefault(getter, []).append(variable.valueReference)
    return list(groups.items())


def _reason(error: Exception) -> str:
    return " ".join(str(error).split()).rstrip(".") or type(error).__name__


class ModelExchangeStepper:
    """Drives one ME instance from communication point to communication point."""

    def __init__(
        self,
        model: Any,
        description: Any,
        solver: str = "cvode",
        tolerance: float | None = None,
        euler_step: float | None = None,
        set_stop_time: bool = True,
        corrector: Corrector | None = None,
    ):
        """``model``: an instantiated fmpy FMU2Model or FMU3Model whose start values the
        caller has set; ``description``: its fmpy ModelDescription. ``tolerance`` is
        CVode's relative tolerance (FMPy's default 1e-5); ``euler_step`` the fixed
        Euler step (default: each communication step in one go); ``corrector`` the
        derivative terms added to the FMU's derivatives (none: the FMU's own)."""
        if solver not in SOLVERS:
            raise ModelExchangeError(f"unknown ME solver {solver!r}: use one of {', '.join(SOLVERS)}")
        if euler_step is not None and not euler_step > 0:
            raise ModelExchangeError(f"euler_step must be > 0, got {euler_step}")
        if description.modelExchange is None:
            raise ModelExchangeError(f"{description.modelName} is not a model-exchange FMU")
        self.model = model
        self.description = description
        self.solver_name = solver
        self.tolerance = tolerance
        self.euler_step = euler_step
        self.set_stop_time = set_stop_time  # False: the FMU is not told the stop time (FMPy's set_stop_time)
        self.fmi3 = description.fmiVersion.startswith("3.")
        self.time = 0.0
        self.stop = math.inf
        self.next_event: float | None = None
        self._solver: Any = None
        self._inputs: tuple | None = None  # the input values the solver last started from
        self._input_groups = input_groups(description)
        self.corrector = corrector if corrector is not None and not corrector.empty else None
        self._term_inputs: list[float] = []  # the inputs the terms read, held over the step as the FMU's are
        self._states = np.zeros(description.numberOfContinuousStates)
        # Its integrator in C (a native_me.NativeIntegrator, set by steppers.ModelExchange for
        # the native loop), which the loop steps instead of do_step: this stepper then
        # initialises, starts it and terminates.
        self.native: Any = None

    def use_coefficients(self, corrector: Corrector) -> None:
        """Other coefficients for the same terms, for the next run (a fit changes only those)."""
        self.corrector = corrector
        if self.native is not None:
            self.native.coefficients(corrector)

    # ---- life cycle -------------------------------------------------------

    def setup(self, start: float, stop: float) -> None:
        """Set the experiment up (FMI 2), before the caller sets start values: some FMUs load their
        defaults in fmi2SetupExperiment."""
        if not stop > start:
            raise ModelExchangeError(f"stop time {stop} must be after start time {start}")
        self.time, self.stop = start, stop
        if not self.fmi3:
            with self._reported("setting up the experiment"):
                self.model.setupExperiment(
                    tolerance=self.tolerance, startTime=start, stopTime=stop if self.set_stop_time else None
                )

    def enter_initialization(self, start: float, stop: float) -> None:
        """Start the experiment (after :meth:`setup` and the start values); parameters may still
        be set until exit_initialization."""
        self.time, self.stop = start, stop
        with self._reported("entering initialization mode"):
            if self.fmi3:
                self.model.enterInitializationMode(
                    tolerance=self.tolerance, startTime=start, stopTime=stop if self.set_stop_time else None
                )
            else:
                self.model.enterInitializationMode()

    def exit_initialization(self) -> None:
        """Leave initialization through the initial event iteration, then set up the solver
        at the initial states (as simulateME does before its loop)."""
        with self._reported("exiting initialization mode"):
            self.model.exitInitializationMode()
            self._update_discrete_states()
            self.model.enterContinuousTimeMode()
            if self.native is not None:
                self.native.start(self.time, self.stop, self.next_event)
                return
            if self.corrector is not None and self.corrector.inputs:
                self._term_inputs = self._read_term_inputs()
            self._solver = self._make_solver()
            self._inputs = self._read_inputs()

    def do_step(self, t: float, h: float) -> None:
        """Integrate from ``t`` to ``t + h``, stopping at every event on the way."""
        if self._solver is None:
            raise ModelExchangeError("do_step called before exit_initialization")
        if not math.isclose(t, self.time):
            raise ModelExchangeError(f"do_step at t={t:.9g} but the instance is at t={self.time:.9g}")
        if not h > 0:
            raise ModelExchangeError(f"communication step must be > 0, got {h} at t={t:.9g}")
        end = t + h
        with self._reported("handling an input change"):
            inputs = self._read_inputs()
            if inputs is None or inputs != self._inputs:
                self._event_iteration()
            self._inputs = inputs
            if self.corrector is not None and self.corrector.inputs:
                self._term_inputs = self._read_term_inputs()
        while self.time < end and not math.isclose(self.time, end):
            self._advance(end, self.euler_step or h)
        self.time = end

    def terminate(self) -> None:
        if self.native is not None:
            self.native.end()
        with self._reported("terminating"):
            self.model.terminate()
        self._solver = None

    # ---- integration ------------------------------------------------------

    def _make_solver(self) -> Any:
        """The solver simulateME would build, with the same arguments."""
        model, description = self.model, self.description
        common = {
            "nx": description.numberOfContinuousStates,
            "nz": description.numberOfEventIndicators,
            "get_x": model.getContinuousStates,
            "set_x": model.setContinuousStates,
            "get_dx": self._derivatives_getter(),
            "get_z": model.getEventIndicators,
            "input": _HeldInputs(),
        }
        if self.solver_name == "euler":
            from fmpy.simulation import ForwardEuler

            return ForwardEuler(**common)
        return _guarded_cvode()(
            get_nominals=model.getNominalsOfContinuousStates,
            set_time=model.setTime,
            startTime=self.time,
            maxStep=(self.stop - self.time) / 50.0,
            relativeTolerance=self.tolerance or DEFAULT_TOLERANCE,
            **common,
        )

    def _derivatives_getter(self) -> Any:
        """What the solver calls for the derivatives: the FMU's own function, or (with terms) one that adds
        the terms at the states the solver has just set."""
        own = self.model.getContinuousStateDerivatives if self.fmi3 else self.model.getDerivatives
        if self.corrector is None:
            return own
        corrector, states, model = self.corrector, self._states, self.model
        pointer = states.ctypes.data_as(ctypes.POINTER(ctypes.c_double))

        def corrected(derivatives: Any, n: int) -> None:  # derivatives: a ctypes pointer, indexed in place
            own(derivatives, n)
            model.getContinuousStates(pointer, n)
            corrector.add(states.tolist(), self._term_inputs, derivatives)

        return corrected

    def _read_term_inputs(self) -> list[float]:
        vrs = [vr for _, vr in self.corrector.inputs]
        return list(self.model.getFloat64(vrs) if self.fmi3 else self.model.getReal(vrs))

    def _advance(self, end: float, euler_step: float) -> None:
        """One pass of simulateME's loop: integrate to the next of the step's end, the
        next time event or (Euler) the next fixed step; then handle any event there."""
        target = _earliest(end, self.time + euler_step if self.solver_name == "euler" else None)
        due = self.next_event if self.next_event is not None and self.next_event > self.time else None
        target = _earliest(target, due)
        time_event = due is not None and math.isclose(target, due)
        state_event = self._integrate(target)
        with self._reported("completing an integrator step"):
            self.model.setTime(self.time)
            step_event = self._completed_integrator_step()
            if time_event or state_event or step_event:
                self._event_iteration()

    def _integrate(self, target: float) -> bool:
        """Run the solver from self.time towards ``target``; True at a state event
        (then self.time is the event's time, which may be before ``target``)."""
        start = self.time
        try:
            state_event, _roots, self.time = self._solver.step(start, target)
        except Exception as e:  # FMPy raises plain exceptions
            failure = getattr(self._solver, "failure", None)
            if failure is not None:
                raise ModelExchangeError(
                    f"{_reason(failure)} while integrating from t={start:.9g} to t={target:.9g}"
                ) from e
            raise ModelExchangeError(
                f"the {self.solver_name} solver failed between t={start:.9g} and t={target:.9g}: {_reason(e)}"
            ) from e
        return bool(state_event)

    def _completed_integrator_step(self) -> bool:
        """Tell the FMU an integrator step is done, if it wants to know; True if it asks
        for an event (a step event)."""
        if not self.description.modelExchange.needsCompletedIntegratorStep:
            return False
        step_event, terminate = self.model.completedIntegratorStep()
        if terminate:
            raise TerminationAsked(self.time)
        return bool(step_event)

    def _read_inputs(self) -> tuple | None:
        """Every input's current value, or None if some input cannot be read back (then
        each step counts as an input change)."""
        if self._input_groups is None:
            return None
        return tuple(tuple(getattr(self.model, getter)(vrs)) for getter, vrs in self._input_groups)

    # ---- events -----------------------------------------------------------

    def _event_iteration(self) -> None:
        """Event mode, discrete states to their fixed point, back to continuous time, and
        a solver restart: states or their derivatives may have jumped."""
        self.model.enterEventMode()
        self._update_discrete_states()
        self.model.enterContinuousTimeMode()
        self._solver.reset(self.time)

    def _update_discrete_states(self) -> None:
        update = self.model.updateDiscreteStates if self.fmi3 else self.model.newDiscreteStates
        for _ in range(MAX_EVENT_ITERATIONS):
            needed, terminate, _nominals, _values, defined, next_time = update()
            if terminate:
                raise TerminationAsked(self.time)
            if not needed:
                self.next_event = next_time if defined else None
                return
        raise ModelExchangeError(
            f"the event iteration at t={self.time:.9g} did not settle in {MAX_EVENT_ITERATIONS} rounds"
        )

    @contextmanager
    def _reported(self, doing: str) -> Iterator[None]:
        """Turn FMPy's exceptions (an FMU error status) into one-line ModelExchangeErrors."""
        try:
            yield
        except DseError:
            raise
        except Exception as e:  # FMICallException and friends
            raise ModelExchangeError(f"{doing} at t={self.time:.9g}: {_reason(e)}") from e
