"""Least-squares fitting of parameters to recordings: the algorithm.

A fit minimises the sum of squares of a vector objective, its residuals
against the recordings (field data's ``fix_residuals``: the position offset at
every fix), over some parameters, by Levenberg-Marquardt with forward-difference
Jacobians. A fit never simulates anything itself: it *asks* for points and is
*told* their residuals (:class:`LevenbergMarquardt`); fit_rounds.py runs any
number of fits in lockstep as sweeps on the cluster, and the ``least_squares``
search strategy runs one as a search.

A candidate's perturbations (its Jacobian) are worth simulating only if the
candidate is accepted, and about a third are rejected: a fit asks for them with
the candidate (``eager``, when the cluster has a thread free for each) or once
the candidate is accepted, a round later. Either way the fit visits the same
points and ends at the same values.

The interval of a fitted parameter comes from the cluster-robust ("sandwich")
covariance with scenarios as clusters: residuals within a run are strongly
correlated, so treating every fix as independent would give intervals far
too narrow.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import DseError
from .domain import Point


@dataclass(frozen=True)
class Parameter:
    name: str  # instance.variable
    start: float
    lower: float
    upper: float
    step: float  # finite-difference step, in the parameter's units


@dataclass(frozen=True)
class FitProblem:
    label: str
    parameters: tuple[Parameter, ...]
    fixed: dict[str, float]  # values of the space's other swept variables
    scenarios: tuple[str, ...]  # whose residuals are fitted
    max_iterations: int = 15
    tolerance: float = 1e-4  # stop when an accepted step gains less than this fraction of the SSE


@dataclass
class FitResult:
    label: str
    names: list[str]
    values: dict[str, float]
    sse: float
    residual_count: int
    iterations: int
    converged: bool
    standard_error: dict[str, float]  # cluster-robust; inf when the data do not determine it
    at_bound: list[str]  # determined by the data, and pinned at a bound
    point: Point  # the full point: fitted values and the fixed ones
    # At the final point, per scenario of the problem (in its order): d residual / d parameter (columns in
    # ``names`` order) and the residuals. Kept so a screen can extrapolate from the fit without simulating
    # it again; in memory only, never written.
    jacobian: list[np.ndarray] = field(default_factory=list, repr=False, compare=False)
    residuals: list[np.ndarray] = field(default_factory=list, repr=False, compare=False)
    error: str | None = None  # the start point failed to simulate: nothing was fitted, the SSE is infinite

    @property
    def undetermined(self) -> list[str]:
        """Parameters no residual responds to: any value fits equally well."""
        return [n for n in self.names if math.isinf(self.standard_error[n])]

    def interval(self, z: float = 1.96, serial: bool = False) -> dict[str, tuple[float, float]]:
        """About 95 % intervals, clipped to nothing: an unbounded side stays infinite. ``serial``: at least as
        wide as the residuals' serial correlation inside each scenario makes them (serial_standard_errors):
        with few scenarios the cluster-robust error is itself a guess from a few numbers, and coloured noise
        then reads as more evidence than it is."""
        error = dict(self.standard_error)
        if serial and self.jacobian:
            within = serial_standard_errors(self.jacobian, self.residuals)
            error = {n: max(error[n], float(e)) for n, e in zip(self.names, within)}
        return {n: (self.values[n] - z * error[n], self.values[n] + z * error[n]) for n in self.names}


Residuals = Callable[[Point, str], np.ndarray | None]  # (point, scenario) -> residual vector, None if failed


class LevenbergMarquardt:
    """One fit as an ask/tell state machine: :meth:`ask` the points whose residuals
    it needs next (a candidate, and its perturbations with it or once it is accepted),
    :meth:`tell` it them."""

    def __init__(self, problem: FitProblem):
        self.problem = problem
        self.params = problem.parameters
        self.lower = np.array([p.lower for p in self.params])
        self.upper = np.array([p.upper for p in self.params])
        self.steps = np.array([p.step for p in self.params])
        start = np.clip([p.start for p in self.params], self.lower, self.upper)
        self.x: np.ndarray | None = None  # accepted point
        self.r: list[np.ndarray] = []  # its residuals per scenario
        self.jacobian: list[np.ndarray] = []  # per scenario, fixes x parameters
        self.sse = np.inf
        self.damping = 1e-3
        self.iterations = 0
        self.done = False
        self.converged = False
        self.candidate = start
        self.perturbed = self._perturbations(start)
        self.eager = True  # the last ask included the candidate's perturbations
        self.pending = False  # the candidate is accepted; its perturbations are asked next
        self.gain = np.inf  # of the accepted candidate, a fraction of the sum of squares before it
        self.error: str | None = None  # why the fit could not start

    def point(self, x: np.ndarray) -> Point:
        return {**self.problem.fixed, **{p.name: float(v) for p, v in zip(self.params, x)}}

    def _perturbations(self, x: np.ndarray) -> list[np.ndarray]:
        """x moved by one step in each parameter, inward at an upper bound."""
        moved = []
        for i in range(len(x)):
            y = x.copy()
            y[i] += self.steps[i] if x[i] + self.steps[i] <= self.upper[i] else -self.steps[i]
            moved.append(y)
        return moved

    def ask(self, eager: bool = True) -> list[Point]:
        """The points to simulate next: the candidate, with its perturbations if ``eager`` (in
        parallel, wasted when the candidate is rejected); or an accepted candidate's perturbations."""
        if self.done:
            return []
        if self.pending:
            return [self.point(y) for y in self.perturbed]
        self.eager = eager
        return [self.point(self.candidate)] + ([self.point(y) for y in self.perturbed] if eager else [])

    def tell(self, residuals: Residuals) -> None:
        if self.pending:
            self.pending = False
            self._accepted(residuals)
            return
        scenarios = self.problem.scenarios
        found = [residuals(self.point(self.candidate), s) for s in scenarios]
        if any(r is None for r in found):
            if (
                self.x is None
            ):  # nothing to fit from: the fit ends, failed, and its caller rejects what it stood for
                failed = [s for s, r in zip(scenarios, found) if r is None]
                self.error = f"its start point fails to simulate on {', '.join(failed)}"
                self._finish(converged=False)
                return
            self._reject()
            return
        sse = float(sum(np.dot(r, r) for r in found))
        if self.x is not None and not sse < self.sse:
            self._reject()
            return
        self.gain = (self.sse - sse) / self.sse if np.isfinite(self.sse) and self.sse > 0 else np.inf
        self.x, self.r, self.sse = self.candidate, found, sse
        self.damping = max(self.damping / 3.0, 1e-9)
        if self.eager:
            self._accepted(residuals)
        else:
            self.pending = True

    def _accepted(self, residuals: Residuals) -> None:
        """The accepted candidate's Jacobian (its perturbations simulated), then the next step or the end."""
        self.jacobian = self._jacobian(residuals)
        if self.gain < self.problem.tolerance:
            self._finish(converged=True)
            return
        self._next()

    def _jacobian(self, residuals: Residuals) -> list[np.ndarray]:
        """Per scenario, d residual / d parameter; a failed perturbation gives a zero column."""
        columns: list[list[np.ndarray]] = [[] for _ in self.problem.scenarios]
        for y in self.perturbed:
            delta = y - self.x
            i = int(np.flatnonzero(delta)[0])
            for k, scenario in enumerate(self.problem.scenarios):
                moved = residuals(self.point(y), scenario)
                columns[k].append(
                    np.zeros_like(self.r[k]) if moved is None else (moved - self.r[k]) / delta[i]
                )
        return [np.column_stack(c) if c else np.zeros((len(r), 0)) for c, r in zip(columns, self.r)]

    def _reject(self) -> None:
        self.damping *= 4.0
        if self.damping > 1e8:
            self._finish(converged=True)  # no downhill step left at any damping
        else:
            self._next()

    def _next(self) -> None:
        self.iterations += 1
        if self.iterations > self.problem.max_iterations or not len(self.params):
            self._finish(converged=not len(self.params))
            return
        step = self._step()
        candidate = np.clip(self.x + step, self.lower, self.upper)
        if np.all(np.abs(candidate - self.x) < 1e-3 * self.steps):
            self._finish(converged=True)
            return
        self.candidate = candidate
        self.perturbed = self._perturbations(candidate)

    def _step(self) -> np.ndarray:
        """Marquardt's step; parameters pinned at a bound the step pushes against are held."""
        J = np.vstack(self.jacobian)
        r = np.concatenate(self.r)
        free = np.ones(len(self.params), dtype=bool)
        for _ in range(len(self.params) + 1):
            step = np.zeros(len(self.params))
            A = J[:, free].T @ J[:, free]
            g = J[:, free].T @ r
            scale = np.diag(A).copy()
            scale[scale <= 0] = 1e-12 * max(float(scale.max(initial=0.0)), 1e-300)
            step[free] = np.linalg.solve(A + self.damping * np.diag(scale), -g)
            pushing = ((self.x <= self.lower) & (step < 0)) | ((self.x >= self.upper) & (step > 0))
            if not (pushing & free).any():
                return step
            free &= ~pushing
        return np.zeros(len(self.params))

    def _finish(self, converged: bool) -> None:
        self.done = True
        self.converged = converged

    def result(self) -> FitResult:
        names = [p.name for p in self.params]
        if self.error is not None:
            start = {n: float(v) for n, v in zip(names, self.candidate)}
            return FitResult(
                self.problem.label,
                names,
                start,
                np.inf,
                0,
                0,
                False,
                {n: np.inf for n in names},
                [],
                self.point(self.candidate),
                error=self.error,
            )
        if self.x is None:
            raise DseError(f"fit {self.problem.label} has not started")
        error = robust_standard_errors(self.jacobian, self.r)
        at_bound = [
            n
            for n, v, lo, hi, st, e in zip(names, self.x, self.lower, self.upper, self.steps, error)
            if (v - lo < 1e-3 * st or hi - v < 1e-3 * st) and np.isfinite(e)
        ]
        return FitResult(
            self.problem.label,
            names,
            {n: float(v) for n, v in zip(names, self.x)},
            self.sse,
            int(sum(len(r) for r in self.r)),
            self.iterations,
            self.converged,
            dict(zip(names, error)),
            at_bound,
            self.point(self.x),
            list(self.jacobian),
            list(self.r),
        )


def robust_standard_errors(jacobian: list[np.ndarray], residuals: list[np.ndarray]) -> np.ndarray:
    """Sandwich covariance with each scenario a cluster: (J'J)^-1 (sum_s J_s' r_s r_s' J_s) (J'J)^-1."""
    if not jacobian or jacobian[0].shape[1] == 0:
        return np.zeros(0)
    J = np.vstack(jacobian)
    bread = J.T @ J
    identifiable = np.diag(bread) > 1e-12 * max(float(np.diag(bread).max()), 1e-300)
    errors = np.full(J.shape[1], np.inf)
    if not identifiable.any():
        return errors
    inverse = np.linalg.pinv(bread[np.ix_(identifiable, identifiable)])
    meat = sum(
        np.outer(Js[:, identifiable].T @ rs, Js[:, identifiable].T @ rs)
        for Js, rs in zip(jacobian, residuals)
    )
    clusters = len(jacobian)
    correction = clusters / (clusters - 1) if clusters > 1 else 1.0
    covariance = correction * inverse @ meat @ inverse
    errors[identifiable] = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    return errors


def serial_standard_errors(jacobian: list[np.ndarray], residuals: list[np.ndarray]) -> np.ndarray:
    """Newey and West's sandwich (1987): each scenario's scores J_t' r_t summed with those up to L samples
    apart, weighted 1 − l/(L + 1), so that residuals correlated over neighbouring samples (coloured noise,
    an unmodelled slow wobble) count for what they are worth. L: twice the residuals' integrated
    autocorrelation time as an AR(1) reads it, (1 + ρ)/(1 − ρ) from their lag-1 correlation ρ, at least
    Newey and West's 4·(n/100)^(2/9) and at most a quarter of the shortest scenario."""
    if not jacobian or jacobian[0].shape[1] == 0:
        return np.zeros(0)
    J = np.vstack(jacobian)
    r = np.concatenate(residuals)
    bread = J.T @ J
    identifiable = np.diag(bread) > 1e-12 * max(float(np.diag(bread).max()), 1e-300)
    errors = np.full(J.shape[1], np.inf)
    if not identifiable.any() or r.size < 3:
        return errors
    rho = float(sum(float(x[1:] @ x[:-1]) for x in residuals if x.size > 1) / max(float(r @ r), 1e-300))
    rho = min(max(rho, 0.0), 0.99)
    shortest = min(x.size for x in residuals)
    lags = int(min(max(math.ceil(2 * (1 + rho) / (1 - rho)), 4 * (r.size / 100) ** (2 / 9)), shortest // 4))
    meat = np.zeros((int(identifiable.sum()),) * 2)
    for Js, rs in zip(jacobian, residuals):
        scores = Js[:, identifiable] * rs[:, None]
        meat += scores.T @ scores
        for lag in range(1, lags + 1):
            if lag >= len(rs):
                break
            cross = scores[lag:].T @ scores[:-lag]
            meat += (1.0 - lag / (lags + 1)) * (cross + cross.T)
    inverse = np.linalg.pinv(bread[np.ix_(identifiable, identifiable)])
    covariance = inverse @ meat @ inverse
    errors[identifiable] = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    return errors
