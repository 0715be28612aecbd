"""Closed-loop search (issue 14) on a real cluster: a Dask scheduler process and two worker processes.

Most tests calibrate the mass-spring-damper of jobs/msd (a model-exchange FMU built from C) against
its recording: the truth is k = 14 N/m, c = 0.8 N s/m, and the recorded position carries Gaussian
noise of sigma 2 mm, so no point can score much below an rmse of 2 mm (the least-squares fit scores
1.77 mm). One simulation takes milliseconds. The failure tests use tests/fmus/cliff, a bowl whose
fmi2DoStep fails over part of its parameter space.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, strict_loads, write_msd_search, write_yaml

from dse_runner.errors import DseError
from dse_runner.sweeps import store
from dse_runner.sweeps.history import load_history
from dse_runner.sweeps.rank import rank
from dse_runner.sweeps.search import BATCH
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import load_status, submit

MSD = REPO / "jobs" / "msd"
CLIFF = REPO / "tests" / "fmus" / "cliff"
TRUTH = {"msd.k": 14.0, "msd.c": 0.8}
BOUNDS = {"msd.k": (5.0, 25.0), "msd.c": (0.2, 2.0)}
NOISE = 0.002  # m: the recording's noise sigma, the floor of the rmse


def msd_space(folder: Path, search: dict, address: str, **changes) -> Path:
    """The msd calibration over continuous k and c, as a search; ``changes`` replace top-level keys."""
    return write_msd_search(folder, search, cluster={"address": address}, **changes)


def cliff_space(folder: Path, search: dict, address: str, **changes) -> Path:
    """tests/fmus/cliff alone, no scenario: y = (a - 3)^2 + (b - 1)^2, failing where a > 7."""
    spec = {
        "name": "cliff",
        "multimodel": {"fmus": {"cliff": str(CLIFF)}},
        "parameters": {"cliff.a": {"low": 0, "high": 10}, "cliff.b": {"low": 0, "high": 2}},
        "objectives": {"y": {"signal": "cliff.y", "reduce": "final"}},
        "search": search,
        "output": str(folder / "out"),
        "cluster": {"address": address},
        "keep_trajectories": 0,
    }
    return write_yaml(folder, {**spec, **changes})


def results(space, *columns: str) -> pd.DataFrame:
    return store.read_results(space.output, space.name, ["status", "error", *space.parameters, *columns])


# ---- each strategy finds the optimum ----------------------------------------------------------------

# Tolerances on the best point, (best rmse [m], |k - 14| [N/m], |c - 0.8| [N s/m]), set from runs of every
# strategy over 40-80 seeds against this landscape (3 points in flight, as on this cluster): each band
# passes for every seed measured. Measured again over seeds 0-29 with results told in ask order, 4 points
# asked ahead (the default since): tpe and cmaes pass for all 30, gp for 29 (seed 18 ends at c = 1.00, rmse
# 4.5 mm, also with Optuna's own GP settings; told as they come, 3 in flight, it passes). Strategies that
# learn from results come within 2 noise sigmas; space-filling samples (and the GA, which with 10
# generations of 10 does little better) within 4 sigmas and about 1 N/m. A sample of 5 random points fails
# the space-filling band for 7 of 8 seeds, and 60 random points fail the model-based band for about half the
# seeds, so neither band passes whatever is asked.
SPACE_FILLING = (4 * NOISE, 1.5, 0.4)
MODEL_BASED = (2 * NOISE, 0.6, 0.2)
CALIBRATION = (0.9 * NOISE, 0.1, 0.03)  # least squares reaches the noise floor: its fit is 14.03, 0.793

STRATEGIES = [
    ("random", 100, {}, SPACE_FILLING),
    ("sobol", 100, {}, SPACE_FILLING),
    ("lhs", 100, {}, SPACE_FILLING),
    # INTO-CPS's option names; "uniform" spreads the first generation as a Latin hypercube. With the first
    # generation random instead, 1 seed in 100 (seed 0, as it happens) ends at c = 1.24.
    ("genetic", 100, {"initialPopulation": 10, "initialPopulationDistribution": "uniform"}, SPACE_FILLING),
    ("tpe", 80, {}, MODEL_BASED),
    ("gp", 30, {}, MODEL_BASED),  # each ask fits a Gaussian process: ~0.5 s on the client
    ("cmaes", 100, {}, MODEL_BASED),
    ("least_squares", 40, {}, CALIBRATION),
]


@pytest.mark.parametrize("name, budget, options, tolerance", STRATEGIES, ids=[s[0] for s in STRATEGIES])
def test_each_strategy_finds_the_calibrations_optimum(
    tmp_path, dask_scheduler, name, budget, options, tolerance
):
    space = load_space(
        msd_space(tmp_path, {"strategy": name, "max_points": budget, **options}, dask_scheduler)
    )
    report = submit(space)
    search = report.search
    assert (search.failed, search.infeasible, report.failed) == (0, 0, 0), report.errors
    if name == "least_squares":  # it stops when a step gains nothing: converged well within the budget
        assert search.stopped == "strategy" and search.points < budget
    else:
        assert search.stopped == "budget" and search.points == budget

    best_rmse, k_tolerance, c_tolerance = tolerance
    point = search.best_point
    assert search.best <= best_rmse, (search.best, point)
    assert abs(point["msd.k"] - TRUTH["msd.k"]) <= k_tolerance, point
    assert abs(point["msd.c"] - TRUTH["msd.c"]) <= c_tolerance, point

    # Every point is ordinary rows in the store, simulated once (a point asked again is told its result and
    # not counted), inside the bounds; the search's best is the store's, and the ranking's.
    rows = results(space, "position_rmse")
    assert len(rows) == report.ran == search.points and rows["task_id"].is_unique
    assert (rows["status"] == "ok").all()
    for parameter, (low, high) in BOUNDS.items():
        assert rows[parameter].between(low, high).all()
    assert rows["position_rmse"].min() == search.best
    assert rank(space.output, space.name).best == pytest.approx(point, rel=1e-12)
    if name == "lhs":  # a Latin hypercube of the budget's size: one point in each 1/budget of each range
        for parameter, (low, high) in BOUNDS.items():
            strata = np.floor((rows[parameter] - low) / (high - low) * budget)
            assert strata.nunique() == budget


def test_least_squares_on_a_residuals_objective_alone_ranks_by_its_sum_of_squares(tmp_path, dask_scheduler):
    """A calibration written as a newcomer writes it, the residuals and nothing else (issue 63): the space
    adds their sum of squares, ranks by it, and the ranking's best is the fit's own point, at the truth."""
    residuals = {"position": {"signal": "msd.x", "recorded": "x", "metric": "residuals"}}
    path = msd_space(tmp_path, {"strategy": "least_squares"}, dask_scheduler, objectives=residuals)
    space = load_space(path)
    assert space.spec.ranking.objective == "position_sum_squares"
    report = submit(space)
    assert report.search.stopped == "strategy" and report.failed == 0
    ranking = rank(space.output, space.name)
    assert ranking.objective == "position_sum_squares"
    assert ranking.best == pytest.approx(report.search.best_point, rel=1e-12)
    assert abs(ranking.best["msd.k"] - TRUTH["msd.k"]) <= 0.1
    assert abs(ranking.best["msd.c"] - TRUTH["msd.c"]) <= 0.03
    rows = results(space, "position", "position_sum_squares")
    squares = rows["position"].map(lambda r: float(np.sum(np.square(r))))
    assert np.allclose(squares, rows["position_sum_squares"], rtol=1e-12)  # it ranks what LM minimises


# ---- several objectives -----------------------------------------------------------------------------


def test_nsga2_returns_a_pareto_front_of_the_two_objectives(tmp_path, dask_scheduler):
    """Fitting the recording (c near 0.8) and ringing little (c high) conflict: the front trades them."""
    path = msd_space(
        tmp_path,
        {"strategy": "nsga2", "max_points": 40, "population_size": 10},
        dask_scheduler,
        objectives={
            "position_rmse": {"signal": "msd.x", "recorded": "x", "metric": "rmse"},
            "ringing": {"signal": "msd.x", "reduce": "rms"},
        },
        ranking={"pareto": ["position_rmse", "ringing"]},
    )
    space = load_space(path)
    report = submit(space)
    assert (report.search.points, report.search.stopped, report.failed) == (40, "budget", 0)

    ranking = rank(space.output, space.name)
    front = ranking.pareto[["position_rmse", "ringing"]].to_numpy()
    every = ranking.totals[["position_rmse", "ringing"]].to_numpy()
    assert len(front) >= 2 and len(every) == report.ran
    for values in front:  # no point of the search dominates a front point
        dominated = np.all(every <= values, axis=1) & np.any(every < values, axis=1)
        assert not dominated.any(), values
    # The front spans the conflict: its ends are the best of each objective over all points.
    assert front[:, 0].min() == every[:, 0].min() and front[:, 1].min() == every[:, 1].min()
    assert front[:, 0].argmin() != front[:, 1].argmin()


# ---- resume -----------------------------------------------------------------------------------------


def asked_points(space) -> list[tuple[float, float]]:
    history = load_history(space.output, space.name)
    return [(p.point["msd.k"], p.point["msd.c"]) for p in history.points]


# Reproducible (the default, 4 points asked ahead): the same points whatever the timing. Asynchronous: only
# with batch 1 is there one ask/tell order, so that the search in one go asks the same points.
@pytest.mark.parametrize(
    "order, batch",
    [("reproducible", {}), ("asynchronous", {"batch": 1})],
    ids=["reproducible", "asynchronous"],
)
def test_a_larger_budget_replays_the_search_and_simulates_only_new_points(
    tmp_path, dask_scheduler, order, batch
):
    search = {"strategy": "tpe", "seed": 7, "order": order, **batch, "n_startup_trials": 5}
    first = load_space(msd_space(tmp_path / "resumed", {**search, "max_points": 8}, dask_scheduler))
    report = submit(first)
    assert (report.ran, report.search.points, report.search.reused, report.search.replayed) == (
        8,
        8,
        0,
        False,
    )

    more = load_space(msd_space(tmp_path / "resumed", {**search, "max_points": 20}, dask_scheduler))
    report = submit(more)
    assert report.search.replayed and not report.search.notes
    assert (report.ran, report.search.points, report.search.reused, report.search.stopped) == (
        12,
        20,
        8,
        "budget",
    )
    assert len(results(more)) == 20

    # The same search in one go, in another store, asks the very same points in the same order.
    fresh = load_space(msd_space(tmp_path / "fresh", {**search, "max_points": 20}, dask_scheduler))
    once = submit(fresh)
    assert once.ran == 20 and not once.search.replayed
    assert asked_points(more) == asked_points(fresh)
    resumed_rows = results(more, "position_rmse").sort_values("task_id").reset_index(drop=True)
    fresh_rows = results(fresh, "position_rmse").sort_values("task_id").reset_index(drop=True)
    pd.testing.assert_frame_equal(
        resumed_rows[["task_id", "msd.k", "msd.c", "position_rmse"]],
        fresh_rows[["task_id", "msd.k", "msd.c", "position_rmse"]],
    )
    assert (report.search.best, report.search.best_point) == (once.search.best, once.search.best_point)

    # The same budget again: everything is replayed, nothing simulated, no row written, and the status (what
    # the dashboard and the report show) stays that of the submission that simulated the last 12 points.
    files = {p: p.stat().st_mtime_ns for p in (more.output / "results").rglob("*.parquet")}
    status = load_status(more.output, more.name)
    again = submit(more)
    assert (again.ran, again.search.points, again.search.reused, again.search.replayed) == (0, 20, 20, True)
    assert again.search.best_point == report.search.best_point
    assert {p: p.stat().st_mtime_ns for p in (more.output / "results").rglob("*.parquet")} == files
    assert load_status(more.output, more.name) == status and status.ran == 12


# ---- the order results are told in ------------------------------------------------------------------

SLEEPER = REPO / "tests" / "fmus" / "sleeper"


def timed_space(folder: Path, search: dict, cluster: dict) -> Path:
    """tests/fmus/cliff beside tests/fmus/sleeper, whose ``pause`` is swept too (0-50 ms in each of 10
    steps): each point takes its own wall time, 0-0.5 s, so points finish in another order than they
    were asked (with seed 11 the first six take 0.23, 0.24, 0.47, 0.05, 0.08 and 0.06 s)."""
    spec = {
        "name": "timed",
        "multimodel": {"fmus": {"cliff": str(CLIFF), "sleeper": str(SLEEPER)}},
        "experiment": {"stop_time": 1, "step": 0.1},
        "parameters": {
            "cliff.a": {"low": 0, "high": 6},
            "cliff.b": {"low": 0, "high": 2},
            "sleeper.pause": {"low": 0, "high": 0.05},
        },
        "objectives": {"y": {"signal": "cliff.y", "reduce": "final"}},
        "search": {"seed": 11, "max_points": 20, **search},
        "output": str(folder / "out"),
        "cluster": cluster,
        "keep_trajectories": 0,
    }
    return write_yaml(folder, spec)


@pytest.mark.parametrize("name", ["gp", "tpe"])
def test_a_seeded_search_asks_the_same_points_whatever_the_workers_timing(tmp_path, dask_scheduler, name):
    """Results are told in the order the points were asked, and point n is asked right after the tells
    of points 0 .. n - BATCH: on the test cluster's two workers and on a local cluster of three that
    the spec starts, whose points finish in other orders, the same seed and spec ask the same points
    and are told the same results."""
    search = {"strategy": name, "n_startup_trials": 4, "max_points": 14}
    spaces = [
        load_space(timed_space(tmp_path / "two", search, {"address": dask_scheduler})),
        load_space(timed_space(tmp_path / "three", search, {"n_workers": 3})),
    ]
    reports = [submit(space) for space in spaces]
    assert [(r.workers, r.search.points, r.search.stopped, r.failed) for r in reports] == [
        (2, 14, "budget", 0),
        (3, 14, "budget", 0),
    ]

    histories = [load_history(space.output, space.name).points for space in spaces]
    for history in histories:
        assert [p.told for p in history] == list(range(14))
        assert [p.asked_after for p in history] == [max(0, n - BATCH + 1) for n in range(14)]
    assert [p.point for p in histories[0]] == [p.point for p in histories[1]]
    assert [p.values for p in histories[0]] == [p.values for p in histories[1]]
    columns = ["task_id", "cliff.a", "cliff.b", "sleeper.pause", "y"]
    rows = [results(space, "y").sort_values("task_id").reset_index(drop=True)[columns] for space in spaces]
    pd.testing.assert_frame_equal(rows[0], rows[1])
    assert reports[0].search.best_point == reports[1].search.best_point


def test_the_asynchronous_order_tells_each_result_as_it_comes(tmp_path, dask_scheduler):
    """order: asynchronous keeps the cluster's threads + 1 points in flight and tells each result when it
    comes: points that take less time are told before points asked earlier."""
    space = load_space(
        timed_space(tmp_path, {"strategy": "tpe", "order": "asynchronous"}, {"address": dask_scheduler})
    )
    report = submit(space)
    assert (report.search.points, report.search.stopped, report.failed) == (20, "budget", 0)
    history = load_history(space.output, space.name).points
    told = [p.told for p in history]
    assert sorted(told) == list(range(20)) and told != list(range(20)), told
    assert all(p.asked_after >= p.number - 2 for p in history)  # 3 in flight: 2 threads + 1


def test_the_order_is_checked_when_the_spec_loads(tmp_path):
    path = msd_space(tmp_path, {"strategy": "tpe", "order": "as_they_come"}, "tcp://127.0.0.1:1")
    with pytest.raises(DseError, match=r"search\.order: .*'reproducible' or 'asynchronous'"):
        load_space(path)


# ---- constraints ------------------------------------------------------------------------------------

CONSTRAINT = "msd.k * msd.c <= 15"  # cuts off about half the box; the truth (11.2) is inside


@pytest.mark.parametrize("name", ["tpe", "random"])
def test_constraints_are_never_violated(tmp_path, dask_scheduler, name):
    space = load_space(
        msd_space(tmp_path, {"strategy": name, "max_points": 30}, dask_scheduler, constraints=[CONSTRAINT])
    )
    report = submit(space)
    search = report.search
    rows = results(space)
    assert len(rows) == report.ran == search.points == 30  # infeasible points do not use the budget
    assert (rows["msd.k"] * rows["msd.c"] <= 15).all()
    assert (rows["msd.k"] * rows["msd.c"] > 12).any()  # the search does go near the boundary

    infeasible = [p.point for p in load_history(space.output, space.name).points if p.state == "infeasible"]
    assert len(infeasible) == search.infeasible
    assert all(p["msd.k"] * p["msd.c"] > 15 for p in infeasible)
    if name == "tpe":  # Optuna proposes over the whole box; each rejected point is told as a failed trial
        assert search.infeasible > 0
    else:  # a sampler draws again until a point passes: the constraints never reach the runner
        assert search.infeasible == 0


@pytest.mark.parametrize("name", ["tpe", "genetic"])
def test_objective_constraints_steer_the_search_and_its_best(tmp_path, dask_scheduler, name):
    """A ranking constraint on the objectives (here: keep out of a disc of radius 1 around the free optimum
    y = 0) is told to constrained strategies, and the search's best is the best point that keeps it."""
    options = {"population": 10} if name == "genetic" else {}
    space = load_space(
        cliff_space(
            tmp_path,
            {"strategy": name, "max_points": 40, "seed": 3, **options},
            dask_scheduler,
            parameters={"cliff.a": {"low": 0, "high": 6}, "cliff.b": {"low": 0, "high": 2}},
            ranking={"objective": "y", "constraints": ["y >= 1"]},
        )
    )
    search = submit(space).search
    rows = results(space, "y")
    kept = rows[rows["y"] >= 1]
    assert search.best == kept["y"].min() and search.best >= 1  # never the free optimum
    assert (rows["y"] < 1).any() or name == "genetic"  # TPE does try inside the disc ...
    told = sorted(
        (p for p in load_history(space.output, space.name).points if p.state == "ok"), key=lambda p: p.told
    )
    late = told[len(told) // 2 :]
    assert sum(p.values["y"] >= 1 for p in late) >= 0.6 * len(late)  # ... and learns to keep out of it
    assert search.best < 1.6  # near the disc's edge: the constrained optimum is 1


# ---- failed simulations -----------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["tpe", "genetic", "random"])
def test_failed_simulations_are_told_and_the_search_goes_on(tmp_path, dask_scheduler, name):
    options = {"population": 10} if name == "genetic" else {}
    space = load_space(cliff_space(tmp_path, {"strategy": name, "max_points": 30, **options}, dask_scheduler))
    report = submit(space)
    search = report.search
    assert (search.points, search.stopped) == (30, "budget")

    rows = results(space, "y")
    failed = rows[rows["status"] == "failed"]
    ok = rows[rows["status"] == "ok"]
    assert len(failed) == report.failed == search.failed > 0 and len(ok) == report.ok
    assert (failed["cliff.a"] > 7).all() and (ok["cliff.a"] <= 7).all()
    assert failed["error"].str.contains("is over the cliff").all() and failed["y"].isna().all()

    told = load_history(space.output, space.name).points
    assert sum(p.state == "failed" for p in told) >= search.failed  # a failed point asked again is told again
    assert all(p.told is not None for p in told)  # every point, failed or not, was told to the strategy
    assert search.best == ok["y"].min() and search.best_point["cliff.a"] <= 7


def test_points_asked_again_are_simulated_once_even_while_they_run(tmp_path, dask_scheduler):
    """On a list of three values TPE keeps asking the same points, also while an equal one is in flight
    (three at a time): each is simulated once, the repeats are told its result and do not use the budget,
    and the search stops once it has had as many repeats as its budget."""
    space = load_space(
        cliff_space(
            tmp_path,
            {"strategy": "tpe", "max_points": 12, "batch": 3},
            dask_scheduler,
            parameters={"cliff.a": [2.0, 3.0, 8.0], "cliff.b": [1.0]},
        )
    )
    report = submit(space)
    search = report.search
    assert (search.points, search.failed, search.stopped) == (3, 1, "repeats") and search.repeats >= 12
    assert (report.ran, report.ok, report.failed) == (3, 2, 1)
    rows = results(space, "y")
    assert sorted(rows["cliff.a"]) == [2.0, 3.0, 8.0]
    assert search.best_point == {"cliff.a": 3.0, "cliff.b": 1.0} and search.best == 0.0
    history = load_history(space.output, space.name)
    assert len(history.points) == 3 + search.repeats and not history.outstanding()


# ---- spec errors ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "search, changes, message",
    [
        ({"strategy": "genetic", "populaton": 10}, {}, r"search\.populaton: extra inputs are not permitted"),
        (
            {"strategy": "nsga2"},
            {},
            r"search: nsga2 optimises several objectives: list two or more under ranking\.pareto",
        ),
        (
            {"strategy": "gp", "acquisition_samples": 0},
            {},
            (
                r"search: GPSampler refuses the options acquisition_samples=0: "
                r"acquisition_samples and local_searches must be"
            ),
        ),
        (
            {"strategy": "least_squares"},
            {"objectives": {"position_rmse": {"signal": "msd.x", "recorded": "x"}}},
            r"search: least_squares fits a vector objective",
        ),
        (
            {"strategy": "least_squares"},
            {
                "parameters": {
                    "msd.k": {"low": 5, "high": 25, "integer": True},
                    "msd.c": {"start": 0.2, "stop": 2.0, "step": 0.2},
                }
            },
            (
                r"search: least_squares moves every parameter "
                r"continuously; msd\.k, msd\.c takes only whole numbers"
            ),
        ),
    ],
    ids=[
        "genetic-option",
        "nsga2-without-pareto",
        "gp-effort",
        "least-squares-without-residuals",
        "least-squares-on-steps",
    ],
)
def test_search_spec_errors_are_found_when_the_spec_loads(tmp_path, search, changes, message):
    path = msd_space(tmp_path, search, "tcp://127.0.0.1:1", **changes)  # no cluster is reached
    with pytest.raises(DseError, match=message) as error:
        load_space(path)
    assert str(error.value).startswith(str(path))


# ---- the command line -------------------------------------------------------------------------------


def test_submit_json_reports_the_search(tmp_path, dask_scheduler):
    path = msd_space(tmp_path, {"strategy": "least_squares", "max_points": 40}, dask_scheduler)
    done = subprocess.run(
        [sys.executable, "-m", "dse_runner", "submit", str(path), "--no-dashboard", "--json"],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    summary = strict_loads(done.stdout)
    search = summary["search"]
    assert search["strategy"] == "least_squares" and search["stopped"] == "strategy"
    assert search["points"] == summary["ran"] == summary["ok"] and search["failed"] == 0
    assert search["best"] == summary["best_total"] and search["best_point"] == summary["best"]
    assert abs(search["best_point"]["msd.k"] - 14) < 0.1 and 0 < search["utilisation"] <= 1
    assert json.loads(done.stdout) == summary  # one object, nothing else on stdout
