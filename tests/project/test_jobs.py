"""The general examples under jobs/: a study without recordings (water tank) and a model-exchange
calibration against a recording (mass-spring-damper), each run as a user would, on the real cluster."""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import REPO

from dse_runner.interfaces.report import write_report
from dse_runner.simulation.run import simulate
from dse_runner.sweeps import store
from dse_runner.sweeps.rank import rank
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit

WATERTANK = REPO / "jobs" / "watertank"
MSD = REPO / "jobs" / "msd"


def _job_space(job, tmp_path, **changes):
    """The job's space.yaml beside its own files (relative paths kept), with ``changes`` applied."""
    spec = yaml.safe_load((job / "space.yaml").read_text()) | changes
    path = job / f".test-space-{tmp_path.name}.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


@pytest.fixture
def job_space(tmp_path):
    written = []

    def make(job, **changes):
        path = _job_space(job, tmp_path, output=str(tmp_path / "out"), **changes)
        written.append(path)
        return load_space(path)

    yield make
    for path in written:
        path.unlink(missing_ok=True)


WATERTANK_GRID = {"controller.minlevel": [0.8, 1.0, 1.2], "controller.maxlevel": [1.0, 1.6, 2.2]}


@pytest.fixture(scope="module")
def watertank(tmp_path_factory, dask_scheduler):
    """The water-tank job on a small grid, run once on the real cluster for the tests below."""
    folder = tmp_path_factory.mktemp("watertank")
    path = _job_space(
        WATERTANK,
        folder,
        output=str(folder / "out"),
        parameters=WATERTANK_GRID,
        cluster={"address": dask_scheduler},
    )
    try:
        space = load_space(path)
        yield space, submit(space)
    finally:
        path.unlink()  # kept until the dashboard test has simulated the best point from it


def test_watertank_sweeps_the_levels_under_its_constraint_and_ranks_a_pareto_front(watertank):
    space, report = watertank
    assert [s.name for s in space.scenarios] == ["nominal"]  # no scenarios: the experiment alone
    assert (report.total, report.failed) == (7, 0)  # 9 points, 2 excluded by maxlevel > minlevel
    rows = store.read_results(
        space.output, space.name, columns=[*WATERTANK_GRID, "level_deviation", "switches"]
    )
    assert (rows["controller.maxlevel"] > rows["controller.minlevel"]).all()

    # Each row is what a direct simulation of its point gives: the Boolean valve drives the tank.
    row = rows.iloc[0]
    point = {name: row[name] for name in WATERTANK_GRID}
    direct = simulate(space.plan, None, point, objectives=space.objectives, experiment=space.experiment)
    valve = direct.trajectory.column("controller.valve")
    assert set(np.unique(valve)) == {0.0, 1.0}
    assert row["switches"] == np.count_nonzero(np.diff(valve)) == direct.objectives["switches"]
    level = direct.trajectory.column("tank.level")
    assert row["level_deviation"] == pytest.approx(
        np.sqrt(np.trapezoid((level - 1.5) ** 2, direct.time) / 100.0), rel=1e-12
    )

    ranking = rank(space.output, space.name)
    assert list(ranking.table1["scenario"]) == ["nominal"]  # Table 1 has a single row
    front = ranking.pareto[["level_deviation", "switches"]].to_numpy()
    assert len(front) >= 2
    others = ranking.totals[["level_deviation", "switches"]].to_numpy()
    for a in front:  # nothing on the front is dominated by any ranked point
        assert not ((others <= a).all(axis=1) & (others < a).any(axis=1)).any()
    # The trade-off the front shows: its best-tracking point switches more than its calmest one.
    assert front[front[:, 0].argmin(), 1] > front[front[:, 1].argmin(), 1]


def test_watertank_report_and_dashboard_show_the_one_scenario(watertank, tmp_path):
    from playwright.sync_api import expect
    from support.pages import browser_page, open_dashboard

    space, report = watertank
    ranking = rank(space.output, space.name)
    page_file = write_report(space.output, tmp_path / "report.html", space.name)
    errors: list[str] = []
    server = subprocess.Popen(
        [sys.executable, "-m", "dse_runner", "dashboard", str(space.output)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        match = re.search(r"http://127\.0\.0\.1:\d+/", server.stdout.readline())
        assert match, server.stderr.read()
        with browser_page(errors, viewport={"width": 1300, "height": 1600}) as page:
            open_dashboard(page, match[0])
            expect(page.locator("#dse-track")).to_have_text(
                re.compile(r"^nominal: best point"), timeout=60_000
            )
            done, track = page.locator("#dse-done").inner_text(), page.locator("#dse-track").inner_text()
            page.goto(page_file.as_uri())
            text = page.locator("body").inner_text()
    finally:
        server.terminate()
        server.wait(timeout=10)
    assert errors == []
    assert done.startswith(f"{report.total} of {report.total}")
    assert track.endswith(f"{ranking.best_total:.4f}")  # the best point's level deviation, simulated again
    assert re.search(r"nominal\s+\S+\s+[\d.]+", text) and f"{ranking.best_total:.4f}" in text


def _recording_script():
    """jobs/msd/make_recording.py, which says what truth and noise made the recording."""
    spec = importlib.util.spec_from_file_location("make_recording", MSD / "make_recording.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_msd_model_exchange_calibration_finds_the_recordings_truth(job_space, dask_scheduler):
    script = _recording_script()
    truth = script.TRUTH
    grid = {
        "msd.k": [truth["k"] - 2, truth["k"], truth["k"] + 2],
        "msd.c": [truth["c"] - 0.3, truth["c"], truth["c"] + 0.3],
    }
    space = job_space(MSD, parameters=grid, cluster={"address": dask_scheduler})
    assert space.plan.interfaces == {"msd": "me"}
    report = submit(space)
    assert (report.total, report.failed) == (9, 0)
    best = rank(space.output, space.name).best
    assert best == {"msd.k": truth["k"], "msd.c": truth["c"]}
    # The recording is the truth plus sensor noise: the best fit's error is the noise's size.
    fit = simulate(
        space.plan, space.scenarios[0], best, objectives=space.objectives, experiment=space.experiment
    )
    assert 0.5 * script.NOISE_SIGMA < fit.objectives["position_rmse"] < 1.5 * script.NOISE_SIGMA


def test_the_jobs_run_from_the_cli_as_their_readme_says(tmp_path, dask_scheduler):
    from typer.testing import CliRunner

    from dse_runner.interfaces.cli import app

    path = _job_space(
        WATERTANK,
        tmp_path,
        output=str(tmp_path / "out"),
        parameters={"controller.minlevel": [1.0], "controller.maxlevel": [2.0, 2.2]},
    )
    try:
        result = CliRunner().invoke(
            app, ["submit", str(path), "--scheduler", dask_scheduler, "--no-dashboard", "--json"]
        )
    finally:
        path.unlink()
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["ok"] == 2 and summary["best"]["controller.maxlevel"] in (2.0, 2.2)
