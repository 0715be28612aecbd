"""Levenberg-Marquardt as an ask/tell machine (sweeps/fit.py), told in-process residuals: asking a candidate's
perturbations with it (eagerly) or once it is accepted (lazily) is a schedule, not an algorithm. Both visit
the same accepted points and end at the same values; lazily, a rejected candidate costs one point, not one per
parameter more."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import write_msd_search

from dse_runner.sweeps import store
from dse_runner.sweeps.expand import key_of
from dse_runner.sweeps.fit import FitProblem, LevenbergMarquardt, Parameter
from dse_runner.sweeps.fit_rounds import evaluate_points
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit

TIMES = {"early": np.linspace(0.0, 1.0, 30), "late": np.linspace(0.5, 4.0, 40)}
TRUTH = {"a": 2.0, "b": 1.3}


def residuals(point: dict[str, float], scenario: str) -> np.ndarray:
    """A decay a exp(-b t) against its truth: nonlinear in b, so a full step from far away overshoots."""
    t = TIMES[scenario]
    return point["a"] * np.exp(-point["b"] * t) - TRUTH["a"] * np.exp(-TRUTH["b"] * t)


def run(schedule) -> tuple[LevenbergMarquardt, list[tuple], int, int]:
    """Fit from far away, each round asked ``eager=schedule(round)``; returns the solver, its accepted points
    in order, how many distinct points it asked for, and in how many rounds."""
    problem = FitProblem(
        "decay",
        (Parameter("a", 0.5, 0.0, 10.0, 1e-4), Parameter("b", 6.0, 0.01, 10.0, 1e-4)),
        {},
        tuple(TIMES),
        max_iterations=40,
        tolerance=1e-10,
    )
    solver = LevenbergMarquardt(problem)
    asked: set = set()
    accepted: list[tuple] = []
    round_ = 0
    while not solver.done:
        asked.update(key_of(p) for p in solver.ask(eager=schedule(round_)))
        solver.tell(residuals)
        if solver.x is not None and (not accepted or accepted[-1] != tuple(solver.x)):
            accepted.append(tuple(solver.x))
        round_ += 1
    return solver, accepted, len(asked), round_


SCHEDULES = {
    "lazy": lambda r: False,
    "alternating": lambda r: r % 2 == 0,
    "every-third": lambda r: r % 3 == 1,
}


@pytest.mark.parametrize("name", SCHEDULES)
def test_asking_perturbations_later_changes_no_step_and_saves_the_rejected_ones(name):
    schedule = SCHEDULES[name]
    eager, eager_path, eager_points, eager_rounds = run(lambda r: True)
    other, path, points, _ = run(schedule)
    assert eager.iterations > 3 and eager.converged
    assert path == eager_path  # the same accepted points, in the same order
    first, second = eager.result(), other.result()
    assert second.values == first.values and second.sse == first.sse
    assert second.standard_error == first.standard_error  # the final Jacobian is simulated either way
    assert first.values == pytest.approx(TRUTH, rel=1e-6)
    rejected = eager_rounds - len(eager_path)  # eagerly, each round tells one candidate: accepted or rejected
    assert rejected > 0, "the test wants a fit that rejects steps"
    if name == "lazy":  # every rejected candidate's 2 perturbations saved
        assert points == eager_points - 2 * rejected
    else:
        assert points < eager_points


def test_a_point_asked_twice_in_one_sweep_runs_once_and_answers_both(tmp_path, dask_scheduler):
    """A fit or a screen may ask for one point twice in a round (the pair screen did, and the sweep raised
    KeyError on the chunk's key coming back twice): it is simulated once and both asks find its rows."""
    space = load_space(
        write_msd_search(
            tmp_path, {"strategy": "given"}, cluster={"address": dask_scheduler}, chunk_seconds=0.001
        )
    )  # a chunk per task
    p, q = {"msd.k": 12.0, "msd.c": 0.7}, {"msd.k": 14.0, "msd.c": 0.7}
    rows, _ = evaluate_points(space, [p, q, dict(p), p], None, ["position_rmse"], seconds_per_task=0.001)
    assert {k: r["status"] for k, r in rows.items()} == {
        (key_of(p), "ringdown"): "ok",
        (key_of(q), "ringdown"): "ok",
    }
    report = submit(
        space, points=[q, p, q], only=[{"ringdown"}] * 3
    )  # each in a chunk of its own, as a fit's rounds are
    assert (report.total, report.skipped) == (2, 2)
    stored = store.read_results(space.output, space.name, ["msd.k", "status"])
    assert sorted(stored["msd.k"]) == [12.0, 14.0] and stored["task_id"].is_unique


def test_a_fit_whose_start_fails_to_simulate_ends_failed_and_says_why_instead_of_raising():
    """A diagnosis fits many candidates at once; one whose start point fails (a solver limit, NaN, a diverging
    run) must be rejected by name, not abort the others."""
    problem = FitProblem("doomed", (Parameter("a", 1.0, 0.0, 2.0, 0.01),), {"b": 3.0}, ("run1", "run2"))
    solver = LevenbergMarquardt(problem)
    solver.ask()
    solver.tell(lambda point, scenario: None if scenario == "run2" else np.zeros(3))
    assert solver.done and not solver.ask()
    result = solver.result()
    assert result.error == "its start point fails to simulate on run2"
    assert result.sse == np.inf and result.point == {"a": 1.0, "b": 3.0} and not result.converged


def test_serially_correlated_residuals_widen_an_interval_as_much_as_they_are_worth():
    """A slope fitted to a line with AR(1) noise (ρ 0.8) on each of three runs: the serial (Newey-West)
    error is the white error times about √((1 + ρ)/(1 − ρ)) = 3, and so is the spread of the slope over
    many noise draws; on white noise both stay the white error. The cluster-robust error of three runs is
    a guess from three numbers, which an interval with ``serial`` never falls below."""
    from dse_runner.sweeps.fit import serial_standard_errors

    rng = np.random.default_rng(7)
    t = np.linspace(-1.0, 1.0, 400)
    jacobian = [t[:, None]] * 3  # d residual / d slope

    def noise(rho: float) -> np.ndarray:
        e = np.empty(t.size)
        e[0] = rng.normal()
        for i in range(1, t.size):
            e[i] = rho * e[i - 1] + math.sqrt(1 - rho**2) * rng.normal()
        return e

    white = 1.0 / math.sqrt(3 * float(t @ t))  # σ = 1
    for rho, factor in ((0.0, 1.0), (0.8, 3.0)):
        draws = [[noise(rho) for _ in range(3)] for _ in range(200)]
        slopes = [sum(float(t @ e) for e in runs) / (3 * float(t @ t)) for runs in draws]
        spread = float(np.std(slopes))
        errors = [serial_standard_errors(jacobian, runs)[0] for runs in draws[:40]]
        assert spread == pytest.approx(factor * white, rel=0.25)
        assert float(np.median(errors)) == pytest.approx(spread, rel=0.3)
