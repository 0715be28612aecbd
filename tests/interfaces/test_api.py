"""The Python API (docs/python.md): each command a function of ``dse_runner`` that returns Python objects,
the CLI a shell over the same functions, and Ctrl-C keeping every finished result as the command does."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time

import pyarrow as pa
import pytest
import yaml
from conftest import REPO, SCENARIOS, sleeper_multimodel, strict_loads, write_space
from conftest import dse_runner as command

import dse_runner as dse
from dse_runner import strict_json
from dse_runner.errors import DseError
from dse_runner.interfaces import api
from dse_runner.sweeps.spec import load_space

QUICKSTART = REPO / "jobs" / "quickstart"
MSD_FMU = REPO / "jobs" / "msd" / "fmus" / "msd"
ISHIGAMI = REPO / "jobs" / "ishigami"


def quickstart_sweep(folder, **changes):
    """jobs/quickstart/sweep.yaml (40 points of the mass-spring-damper, its own objective module beside
    it) in ``folder``, ``changes`` applied."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(QUICKSTART / "scores.py", folder)
    spec = yaml.safe_load((QUICKSTART / "sweep.yaml").read_text())
    spec.update(multimodel=str(MSD_FMU), output=str(folder / "out"), **changes)
    (folder / "sweep.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return folder / "sweep.yaml"


def test_the_package_exports_the_api_and_imports_it_on_first_use():
    """``import dse_runner`` loads neither Dask nor pandas nor FMPy (the CLI starts fast); each name is the
    API's own function on first use."""
    script = (
        "import sys, dse_runner\n"
        "print([m for m in ('dask', 'distributed', 'pandas', 'fmpy') if m in sys.modules])\n"
        "from dse_runner import Diagnosis, Interrupted, Study, diagnose, rank, report, sensitivity, submit\n"
        "from dse_runner.interfaces import api\n"
        "print(submit is api.submit and Study is api.Study and diagnose is api.diagnose\n"
        "      and rank is api.rank and report is api.report and sensitivity is api.sensitivity\n"
        "      and Diagnosis is api.Diagnosis and issubclass(Interrupted, KeyboardInterrupt))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], check=False, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:2] == ["[]", "True"]
    assert set(dse.__all__) <= set(dir(dse))
    with pytest.raises(AttributeError, match="no attribute 'sumbit'"):
        dse.sumbit  # noqa: B018


def test_bad_input_is_one_line_before_any_cluster_starts(tmp_path):
    started = time.monotonic()
    with pytest.raises(DseError, match="cannot read space.yaml .*missing.yaml"):
        dse.submit(tmp_path / "missing.yaml")
    loaded = load_space(quickstart_sweep(tmp_path))
    with pytest.raises(DseError, match="multimodel and coe go with a spec file"):
        dse.submit(loaded, multimodel=MSD_FMU)
    with pytest.raises(DseError, match="--folds 1: cross-validation needs 2 folds or more"):
        dse.diagnose(tmp_path / "sweep.yaml", folds=1)
    with pytest.raises(DseError, match="no results"):
        dse.Study(tmp_path)
    assert time.monotonic() - started < 30  # no cluster was started for any of them
    assert api.interrupted_line(None) == "interrupted before the sweep started; nothing was lost"


@pytest.fixture(scope="module")
def study(tmp_path_factory, dask_scheduler):
    """The quickstart's grid submitted from Python to the test's cluster, its progress told to a list."""
    spec = quickstart_sweep(tmp_path_factory.mktemp("api"), cluster={"address": dask_scheduler})
    reports = []
    return dse.submit(spec, progress=reports.append), reports, spec


def test_submit_returns_the_study_with_its_rows_as_pandas_or_arrow(study):
    study, reports, _ = study
    assert reports and (reports[-1].ran, reports[-1].failed) == (40, 0)  # the caller's own progress
    rows = study.results()
    assert len(rows) == study.status.total == 40 and (rows["status"] == "ok").all()
    assert {"msd.k", "msd.c", "settle", "overshoot", "wall_time"} <= set(rows.columns)
    table = study.results(arrow=True)
    assert isinstance(table, pa.Table) and sorted(table["task_id"].to_pylist()) == sorted(rows["task_id"])
    assert set(study.results(columns=["settle"]).columns) == {"task_id", "sweep", "scenario", "settle"}
    assert study.files["json"].endswith("ranking.json")  # submit ranked, as the command does


def test_best_rank_and_report_are_the_commands(study, tmp_path):
    study, _, _ = study
    ranked = command("rank", study.output, "--json")
    assert ranked.returncode == 0, ranked.stderr
    assert study.best == strict_loads(ranked.stdout)["best"] == {"msd.k": 16.0, "msd.c": 6.0}
    ranking = study.rank(objective="overshoot", best_values=tmp_path / "best.yaml")
    assert ranking.objective == "overshoot" and study.best == ranking.best != {"msd.k": 16.0, "msd.c": 6.0}
    assert yaml.safe_load((tmp_path / "best.yaml").read_text()) == ranking.best
    path = study.report(tmp_path / "report.html")
    assert path == tmp_path / "report.html" and path.read_text().lstrip().lower().startswith("<!doctype html")


def test_a_study_submitted_again_or_opened_is_the_same(study):
    study, _, spec = study
    again = dse.submit(spec, progress=False)
    assert (again.status.skipped, again.status.ran) == (40, 0)  # resumed: nothing to run
    assert again.best == {"msd.k": 16.0, "msd.c": 6.0}
    opened = dse.Study(study.output)
    assert (opened.name, opened.status.total) == ("quickstart-sweep", 40)
    assert opened.best == again.best and repr(opened).startswith("Study('quickstart-sweep' in ")
    track = opened.trajectory()
    assert {"time", "msd.x"} <= set(track.columns) and len(track) > 100
    with pytest.raises(DseError, match="no trajectory of the best point 99 on 'nominal'"):
        opened.trajectory(rank=99)


def test_sensitivity_is_the_commands_and_warns_in_python(tmp_path, dask_scheduler):
    """The indices Python returns are those `dse-runner sensitivity --json` prints; their warning (a small
    sample) is a Python warning; figures are written where asked."""
    spec = yaml.safe_load((ISHIGAMI / "space.yaml").read_text())
    spec.update(
        multimodel={"fmus": {"ishigami": str(ISHIGAMI / "fmus" / "ishigami")}},
        output=str(tmp_path / "out"),
        cluster={"address": dask_scheduler},
        search={"strategy": "sobol_indices", "max_points": 1000},
    )
    (tmp_path / "space.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    study = dse.submit(tmp_path / "space.yaml", progress=False, rank=False)
    assert study.ranking is None and study.status.ok == 1000
    with pytest.warns(UserWarning, match=r"max_points >="):
        found = dse.sensitivity(study, figures=tmp_path / "figures")
    assert (tmp_path / "figures" / "sensitivity-y.png").stat().st_size > 0
    printed = command("sensitivity", tmp_path / "out", "--json")
    assert printed.returncode == 0, printed.stderr
    assert {**json.loads(strict_json.dumps(found.to_json())), "figures": {}} == strict_loads(printed.stdout)
    with pytest.warns(UserWarning, match=r"max_points >="):
        assert study.sensitivity(resamples=100).to_json() == found.to_json()


INTERRUPTED = """
import json, sys

import dse_runner

if __name__ == "__main__":  # the local cluster's workers re-import this file
    try:
        dse_runner.submit(sys.argv[1])
    except dse_runner.Interrupted as interrupt:
        rows = len(interrupt.study.results(columns=[]))
        print(json.dumps({"line": interrupt.line, "rows": rows}))
        sys.exit(130)
"""


@pytest.mark.slow  # Ctrl-C to a Python program's process group mid-sweep, on a local cluster it started
def test_ctrl_c_keeps_finished_results_and_the_study_reads_them(tmp_path):
    """As in a terminal (or a kernel's interrupt, which jupyter_client sends to the kernel's process group):
    SIGINT to the program and its local cluster's workers once a first row is on disk. submit raises
    Interrupted, whose line counts the rows on disk and whose study reads them (a submit that finds them
    runs the rest: tests/sweeps/test_interrupt.py, which also explains the sleeper FMU's 3.4 s tasks)."""
    spec = write_space(
        tmp_path,
        multimodel=str(sleeper_multimodel(tmp_path)),
        scenarios=[str(SCENARIOS / "sin1")],
        parameters={"sleeper.pause": [0.002 + k * 1e-5 for k in range(8)]},
        keep_trajectories=0,
        chunk_seconds=0.05,
        cluster={"n_workers": 2},
    )
    script = tmp_path / "study.py"
    script.write_text(INTERRUPTED)
    process = subprocess.Popen(
        [sys.executable, str(script), str(spec)],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # noqa: PLW1509  (only that)
    )
    deadline = time.monotonic() + 300
    while not any((tmp_path / "out" / "results").rglob("part-*.parquet")):
        assert process.poll() is None, f"submit ended before it could be interrupted: {process.communicate()}"
        assert time.monotonic() < deadline, "no row was ever written"
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGINT)
    out, err = process.communicate(timeout=600)
    assert process.returncode == 130, err
    assert "Traceback" not in err, err  # neither the program's nor its workers'
    said = json.loads(out)
    match = re.fullmatch(
        r"interrupted: (\d+) of (\d+) tasks have results in (.+); submit again to finish the rest",
        said["line"],
    )
    assert match, said
    done, total = int(match[1]), int(match[2])
    assert 0 < done < total == 8 and said["rows"] == done
    assert len(dse.Study(tmp_path / "out").results()) == done  # on disk, for the next submit to skip
