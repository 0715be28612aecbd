"""Sweeps on a real cluster: a Dask scheduler process and two worker processes."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, SCENARIOS, sleeper_multimodel, strict_loads, write_space

from dse_runner.simulation.run import simulate
from dse_runner.sweeps import store
from dse_runner.sweeps.expand import expand
from dse_runner.sweeps.rank import rank
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit


def test_rows_equal_direct_simulations(tmp_path, dask_scheduler, plan):
    space = load_space(write_space(tmp_path, cluster={"address": dask_scheduler}))
    # Every worker loads the model first (a sweep probes on each), so that neither is still busy
    # loading when the chunks go out: a worker of a fresh cluster could take longer to do so
    # than the other takes for all 12.
    submit(
        space.with_overrides(output=tmp_path / "warm-up"),
        points=[{name: values[0] for name, values in space.parameters.items()}],
    )
    report = submit(space)
    assert (report.total, report.ok, report.failed, report.workers) == (12, 12, 0, 2)
    rows = store.read_results(space.output, "small", columns=[*space.parameters, *space.objectives, "worker"])
    assert len(rows) == 12 and rows["task_id"].is_unique
    assert set(rows["worker"]) == {"worker-0", "worker-1"}  # both worker processes took chunks
    for _, row in rows.sample(4, random_state=1).iterrows():
        point = {name: row[name] for name in space.parameters}
        direct = simulate(plan, SCENARIOS / row["scenario"], point)
        for name in space.objectives:
            assert row[name] == pytest.approx(direct.objectives[name], rel=1e-12, abs=1e-12)
    # The best point's tracks were kept for plotting, one per scenario.
    best = rank(space.output).best
    track = store.read_trajectory(space.output, "small", "sin1", 1)
    assert {f"point:{k}": v for k, v in best.items()} == {
        c: track[c].iloc[0] for c in track if c.startswith("point:")
    }
    assert len(track) == 1681 and {"time", "vehicle.x", "vehicle.y"} <= set(track.columns)


def test_resubmitting_a_finished_sweep_runs_nothing_and_keeps_the_status_of_the_run_that_did(
    tmp_path, dask_scheduler
):
    from dse_runner.interfaces.report import build_report
    from dse_runner.sweeps.sweep import load_status

    space = load_space(write_space(tmp_path, cluster={"address": dask_scheduler}, keep_trajectories=0))
    first = submit(space)
    files = {p: p.stat().st_mtime_ns for p in (space.output / "results").rglob("*.parquet")}
    status = load_status(space.output, "small")
    second = submit(space)
    assert (first.ran, second.ran, second.skipped) == (12, 0, 12)
    assert {p: p.stat().st_mtime_ns for p in (space.output / "results").rglob("*.parquet")} == files
    assert load_status(space.output, "small") == status and (status.ran, status.workers) == (12, 2)
    page = build_report(space.output)  # a user saw "ran 0 tasks in 0.2 s on 0 workers" here
    assert re.search(
        r"last submission that ran tasks</td><td[^>]*>finished: ran 12 tasks in [\d.]+ s on 2 workers<", page
    ), re.findall(r"last submission.*", page)


def test_failing_simulations_become_failed_rows(tmp_path, dask_scheduler):
    path = write_space(
        tmp_path,
        cluster={"address": dask_scheduler},
        parameters={"vehicle.mass": [1500, -5], "vehicle.rk4_step": [0.001]},
    )
    report = submit(load_space(path))
    assert (report.ok, report.failed) == (2, 2)
    rows = store.read_results(
        tmp_path / "out", "small", columns=["vehicle.mass", "status", "error", "cross_track_error"]
    )
    failed = rows[rows["status"] == "failed"]
    assert set(failed["vehicle.mass"]) == {-5.0}
    assert failed["error"].str.contains(r"vehicle \(robotti_vehicle\).*parameter mass must be > 0").all()
    assert failed["cross_track_error"].isna().all()
    assert rows.loc[rows["status"] == "ok", "cross_track_error"].gt(0).all()


def sleeper_space(tmp_path, pauses: list[float], timeout: float):
    return write_space(
        tmp_path,
        multimodel=str(sleeper_multimodel(tmp_path)),
        scenarios=[str(SCENARIOS / "sin1")],
        parameters={"sleeper.pause": pauses},
        timeout=timeout,
        keep_trajectories=0,
    )


def test_timeout_becomes_a_failed_row(tmp_path, dask_scheduler):
    """sin1 is 1680 steps of 0.05 s: at pause 0.02 a run would take 34 s of wall time, 34 times
    its limit, and it is stopped at the first check past the limit (every 64 steps: 1.3 s); at
    pause 0 it takes milliseconds."""
    path = sleeper_space(tmp_path, pauses=[0, 0.02], timeout=1.0)
    report = submit(load_space(path).with_overrides(address=dask_scheduler))
    assert (report.ok, report.failed) == (1, 1), report.errors
    rows = store.read_results(tmp_path / "out", "small", columns=["sleeper.pause", "status", "error"])
    slow = rows[rows["sleeper.pause"] == 0.02].iloc[0]
    assert slow["status"] == "failed" and slow["error"].startswith(
        "timeout: the simulation was stopped at t="
    )
    stopped_at = float(re.match(r"timeout: the simulation was stopped at t=(\S+) of 84 s", slow["error"])[1])
    assert 0 < stopped_at < 84
    fast = rows[rows["sleeper.pause"] == 0].iloc[0]
    assert fast["status"] == "ok" and pd.isna(fast["error"])


def test_rank_matches_a_plain_pandas_computation(tmp_path, dask_scheduler):
    space = load_space(
        write_space(
            tmp_path,
            cluster={"address": dask_scheduler},
            ranking={
                "objective": "cross_track_error",
                "pareto": ["cross_track_error", {"objective": "final_error"}],
                "weights": {"cross_track_error": 1.0, "max_error": 0.5},
            },
        )
    )
    submit(space)
    ranking = rank(space.output)
    rows = pd.concat(
        pd.read_parquet(p).assign(scenario=p.parent.name.removeprefix("scenario="))
        for p in (space.output / "results").rglob("*.parquet")
    )
    params = list(space.parameters)
    totals = rows.groupby(params)[["cross_track_error", "max_error", "final_error"]].sum()
    best = totals["cross_track_error"].idxmin()
    assert tuple(ranking.best.values()) == best
    assert ranking.best_total == pytest.approx(totals["cross_track_error"].min())
    weighted = (totals["cross_track_error"] + 0.5 * totals["max_error"]).sort_values()
    assert ranking.weighted.loc[0, "weighted"] == pytest.approx(weighted.iloc[0])
    sin1 = rows[rows["scenario"] == "sin1"].set_index(params)["cross_track_error"]
    table = ranking.table1.set_index("scenario")
    assert table.loc["sin1", "min_error"] == pytest.approx(sin1.min())
    assert table.loc["sin1", "average_error"] == pytest.approx(sin1.mean())
    assert table.loc["sin1", "computed"] == pytest.approx(sin1.loc[best])
    # Pareto: no front point is dominated by any point.
    front = ranking.pareto[["cross_track_error", "final_error"]].to_numpy()
    every = totals[["cross_track_error", "final_error"]].to_numpy()
    for f in front:
        assert not np.any(np.all(every <= f, axis=1) & np.any(every < f, axis=1))
    assert len(ranking.groups) == 2 and set(ranking.groups["group"]) == {"sin", "speed_step"}


@pytest.mark.parametrize(
    "excluded, incomplete, scope",
    [
        (0, 0, "3 points"),
        (2, 0, "3 of 5 points meet e < 1 and f > 0; min/max/average over the 3"),
        (0, 4, "4 points without an ok result on every scenario left out; min/max/average over the 3"),
        (
            2,
            4,
            (
                "3 of 5 points meet e < 1 and f > 0; 4 points without an ok result on every scenario "
                "left out; min/max/average over the 3"
            ),
        ),
    ],
)
def test_table1_says_which_points_it_is_over(excluded, incomplete, scope):
    from dse_runner.sweeps.rank import Ranking, table1_scope

    none = pd.DataFrame()
    ranking = Ranking(
        "s",
        ["k"],
        "e",
        "min",
        {"k": 1.0},
        1.0,
        pd.DataFrame({"k": [1.0, 2.0, 3.0]}),
        none,
        none,
        none,
        none,
        incomplete_points=incomplete,
        failed_rows=0,
        excluded_points=excluded,
        constraints=("e < 1", "f > 0"),
    )
    assert table1_scope(ranking) == scope


@pytest.mark.slow  # a sweep on a local cluster
def test_a_transient_failure_is_retried_once(tmp_path, monkeypatch):
    """The first attempt of every task fails, the retry succeeds: every row is ok.
    A task that fails both times is a failed row with its message."""
    (tmp_path / "flaky_objectives.py").write_text(
        "import os\n"
        "def flaky(trajectory, scenario):\n"
        "    marker = os.path.join(os.path.dirname(__file__), "
        "f'seen-{os.getpid()}-{trajectory.values.sum()}')\n"
        "    if not os.path.exists(marker):\n"
        "        open(marker, 'w').close()\n"
        "        raise RuntimeError('transient failure')\n"
        "    return 1.0\n"
        "def broken(trajectory, scenario):\n"
        "    raise RuntimeError('always broken')\n"
    )
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))  # the local cluster's workers import it
    monkeypatch.syspath_prepend(str(tmp_path))
    space = load_space(
        write_space(
            tmp_path,
            objectives=["flaky_objectives:flaky"],
            ranking={"objective": "flaky_objectives:flaky"},
            cluster={"n_workers": 1},
            keep_trajectories=0,
        )
    )
    report = submit(space)
    assert (report.ok, report.failed) == (12, 0)
    broken = load_space(
        write_space(
            tmp_path,
            name="broken",
            objectives=["flaky_objectives:broken"],
            ranking={"objective": "flaky_objectives:broken"},
            cluster={"n_workers": 1},
            keep_trajectories=0,
        )
    )
    report = submit(broken)
    assert (report.ok, report.failed) == (0, 12)
    rows = store.read_results(broken.output, "broken", columns=["status", "error"])
    assert rows["error"].str.contains("RuntimeError: always broken").all()


def test_rank_command_json(tmp_path, dask_scheduler):
    space = load_space(write_space(tmp_path, cluster={"address": dask_scheduler}))
    submit(space)
    done = subprocess.run(
        [sys.executable, "-m", "dse_runner", "rank", str(space.output), "--json"],
        check=False,
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert done.returncode == 0, done.stderr
    report = strict_loads(done.stdout)
    assert set(report["best"]) == set(space.parameters)
    assert report["best_total"] == pytest.approx(rank(space.output).best_total)
    assert len(report["table1"]) == 2
    assert (space.output / "ranking" / "small" / "table1.csv").is_file()


def test_a_changed_model_is_ranked_on_its_own_rows(tmp_path, dask_scheduler):
    """Re-running a sweep after its model changed (here its objectives; equally a rebuilt FMU) adds the new
    model's rows beside the old; the ranking uses only the new ones."""
    first = load_space(write_space(tmp_path, objectives=["cross_track_error"])).with_overrides(
        address=dask_scheduler
    )
    submit(first)
    second = load_space(write_space(tmp_path, objectives=["cross_track_error", "max_error"])).with_overrides(
        address=dask_scheduler
    )
    report = submit(second)
    assert report.skipped == 0 and report.ran == report.total
    assert len(store.read_results(second.output, "small", columns=[])) == 2 * report.total
    ranking = rank(second.output, "small")
    assert len(ranking.totals) == report.total // len(second.scenarios)  # every point complete, once


def test_an_optimisers_read_back_finds_columns_only_newer_files_have(tmp_path, dask_scheduler):
    """What fit.py reads after each round: just the round's task ids, and a
    column the first run's files lack."""
    first = load_space(write_space(tmp_path, objectives=["cross_track_error"])).with_overrides(
        address=dask_scheduler
    )
    submit(first)
    second = load_space(write_space(tmp_path, objectives=["cross_track_error", "max_error"])).with_overrides(
        address=dask_scheduler
    )
    submit(second)
    ids = [task.task_id for task in expand(second)][:3]
    rows = store.read_results(second.output, "small", ["max_error"], task_ids=ids)
    assert sorted(rows["task_id"]) == sorted(ids)
    assert rows["max_error"].notna().all()


def test_a_chunk_given_up_on_loses_the_rows_it_wrote_and_only_those(tmp_path):
    """A chunk can finish and write its rows on a worker that then dies before the result is fetched; Dask
    gives up on it and the sweep runs its halves again: its own rows must go first, or they stand twice."""
    schema = store.results_schema({"vehicle.mass": [1000.0]}, {"cross_track_error": None})

    def rows(ids, scenario):
        return [
            {
                "task_id": i,
                "scenario": scenario,
                "status": "ok",
                "error": None,
                "vehicle.mass": 1000.0,
                "cross_track_error": 1.0,
            }
            for i in ids
        ]

    store.write_rows(tmp_path, "s", "gone", rows(["a", "b"], "sin1") + rows(["c"], "sin2"), schema)
    store.write_rows(tmp_path, "s", "kept", rows(["d"], "sin1"), schema)
    assert store.remove_chunk(tmp_path, "s", "gone") == 2
    assert store.remove_chunk(tmp_path, "s", "never-written") == 0
    assert set(store.finished_task_ids(tmp_path, "s")) == {"d"}


@pytest.mark.parametrize(
    "value",
    [
        0.5,
        -0.0,
        1e300,
        5e-324,
        1 / 3,
        float("nan"),
        float("inf"),
        -float("inf"),
        3,
        -7,
        2**70,
        True,
        False,
        np.float64(0.25),
        "fast",
        None,
    ],
)
def test_task_ids_do_not_depend_on_how_they_are_written(value):
    """Plain numbers have their JSON written directly (fast); every value must give the id the json
    module gives, or a re-run would not find the rows of an earlier run."""
    from dse_runner.sweeps.expand import _digest, task_id

    point = {"b.x": value, 'a.ü "q"': 1.5}
    assert task_id("m" * 32, point, "s" * 32) == _digest("m" * 32, sorted(point.items()), "s" * 32)[:24]


@pytest.mark.parametrize(
    "values", [[0.5, 1 / 3, float("nan"), -0.0], [3, True, 2.5, -7], ["fast", 1.0, None, 2.0]]
)
def test_tasks_hashed_a_block_at_a_time_keep_their_ids(values):
    """A sweep hashes points a block at a time, a column at a time; the ids must be task_id's, whatever
    the values (plain numbers, mixed types, strings), and the values must come back as given."""
    from dse_runner.sweeps.expand import TaskBatch, task_id

    points = [{"b.x": v, 'a.ü "q"': float(k)} for k, v in enumerate(values)]
    batch = TaskBatch.of_points("m" * 32, points, "sin1", "s" * 32)
    tasks = list(batch)
    assert [t.task_id for t in tasks] == [task_id("m" * 32, p, "s" * 32) for p in points]
    for task, point in zip(tasks, points):
        assert task.scenario == "sin1" and repr(task.point) == repr(tuple(sorted(point.items())))  # NaN too
        assert all(type(v) is type(point[name]) for name, v in task.point)  # plain Python values again


def test_points_of_differing_parameters_in_one_sweep_keep_their_ids_and_values(tmp_path):
    """A fit may ask in one sweep for points that set different parameters (a probe that sets one more): each
    task keeps its own point and id, none is dropped or given another point's columns."""
    from dse_runner.sweeps.expand import blocks, chunked, scenario_hash, task_id

    space = load_space(write_space(tmp_path))
    base = dict(next(iter(expand(space))).point)
    extra = next(iter(base))
    points = [
        base,
        {**base, "vehicle.corr_onset_time": 3.0},
        {k: v for k, v in base.items() if k != extra},
        {**base, extra: 0.25},
    ]
    tasks = [t for chunk in chunked(blocks(space, points), 3) for t in chunk]  # a sweep's chunks
    assert len(tasks) == len(points) * len(space.scenarios)
    for scenario in space.scenarios:
        mine = [t for t in tasks if t.scenario == scenario.name]
        assert [dict(t.point) for t in mine] == points
        assert [t.task_id for t in mine] == [
            task_id(space.model_key, p, scenario_hash(scenario)) for p in points
        ]


def test_chunks_hold_the_tasks_in_order_at_the_asked_sizes_less_the_done(tmp_path):
    """Chunks are cut across blocks and scenarios at whatever size the sweep asks next; finished tasks
    are left out and no task is lost or repeated."""
    from dse_runner.sweeps.expand import blocks, chunked

    space = load_space(write_space(tmp_path))  # 6 points x 2 scenarios
    every = list(expand(space))
    done = store.TaskIds.of({every[1].task_id, every[7].task_id})
    sizes = iter([4, 3, 2, 100])
    chunks = list(chunked(blocks(space, done=done), lambda: next(sizes)))
    assert [len(c) for c in chunks] == [4, 3, 2, 1]
    assert [t for c in chunks for t in c] == [t for t in every if t.task_id not in done]
    assert chunks[1].scenarios == (every[0].scenario, every[6].scenario)  # a chunk may span two scenarios


def test_chunks_ramp_up_from_the_smallest_then_follow_the_work_left():
    from dse_runner.sweeps.sweep import SMALLEST_CHUNK_PART, chunk_size

    per_task, target, pending, threads = 1e-4, 2.0, 100_000, 2
    smallest = round(target / SMALLEST_CHUNK_PART / per_task)
    sizes = [chunk_size(per_task, target, pending, threads, r) for r in range(8)]
    assert sizes[0] == smallest and sizes[1] == 2 * smallest  # each round doubles ...
    assert (
        max(sizes) == chunk_size(per_task, target, pending, threads) == pending // (4 * threads)
    )  # ... up to this
    assert chunk_size(per_task, target, 10, threads, 0) == smallest  # the last chunks keep the smallest size
