"""jobs/robotti-control: the path controller tuned on the diagnosed plant, run end to end on a small budget
on the real cluster, and the tuned gains reproduced from the command line as the README says."""

from __future__ import annotations

import json
import subprocess
import sys

import yaml
from conftest import REPO

from dse_runner.simulation.values import read_values
from dse_runner.sweeps.rank import rank
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit

JOB = REPO / "jobs" / "robotti-control"
PATHS = REPO / "scenarios" / "robotti-paths"


def job_space(name: str, tmp_path, **changes):
    """One of the job's spaces beside its files (relative paths kept), with ``changes`` applied."""
    spec = yaml.safe_load((JOB / name).read_text()) | changes
    path = JOB / f".test-{tmp_path.name}-{name}"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "dse_runner", *args], capture_output=True, text=True, cwd=REPO, check=False
    )


def test_the_pareto_search_runs_every_path_on_every_plant_and_ranks_a_front(tmp_path, dask_scheduler):
    path = job_space(
        "pareto.yaml",
        tmp_path,
        output=str(tmp_path / "out"),
        cluster={"address": dask_scheduler},
        search={"strategy": "nsga2", "max_points": 8, "seed": 1, "population_size": 4},
    )
    try:
        space = load_space(path)
    finally:
        path.unlink()
    plants = yaml.safe_load((JOB / "plants.yaml").read_text())
    paths = sorted(p.name for p in PATHS.iterdir() if (p / "path.csv").is_file())
    assert sorted(s.name for s in space.scenarios) == sorted(
        f"{p}-{v['name']}" for p in paths for v in plants
    )
    report = submit(space)
    assert (report.search.points, report.failed) == (8, 0) and report.ok == 8 * len(space.scenarios)
    ranking = rank(space.output, space.name)
    assert len(ranking.pareto) >= 1 and set(ranking.best) == set(space.parameters)
    front = ranking.pareto.sort_values("steering_effort")
    assert front["path_error_mean"].is_monotonic_decreasing  # more steering buys accuracy along the front


def test_the_defaults_written_as_best_values_run_again_from_the_cli(tmp_path, dask_scheduler):
    path = job_space(
        "defaults.yaml", tmp_path, output=str(tmp_path / "out"), cluster={"address": dask_scheduler}
    )
    try:
        space = load_space(path)
    finally:
        path.unlink()
    submit(space)
    written = cli("rank", str(space.output), "--best-values", str(tmp_path / "best.yaml"))
    assert written.returncode == 0, written.stderr
    assert "(mean path_error_mean " in written.stdout  # reduced by over_scenarios: mean, not summed
    assert read_values(tmp_path / "best.yaml") == {ref: values[0] for ref, values in space.parameters.items()}
    runs = []
    for values in ([], ["--values", str(tmp_path / "best.yaml")], ["--values", str(JOB / "tuned.yaml")]):
        done = cli(
            "simulate",
            str(JOB / "multimodel.yaml"),
            "--scenario",
            str(PATHS / "straight_offset"),
            *values,
            "--json",
        )
        assert done.returncode == 0, done.stderr
        runs.append(json.loads(done.stdout))
    no_values, defaults, tuned = runs
    assert {"path_error_mean", "steering_effort"} <= set(tuned["objectives"])
    assert defaults["objectives"] == no_values["objectives"]  # the FMU's defaults are the defaults.yaml point
    assert tuned["objectives"] != defaults["objectives"]
    assert {ref: tuned["values"][ref] for ref in read_values(JOB / "tuned.yaml")} == read_values(
        JOB / "tuned.yaml"
    )
