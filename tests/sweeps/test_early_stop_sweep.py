"""A sweep over FMUs that ask to stop early (tests/fmus/stair2, FMI 2.0; stair3, FMI 3.0: each stops at its
parameter stop_at): the rows are stored with status ``stopped``, the span their objectives cover
(``span_end``) and which FMU stopped; rank puts the points with such a run after the complete ones and
says how many; a search is told them as failures. On a real Dask cluster and real Parquet."""

from __future__ import annotations

import pandas as pd
import pyarrow as pa
import pytest
import yaml
from conftest import REPO, dse_runner, strict_loads

from dse_runner.sweeps import store
from dse_runner.sweeps.chunks import TaskRun
from dse_runner.sweeps.rank import rank
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit

FMUS = REPO / "tests" / "fmus"


def stair_space(folder, fmu: str, scheduler: str, **changes) -> str:
    """A space over stop_at on one stair FMU, run to t = 10: stop_at 20 runs whole, 4 and 7 stop early.
    Its objective, the last ramp value (the time reached), is smallest for the shortest run."""
    spec = {
        "name": fmu,
        "multimodel": str(FMUS / fmu),
        "parameters": {f"{fmu}.stop_at": [4.0, 7.0, 20.0]},
        "experiment": {"start_time": 0, "stop_time": 10, "step": 0.5},
        "objectives": {
            "reached": {"signal": f"{fmu}.ramp", "reduce": "final"},
            "steps": {"signal": f"{fmu}.counter", "reduce": "max"},
        },
        "ranking": {"objective": "reached", "goal": "min", "pareto": ["reached", "steps"]},
        "output": str(folder / "out"),
        "cluster": {"address": scheduler},
        "keep_trajectories": 0,
        **changes,
    }
    path = folder / "space.yaml"
    path.write_text(yaml.safe_dump(spec))
    return str(path)


@pytest.mark.parametrize("fmu", ["stair2", "stair3"])
def test_rows_of_runs_an_fmu_stopped_say_so_and_rank_after_complete_points(tmp_path, dask_scheduler, fmu):
    space = load_space(stair_space(tmp_path, fmu, dask_scheduler))
    report = submit(space)
    assert (report.ok, report.failed) == (3, 0)  # a run that stopped early is no failure
    rows = store.read_results(
        space.output, fmu, [f"{fmu}.stop_at", "status", "span_end", "error", "reached", "steps"]
    ).sort_values(f"{fmu}.stop_at")
    assert list(rows["status"]) == ["stopped", "stopped", "ok"]
    assert list(rows["span_end"]) == [4.0, 7.0, 10.0]  # what the objectives cover
    assert list(rows["reached"]) == [4.0, 7.0, 10.0] and list(rows["steps"]) == [5.0, 8.0, 11.0]
    assert list(rows["error"].fillna("")) == [
        f"{fmu}: the FMU asked to stop at t = 4",
        f"{fmu}: the FMU asked to stop at t = 7",
        "",
    ]

    ranking = rank(space.output)
    # by the objective alone the shortest run would be best; a complete run is ranked first
    assert ranking.best == {f"{fmu}.stop_at": 20.0} and ranking.best_total == 10.0
    totals = ranking.totals
    assert list(totals[f"{fmu}.stop_at"]) == [20.0, 4.0, 7.0] and list(totals["stopped"]) == [0, 1, 1]
    assert (ranking.stopped_points, ranking.failed_rows, ranking.incomplete_points) == (2, 0, 0)
    assert list(ranking.pareto[f"{fmu}.stop_at"]) == [20.0]  # the front is of complete points only
    assert ranking.to_json()["stopped_points"] == 2

    done = dse_runner("rank", space.output)
    assert done.returncode == 0, done.stderr
    assert (
        "ranked last: 2 points with a run an FMU stopped early (their objectives cover a shorter span; "
        "column stopped)"
    ) in done.stdout
    assert strict_loads(dse_runner("rank", space.output, "--json").stdout)["stopped_points"] == 2
    if fmu == "stair2":  # the report says it too
        from dse_runner.interfaces.report import build_report

        assert "ranked last: a run an FMU stopped early</td><td" in build_report(space.output)


def test_a_sweep_whose_every_run_stops_ranks_them_all(tmp_path, dask_scheduler):
    space = load_space(
        stair_space(tmp_path, "stair2", dask_scheduler, parameters={"stair2.stop_at": [6.0, 3.0]})
    )
    submit(space)
    ranking = rank(space.output)
    assert ranking.best == {"stair2.stop_at": 3.0} and ranking.stopped_points == 2
    assert ranking.pareto.empty  # no complete point to put on it


def test_a_task_that_stopped_early_is_told_to_a_search_as_a_failure():
    from dse_runner.simulation.trajectory import Stop

    stopped = TaskRun({"reached": 4.0}, None, "reset", Stop("stair2", 4.0), 4.0)
    assert (stopped.status, stopped.told, stopped.note) == (
        "stopped",
        None,
        "stair2: the FMU asked to stop at t = 4",
    )
    whole = TaskRun({"reached": 10.0}, None, "reset", None, 10.0)
    assert (whole.status, whole.told, whole.note) == ("ok", {"reached": 10.0}, None)
    assert TaskRun(None, "boom").status == "failed"


def test_a_store_written_before_span_end_still_ranks(tmp_path):
    """Rows of an earlier version have no span_end column and no stopped status: rank reads neither."""
    from dse_runner.sweeps.rank import save_sweep_spec
    from dse_runner.sweeps.spec import SpaceSpec

    spec = SpaceSpec.model_validate(
        {
            "name": "old",
            "multimodel": str(FMUS / "stair2"),
            "parameters": {"stair2.stop_at": [20.0, 30.0]},
            "objectives": {"reached": {"signal": "stair2.ramp", "reduce": "final"}},
            "ranking": {"objective": "reached"},
        }
    )
    save_sweep_spec(tmp_path, spec, "m")
    frame = pd.DataFrame(
        {
            "task_id": ["a", "b"],
            "model": ["m", "m"],
            "group": ["all", "all"],
            "stair2.stop_at": [20.0, 30.0],
            "reached": [2.0, 1.0],
            "status": ["ok", "ok"],
        }
    )
    table = pa.Table.from_pandas(frame, preserve_index=False)
    store.write_results(tmp_path, "old", "c", table, ["nominal"] * 2)
    ranking = rank(tmp_path, "old")
    assert ranking.best == {"stair2.stop_at": 30.0} and ranking.stopped_points == 0
    assert "stopped" not in ranking.totals
