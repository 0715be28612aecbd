"""Diagnosis on real recordings: the Cascaded Tanks benchmark's estimation record (jobs/cascaded_tanks), one
long record of a real process with quantised, saturated measurements and an unknown initial state."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import REPO

from dse_runner.analysis.diagnose.signal_library import diagnose_space
from dse_runner.simulation.run import simulate
from dse_runner.simulation.values import read_values

JOB = REPO / "jobs" / "cascaded_tanks"
SHARED = REPO.parent / "shared" / "real-data" / "cascaded-tanks" / "estimation"


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/real-data is not beside this checkout")
def test_the_job_holds_the_published_files_unchanged():
    for name in ("pump.csv", "level.csv"):
        assert (JOB / "estimation" / name).read_bytes() == (SHARED / name).read_bytes()


@pytest.mark.slow
def test_the_tanks_overflow_is_found_on_blocks_of_the_one_record_and_the_diagnosed_model_predicts_better(
    tmp_path, dask_scheduler
):
    """The space as the job gives it (intervals, calibrated by a Sobol' design and least squares), three of
    the library's effects tried (--hypothesis, to keep the test short): one record, so held out by blocks of
    time; the overflow of the upper tank into the lower one is named; the values file replays the diagnosed
    model with ``simulate``, whose error on the record is the fit's."""
    only = ["state_overflow(tanks.x1, x2)", "output_max(tanks.y)", "input_offset(tanks.u)"]
    found = diagnose_space(
        JOB / "space.yaml", out=tmp_path / "out", address=dask_scheduler, only=only
    ).to_json()
    assert found["validation"] == {"by": "time blocks", "folds": 3, "record": "estimation"}
    named = {e["id"] for e in found["effects"]}
    assert "state_overflow" in named, found["candidates"]
    assert found["held_out_after"] < 0.7 * found["held_out_before"]
    estimate = found["case"]["compared"][0]["noise_estimate"]
    assert estimate["flat"] > 0 and estimate["quantum"] == pytest.approx(1e-4)  # stuck at 10 V; 4 decimals
    before = simulate(JOB / "multimodel.yaml", JOB / "estimation", found["calibrated"]["parameters"])
    after = simulate(JOB / "multimodel.yaml", JOB / "estimation", read_values(found["files"]["values"]))
    assert after.objectives["y_rmse"] < 0.8 * before.objectives["y_rmse"]
    assert [Path(f).name for f in found["files"]["figures"]] == ["estimation-tanks.y.png"]
    report = Path(found["files"]["report"]).read_text()
    assert (
        "Validated by time blocks" in report
        and "![estimation-tanks.y](figures/estimation-tanks.y.png)" in report
    )
