"""Rank (and sensitivity: tests/analysis/test_sensitivity.py) aggregate the store in Arrow
(sweeps/aggregate.py); nothing may be lost on the way: on the same real store, their totals, Table 1,
groups and indices equal those of the plain pandas computation they replaced, written out here from the
Parquet files read one by one.

The stores are real sweeps on the real cluster, with the untidy parts a long study meets added the way
they arise: a chunk's file written twice under two names (each task must count once), and a point missing a
scenario's row (left out as incomplete)."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from conftest import SCENARIOS, write_space

from dse_runner.sweeps import store
from dse_runner.sweeps.rank import current_model, rank
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit

OBJECTIVES = ["cross_track_error", "max_error", "final_error"]


def plain_rows(output, sweep: str) -> pd.DataFrame:
    """Every file read on its own, the scenario from its folder, each task once (the first file's row, files
    in name order), the current model's rows only: what the pandas readers did."""
    files = sorted((output / "results" / f"sweep={sweep}").rglob("*.parquet"), key=str)
    rows = pd.concat(
        pd.read_parquet(p).assign(scenario=p.parent.name.removeprefix("scenario=")) for p in files
    )
    rows = rows.drop_duplicates("task_id", keep="first")
    return rows[rows["model"] == current_model(output, sweep)].reset_index(drop=True)


def plain_totals(rows: pd.DataFrame, parameters: list[str], objectives: list[str], over: str) -> pd.DataFrame:
    ok = rows[rows["status"] == "ok"]
    per_point = ok.groupby(parameters, dropna=False)
    totals = per_point[objectives].agg(over)
    return totals[(per_point.size() == rows["scenario"].nunique()).to_numpy()].reset_index()


@pytest.fixture(scope="module")
def untidy(tmp_path_factory, dask_scheduler):
    """A grid on three scenarios in two groups, ranked by the mean over them with a constraint; then one chunk
    file copied under a second name and one point's row on one scenario taken out."""
    folder = tmp_path_factory.mktemp("untidy")
    path = write_space(
        folder,
        cluster={"address": dask_scheduler},
        scenarios=[str(SCENARIOS / name) for name in ("sin1", "sin2", "speed_step2")],
        parameters={
            "vehicle.cAlphaF": [20000, 29000, 38000],
            "vehicle.mass": {"start": 1000, "stop": 3000, "num": 3},
        },
        ranking={
            "objective": "cross_track_error",
            "over_scenarios": "mean",
            "constraints": ["max_error < 1e9"],
            "weights": {"cross_track_error": 1.0},
        },
        keep_trajectories=0,
    )
    space = load_space(path)
    submit(space)
    results = space.output / "results" / "sweep=small"
    files = sorted(results.rglob("*.parquet"), key=str)
    shutil.copy(files[0], files[0].with_name("part-zz-copy.parquet"))  # the same tasks in a second file
    last = pq.read_table(files[-1])
    pq.write_table(last.slice(1), files[-1])  # its first task never wrote: that point is incomplete
    return space


def test_rank_equals_the_plain_computation_on_an_untidy_store(untidy):
    space = untidy
    parameters = list(space.parameters)
    rows = plain_rows(space.output, space.name)
    assert len(rows) == 9 * 3 - 1  # the copied file counted once, the removed row gone
    ranking = rank(space.output)
    totals = plain_totals(rows, parameters, OBJECTIVES, "mean")
    admitted = totals[totals["max_error"] < 1e9]
    expected = admitted.sort_values("cross_track_error", kind="stable").reset_index(drop=True)
    assert ranking.incomplete_points == 1 and len(ranking.totals) == 8
    pd.testing.assert_frame_equal(
        ranking.totals[[*parameters, *OBJECTIVES]], expected, rtol=1e-12, atol=0, check_dtype=False
    )

    ranked = rows[rows["status"] == "ok"].merge(expected[parameters], on=parameters)
    stats = (
        ranked.groupby(["scenario", "group"])["cross_track_error"].agg(["min", "max", "mean"]).reset_index()
    )
    table1 = ranking.table1
    assert table1[["scenario", "group"]].values.tolist() == stats[["scenario", "group"]].values.tolist()
    np.testing.assert_array_equal(
        table1[["min_error", "max_error"]].to_numpy(), stats[["min", "max"]].to_numpy()
    )
    np.testing.assert_allclose(table1["average_error"], stats["mean"], rtol=1e-12)
    at_best = ranked[np.logical_and.reduce([ranked[p] == v for p, v in ranking.best.items()])]
    np.testing.assert_array_equal(
        table1["computed"], at_best.set_index("scenario").loc[table1["scenario"], "cross_track_error"]
    )

    for group, members in rows.groupby("group"):
        n = members["scenario"].nunique()
        sums = (
            members[members["status"] == "ok"].groupby(parameters)["cross_track_error"].agg(["sum", "size"])
        )
        sums = sums[sums["size"] == n]
        shown = ranking.groups.set_index("group").loc[group]
        assert shown["scenarios"] == n
        assert shown["cross_track_error_total"] == pytest.approx(sums["sum"].min(), rel=1e-12)
        assert tuple(shown[p] for p in parameters) == sums["sum"].idxmin()


def test_a_task_in_two_files_is_read_once_its_first_row_kept(tmp_path):
    schema = pa.schema([("task_id", pa.string()), ("model", pa.string()), ("y", pa.float64())])
    first = pa.table({"task_id": ["a", "b"], "model": ["m", "m"], "y": [1.0, 2.0]}, schema=schema)
    second = pa.table({"task_id": ["b", "c"], "model": ["m", "m"], "y": [20.0, 3.0]}, schema=schema)
    store.write_results(tmp_path, "s", "1", first, ["x", "x"])
    store.write_results(tmp_path, "s", "2", second, ["x", "x"])
    rows = store.read_results(tmp_path, "s", ["y"])
    assert rows["task_id"].tolist() == ["a", "b", "c"] and rows["y"].tolist() == [1.0, 2.0, 3.0]
    assert store.read_results(tmp_path, "s", ["y"], model="other").empty
