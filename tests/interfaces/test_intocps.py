"""INTO-CPS projects run unchanged: jobs/intocps-watertank, an INTO-CPS-shaped project of our own
(our water-tank FMUs, Python 3 user scripts), submitted as its dse.json on the real cluster and
compared with the same study written as space.yaml; conversion, discovery and bad input."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, strict_loads

from dse_runner.errors import DseError
from dse_runner.interfaces import intocps
from dse_runner.simulation import python2
from dse_runner.simulation.multimodel import load_multimodel
from dse_runner.simulation.objectives import Reduce
from dse_runner.simulation.run import simulate
from dse_runner.sweeps import store
from dse_runner.sweeps.spec import load_space

PROJECT = REPO / "jobs" / "intocps-watertank"
DSE = Path("DSEs/levels/levels.dse.json")
WILD = REPO.parent / "shared" / "fmus-wild"  # INTO-CPS's own example projects
needs_wild = pytest.mark.skipif(
    not WILD.is_dir(), reason=f"INTO-CPS's example projects are not beside the checkout ({WILD}); CI has them"
)


def dse_runner(*args, cwd=REPO):
    return subprocess.run(
        [sys.executable, "-m", "dse_runner", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        check=False,
    )


def copy_project(folder: Path) -> Path:
    """The project and the water-tank FMU sources its mm.json names (../../watertank/fmus/...)."""
    shutil.copytree(PROJECT, folder / "jobs" / "intocps-watertank", ignore=shutil.ignore_patterns("out"))
    shutil.copytree(REPO / "jobs" / "watertank" / "fmus", folder / "jobs" / "watertank" / "fmus")
    return folder / "jobs" / "intocps-watertank"


def edit_json(path: Path, change) -> None:
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data, indent=2))


def submit(spec: Path, out: Path, scheduler: str, *more) -> dict:
    done = dse_runner(
        "submit", spec, "--out", out, "--scheduler", scheduler, "--no-dashboard", "--json", *more
    )
    assert done.returncode in (0, 1), done.stderr
    return strict_loads(done.stdout)


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    return copy_project(tmp_path_factory.mktemp("intocps"))


@pytest.fixture(scope="module")
def both(project, dask_scheduler, tmp_path_factory):
    """The DSE config and its hand-written space.yaml, each run once on the cluster."""
    out = tmp_path_factory.mktemp("intocps-out")
    dse = submit(project / DSE, out / "dse", dask_scheduler)
    yaml = submit(project / "space.yaml", out / "yaml", dask_scheduler)
    return dse, yaml


def totals(summary: dict) -> pd.DataFrame:
    return pd.read_csv(Path(summary["ranking"]).parent / "totals.csv")


def test_the_dse_config_ranks_as_the_same_study_written_as_space_yaml(both):
    dse, yaml = both
    assert dse["ok"] == dse["ran"] == yaml["ran"] > 0 and dse["failed"] == 0
    ours, theirs = totals(dse), totals(yaml)
    assert list(ours.columns) == list(theirs.columns)
    pd.testing.assert_frame_equal(ours, theirs)  # every point, every objective, the same order
    front = [json.loads(Path(s["ranking"]).read_text())["pareto"] for s in both]
    assert front[0] == front[1] and len(front[0]) >= 2
    assert dse["best"] == yaml["best"]


def test_parameter_and_objective_constraints_hold(both, project):
    dse, _ = both
    rows = store.read_results(dse["output"], "levels")
    assert (rows["controller.maxlevel"] - rows["controller.minlevel"] >= 0.6 - 1e-12).all()
    assert len(rows) < 16  # the constraint left grid points out, unsimulated
    ranking = json.loads(Path(dse["ranking"]).read_text())
    ranked = totals(dse)
    assert (ranked["levelMax"] < 2.1).all()
    assert ranking["excluded_points"] == (rows["levelMax"] >= 2.1).sum() > 0
    assert ranking["points"] + ranking["excluded_points"] == len(rows)


def test_table1_is_over_the_points_the_constraints_admit_and_says_so(both):
    """The example's Table 1 once said "(11 points)", averaged over all 15 and showed a min below its best:
    the CLI and the report now say what the objective constraint left out, and count only what they say."""
    import html
    import re

    from dse_runner.interfaces.report import build_report

    dse, _ = both
    ranked, rows = totals(dse), store.read_results(dse["output"], "levels")
    n, excluded = len(ranked), int((rows["levelMax"] >= 2.1).sum())
    scope = f"{n} of {n + excluded} points meet levelMax < 2.1; min/max/average over the {n}"
    shown = dse_runner("rank", dse["output"])
    assert shown.returncode == 0, shown.stderr
    title, header, target = shown.stdout.splitlines()[:3]
    assert excluded > 0 and title == f"Table 1: switches per scenario ({scope})"
    figures = [float(v) for v in target.split()[1:]]  # min, max, average, best, difference
    switches = ranked["switches"]  # one scenario: a point's total is its value on it
    assert figures == pytest.approx(
        [
            switches.min(),
            switches.max(),
            switches.mean(),
            switches.iloc[0],
            switches.iloc[0] - switches.mean(),
        ],
        abs=5e-4,
    )
    page = build_report(dse["output"])
    assert f"<h2>Table 1: switches per scenario ({scope})</h2>" in html.unescape(page)
    table = page[page.index("<h2>Table 1") :].split("<h2>")[1]
    columns = [c for c in re.findall(r"<th>([^<]*)</th>", table) if c != "group"]
    assert columns == header.split()  # the CLI and the report head the columns alike


def test_internal_functions_and_scripts_compute_what_intocps_would(project):
    """INTO-CPS's mean is that of the samples; the scripts read results.csv by INTO-CPS's column ids."""
    space = intocps.load_space(project / DSE)
    point = {"controller.minlevel": 0.8, "controller.maxlevel": 1.8}
    result = simulate(
        space.plan,
        space.scenarios[0],
        point,
        objectives={**space.objectives, "changes": Reduce(signal="controller.valve", reduce="changes")},
        experiment=space.experiment,
    )
    level = result.trajectory.column("tank.level")
    scores = result.objectives
    assert scores["levelMean"] == pytest.approx(np.mean(level), rel=1e-12)
    assert (scores["levelMax"], scores["levelMin"]) == (level.max(), level.min())
    assert scores["switches"] == scores["changes"] > 0
    target = json.loads((project / "userMetricScripts/target/target.json").read_text())["level"]
    assert scores["deviation"] == pytest.approx(np.sqrt(np.mean((level - target) ** 2)), rel=1e-12)


def test_convert_writes_a_space_yaml_that_runs_where_it_is_written(project, tmp_path):
    done = dse_runner("convert-intocps", project / DSE, "-o", tmp_path / "moved" / "space.yaml", "--json")
    assert done.returncode == 0, done.stderr
    path = Path(strict_loads(done.stdout)["space"])
    converted, original = load_space(path), intocps.load_space(project / DSE)
    assert converted.spec.parameters == original.spec.parameters
    assert converted.spec.constraints == ["controller.maxlevel - controller.minlevel >= 0.6"]
    assert converted.spec.ranking == original.spec.ranking
    point = {"controller.minlevel": 1.0, "controller.maxlevel": 2.0}
    runs = [
        simulate(s.plan, s.scenarios[0], point, objectives=s.objectives, experiment=s.experiment)
        for s in (converted, original)
    ]
    assert runs[0].objectives == runs[1].objectives


def test_report_writes_intocps_result_files(both, tmp_path):
    dse, _ = both
    done = dse_runner("report", dse["output"], "-o", tmp_path / "report.html", "--json")
    assert done.returncode == 0, done.stderr
    folder = Path(strict_loads(done.stdout)["intocps"])
    ranked = totals(dse)
    rows = list(pd.read_csv(folder / "dseResults.csv").itertuples())
    assert len(rows) == len(ranked) and rows[0].Rank == 1
    assert [r.Rank for r in rows] == sorted(r.Rank for r in rows)
    ranking = json.loads((folder / "ranking.json").read_text())
    front = json.loads(Path(dse["ranking"]).read_text())["pareto"]
    assert len(ranking["pareto"]["1"]) == len(front)
    assert "<h1>pareto</h1>" in (folder / "results.html").read_text()
    assert (folder / "graphs" / "pareto.png").read_bytes()[:4] == b"\x89PNG"


def test_a_failing_script_gives_failed_rows_with_its_stderr(tmp_path, dask_scheduler):
    project = copy_project(tmp_path)
    (project / "userMetricScripts" / "switches.py").write_text(
        "import sys\nsys.exit('switches.py: no valve column in ' + sys.argv[1])\n"
    )
    summary = submit(project / DSE, tmp_path / "out", dask_scheduler)
    assert summary["failed"] == summary["ran"] > 0 and summary["ranking"] is None
    errors = store.read_results(summary["output"], "levels")["error"]
    assert errors.str.contains(
        r"objective 'switches': script switches.py failed \(exit code 1\): "
        r"switches.py: no valve column in"
    ).all()


def test_a_script_that_writes_no_value_fails_its_task(project):
    space = intocps.load_space(project / DSE)
    script = space.objectives["switches"].model_copy(update={"script": str(project / "FMUs" / "README.md")})
    script._code = "print('forgot to write objectives.json')\n"
    with pytest.raises(
        DseError, match=r"objective 'switches': script README.md wrote no value for 'switches'"
    ):
        simulate(
            space.plan, space.scenarios[0], {}, objectives={"switches": script}, experiment=space.experiment
        )


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            lambda d: d.update(algorithm={"type": "simulated-annealing"}),
            r"algorithm 'simulated-annealing' is not one INTO-CPS or dse-runner runs \(exhaustive, genetic\)",
        ),
        (
            lambda d: d["objectiveDefinitions"]["externalScripts"]["switches"].update(scriptFile="gone.py"),
            (
                r"objectiveDefinitions\.externalScripts\.switches: "
                r"script not found: .*userMetricScripts/gone\.py"
            ),
        ),
        (
            lambda d: d["parameters"].update({"{controllerFMU}.controller.minlevle": [1]}),
            r"parameters: unknown variable 'controller\.minlevle': .* \(did you mean minlevel",
        ),
        (
            lambda d: d.update(parameterConstraints=["math.sqrt({controllerFMU}.controller.maxlevel) > 1"]),
            (
                r"parameterConstraints\.0: cannot translate "
                r"'math\.sqrt\(\{controllerFMU\}\.controller\.maxlevel\) > 1'"
            ),
        ),
        (
            lambda d: d.update(objectiveConstraints=["levelMax < __import__('os').getpid()"]),
            r"objectiveConstraints\.0: cannot translate \"levelMax < __import__\('os'\)\.getpid\(\)\"",
        ),
        (lambda d: d.update(ranking={"weighted": {"levelMax": "-"}}), r"ranking 'weighted' is not a ranking"),
        (lambda d: d.update(ranking={"pareto": {"lapTime": "-"}}), r"ranking\.pareto names 'lapTime'"),
    ],
)
def test_bad_intocps_input_gives_one_line_naming_it(tmp_path, change, message):
    project = copy_project(tmp_path)
    edit_json(project / DSE, change)
    done = dse_runner("submit", project / DSE, "--no-dashboard")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), done.stderr
    assert __import__("re").search(message, lines[0]), lines[0]


def test_the_coe_json_is_found_as_the_application_finds_it(tmp_path):
    project = copy_project(tmp_path)
    mm_folder = project / "Multi-models" / "watertank"
    located = intocps.project.locate(project / DSE)
    assert located.coe == (mm_folder / "experiment" / "experiment.coe.json").resolve()
    # a results copy (R_<date>/coe.json) is not a candidate; an old coe without multimodel_path is
    # associated by its folder
    (mm_folder / "experiment" / "R_2026_11_23-10_00_00_000").mkdir()
    shutil.copy(
        mm_folder / "experiment" / "experiment.coe.json",
        mm_folder / "experiment" / "R_2026_11_23-10_00_00_000",
    )
    edit_json(mm_folder / "experiment" / "experiment.coe.json", lambda d: d.pop("multimodel_path"))
    assert intocps.project.locate(project / DSE).multimodel == (mm_folder / "watertank.mm.json").resolve()
    # a second multi-model whose FMUs the DSE does not name is passed over
    other = project / "Multi-models" / "other"
    (other / "run").mkdir(parents=True)
    (other / "other.mm.json").write_text(json.dumps({"fmus": {"{x}": "x.fmu"}}))
    (other / "run" / "coe.json").write_text(
        json.dumps({"endTime": 1, "algorithm": {"type": "fixed-step", "size": 1}})
    )
    assert (
        intocps.project.locate(project / DSE).coe
        == (mm_folder / "experiment" / "experiment.coe.json").resolve()
    )
    # two that both fit: the error lists them, and --coe chooses
    shutil.copytree(mm_folder / "experiment", mm_folder / "fast", ignore=shutil.ignore_patterns("R_*"))
    with pytest.raises(
        DseError,
        match=r"several co-simulation configs could run this DSE \(.*experiment.coe.json, "
        r".*fast/experiment.coe.json\); choose one with --coe",
    ):
        intocps.project.locate(project / DSE)
    chosen = intocps.project.locate(project / DSE, coe=mm_folder / "fast" / "experiment.coe.json")
    assert chosen.multimodel == (mm_folder / "watertank.mm.json").resolve()


def test_a_variable_step_config_runs_at_its_initial_step_with_a_warning(tmp_path):
    project = copy_project(tmp_path)
    coe = project / "Multi-models/watertank/experiment/experiment.coe.json"
    edit_json(
        coe,
        lambda d: d.update(
            algorithm={
                "type": "var-step",
                "initsize": 0.05,
                "size": [0.1, 1],
                "constraints": {"max": {"type": "fmumaxstepsize"}},
            }
        ),
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        space = intocps.load_space(project / DSE)
    assert space.experiment.step == 0.1  # the initial size, clamped into the size range
    assert any(
        "variable-step algorithm becomes a fixed step of 0.1 s" in str(w.message)
        and "constraints (max)" in str(w.message)
        for w in caught
    )


def test_genetic_becomes_nsga2_for_a_pareto_ranking_and_genetic_for_one_objective(tmp_path, dask_scheduler):
    project = copy_project(tmp_path)
    edit_json(
        project / DSE,
        lambda d: d.update(
            algorithm={
                "type": "genetic",
                "initialPopulation": 4,
                "initialPopulationDistribution": "random",
                "mutationProbability": 20,
                "parentSelectionStrategy": "random",
                "maxGenerationsWithoutImprovement": 3,
            }
        ),
    )
    search = intocps.load_space(project / DSE).spec.search
    assert search.strategy == "nsga2" and search.options == {"population_size": 4, "mutation_prob": 0.2}
    summary = submit(project / DSE, tmp_path / "out", dask_scheduler, "--max-points", "8")
    assert summary["search"]["strategy"] == "nsga2" and summary["search"]["points"] == 8
    edit_json(project / DSE, lambda d: d.update(ranking={"pareto": {"deviation": "-"}}))
    search = intocps.load_space(project / DSE).spec.search
    assert search.strategy == "genetic" and search.options == {
        "population": 4,
        "mutation_probability": 0.2,
        "max_generations_without_improvement": 3,
    }


def test_mm_json_connections_of_every_type(tmp_path):
    """Integer and Boolean connections as INTO-CPS writes them, through an FMU with every FMI 2 type."""
    types2 = REPO / "tests" / "fmus" / "types2"
    mm = tmp_path / "types.mm.json"
    mm.write_text(
        json.dumps(
            {
                "fmus": {"{t}": str(types2)},
                "connections": {
                    "{t}.a.int_out": ["{t}.b.int_in"],
                    "{t}.a.bool_out": ["{t}.b.bool_in"],
                    "{t}.a.real_out": ["{t}.b.real_in"],
                },
                "parameters": {"{t}.a.int_offset": 3, "{t}.b.int_offset": 4, "{t}.b.invert": True},
            }
        )
    )
    out = simulate(mm, stop_time=1, step=0.5).trajectory.outputs  # int_out = int_in + int_offset + steps
    assert (out["a.int_out"] == 3 + out["a.steps"]).all()
    # b's inputs are a's outputs of the communication point before
    assert (out["b.int_out"][1:] == out["a.int_out"][:-1] + 4 + out["b.steps"][1:]).all()
    assert (out["b.bool_out"][1:] == 1 - out["a.bool_out"][:-1]).all()  # bool_out = bool_in XOR invert
    mm.write_text(
        json.dumps(
            {
                "fmus": {"{t}": str(types2), "{u}": str(types2)},
                "connections": {"{t}.a.int_out": ["{u}.a.int_in"]},
            }
        )
    )
    with pytest.raises(DseError, match=r"instance 'a' belongs to two FMUs, \{t\} and \{u\}"):
        simulate(mm, stop_time=1, step=0.5)


def failing_script(project: Path) -> None:
    """switches.py raising on its third line."""
    (project / "userMetricScripts" / "switches.py").write_text("import sys\n\nratio = 1 / 0\n")


def test_a_failing_script_is_reported_by_its_exception_line(tmp_path, dask_scheduler):
    """submit prints each failure's first line: the script's exception, not
    'Traceback (most recent call last):'."""
    project = copy_project(tmp_path)
    failing_script(project)
    done = dse_runner(
        "submit", project / DSE, "--out", tmp_path / "out", "--scheduler", dask_scheduler, "--no-dashboard"
    )
    failed = [line for line in done.stdout.splitlines() if line.startswith("  failed: ")]
    assert failed and "Traceback" not in done.stdout, done.stdout
    assert all(
        line.endswith(
            "objective 'switches': script switches.py failed (exit code 1) at line 3: "
            "ZeroDivisionError: division by zero"
        )
        for line in failed
    ), failed
    error = store.read_results(tmp_path / "out", "levels")["error"].iloc[0]
    assert "Traceback (most recent call last):" in error.splitlines()[1]  # the traceback follows


def test_submit_exits_1_alike_with_and_without_json_when_nothing_is_ranked(tmp_path, dask_scheduler):
    project = copy_project(tmp_path)
    failing_script(project)
    runs = {
        flags: dse_runner(
            "submit",
            project / DSE,
            "--out",
            tmp_path / f"out{len(flags)}",
            "--scheduler",
            dask_scheduler,
            "--no-dashboard",
            *flags,
        )
        for flags in ((), ("--json",))
    }
    assert [done.returncode for done in runs.values()] == [1, 1], [done.stderr for done in runs.values()]
    for done in runs.values():
        assert (
            done.stderr.strip()
            .splitlines()[-1]
            .startswith("error: no ranking: sweep 'levels': no parameter point has an ok result")
        )
    summary = strict_loads(runs[("--json",)].stdout)  # nothing but the JSON on stdout
    assert summary["ranking"] is None and summary["failed"] == summary["ran"] > 0


def test_a_dse_naming_instances_no_multimodel_defines_names_them(tmp_path):
    project = copy_project(tmp_path)
    other = project / "Multi-models" / "other"
    (other / "run").mkdir(parents=True)
    (other / "run" / "coe.json").write_text(
        json.dumps({"endTime": 1, "algorithm": {"type": "fixed-step", "size": 1}})
    )
    mm = {
        "fmus": {"{controller}": "c.fmu", "{tankFMU}": "t.fmu"},
        "connections": {"{controller}.controller.valve": ["{tankFMU}.tanks.valvecontrol"]},
    }
    (other / "other.mm.json").write_text(json.dumps(mm))
    dse = project / DSE
    dse.write_text(dse.read_text().replace("{controllerFMU}", "{controller}"))
    with pytest.raises(DseError) as error:
        intocps.project.locate(dse)
    assert str(error.value) == (
        "no multi-model of the project defines every {fmu}.instance this DSE names: "
        "Multi-models/other/other.mm.json lacks {tankFMU}.tank; "
        "Multi-models/watertank/watertank.mm.json lacks {controller}.controller"
    )
    mm["connections"] = {"{ctrl}.controller.valve": ["{tankFMU}.tank.valvecontrol"]}
    mm["fmus"]["{ctrl}"] = mm["fmus"].pop("{controller}")
    (other / "other.mm.json").write_text(json.dumps(mm))
    done = dse_runner("submit", dse, "--no-dashboard")  # the same from the command, with what both lack
    assert done.returncode == 2 and done.stderr.strip() == (
        "error: this DSE names {controller}.controller, which no multi-model of the project defines "
        "(looked at Multi-models/other/other.mm.json, Multi-models/watertank/watertank.mm.json; a "
        "multi-model defines the {fmu}.instance its connections and parameters name)"
    )
    with pytest.raises(
        DseError,
        match=r"^this DSE names \{controller\}\.controller, .*\(looked at "
        r"Multi-models/watertank/watertank\.mm\.json;",
    ):
        intocps.project.locate(dse, multimodel=project / "Multi-models/watertank/watertank.mm.json")


@needs_wild
def test_an_mm_json_naming_fmus_with_windows_separators_runs():
    """mass_spring_damper's mm.json names 20-Sim\\MassSpringDamper2.fmu, in the FMUs folder's 20-Sim/."""
    project = WILD / "mass_spring_damper"
    mm = project / "Multi-models" / "Stability" / "mm.json"
    model = load_multimodel(mm)
    assert model.fmu_path("i2") == (project / "FMUs" / "20-Sim" / "MassSpringDamper2.fmu").resolve()
    trajectory = simulate(mm, stop_time=0.05, step=0.001).trajectory
    x1, x2 = trajectory.column("i1.x1"), trajectory.column("i2.x2")
    assert np.isfinite(x1).all() and np.isfinite(x2).all()
    assert x1[0] == 1.0 and x2[-1] > 0  # m1 starts displaced and pulls m2 through the connections


def test_our_multimodel_reads_backslashes_in_fmu_paths_as_slashes(tmp_path):
    types2 = REPO / "tests" / "fmus" / "types2"
    relative = __import__("os").path.relpath(types2, tmp_path).replace("/", "\\")
    (tmp_path / "mm.yaml").write_text(f"fmus: {{a: '{relative}'}}\n")
    assert load_multimodel(tmp_path / "mm.yaml").fmu_path("a") == types2.resolve()


def test_a_python2_script_that_does_not_port_is_refused_with_its_line(tmp_path):
    """Python 2 accepted a tab after spaces where Python 3 cannot tell the indentation: fissix keeps the
    line, so the ported script still does not compile; one line names the script, the line and both
    reasons, and nothing runs."""
    project = copy_project(tmp_path)
    (project / "userMetricScripts" / "switches.py").write_text(
        "import sys\n\nif len(sys.argv) > 2:\n        x = 1\n\ty = 2\nprint sys.argv[2]\n"
    )
    done = dse_runner("submit", project / DSE, "--out", tmp_path / "out", "--no-dashboard")
    assert done.returncode == 2 and not (tmp_path / "out").exists()
    (line,) = done.stderr.strip().splitlines()
    script = str((project / "userMetricScripts" / "switches.py").resolve())
    assert line.startswith(f"error: {project / DSE}: objectives.switches: {script} line 5: ") and (
        "ported by fissix it is still not Python 3: line 5: not valid Python 3: inconsistent use of tabs"
        in line
    )


def switches_and_changes(space) -> tuple[float, float]:
    """The DSE's switches script's value at one point, and what {signal:
    valve, reduce: changes} gives there."""
    result = simulate(
        space.plan,
        space.scenarios[0],
        {"controller.minlevel": 0.8, "controller.maxlevel": 1.8},
        objectives={
            "switches": space.objectives["switches"],
            "changes": Reduce(signal="controller.valve", reduce="changes"),
        },
        experiment=space.experiment,
    )
    return result.objectives["switches"], result.objectives["changes"]


def test_a_python2_script_is_ported_for_the_run_once_and_the_file_left_unchanged(tmp_path):
    """``print x`` and ``unicode()``: the run uses the ported text, one warning per script says so, the
    user's file is byte for byte as it was, and the value is what the declared objective computes."""
    project = copy_project(tmp_path)
    script = project / "userMetricScripts" / "switches.py"
    script.write_text(
        script.read_text().replace(
            "objectives[name] = switches\n", 'objectives[name] = switches\nprint "%d switches" % switches\n'
        )
    )
    before = script.read_bytes()
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        space = intocps.load_space(project / DSE)
        intocps.load_space(project / DSE)  # loaded again (a resubmission): said once
    ported = [str(w.message) for w in said if "ported to Python 3 with fissix" in str(w.message)]
    line = script.read_text().splitlines().index('print "%d switches" % switches') + 1
    assert ported == [
        (
            f"{script.resolve()} line {line}: a Python 2 script (print statement); ported to "
            "Python 3 with fissix for this run, the file unchanged"
        )
    ]
    switches, changes = switches_and_changes(space)
    assert switches == changes > 0
    assert script.read_bytes() == before


# A published INTO-CPS script's shape (the line-following robot's userMetricScripts): Python 2, its CSV opened
# with 'rU', which Python 3.11 refuses; here it counts the valve's switches as switches.py does
PUBLISHED_PYTHON2 = """import csv, os, sys, json, io

def loadCSV(f):
  with open(f, 'rU') as infile:
    reader = csv.DictReader(infile)
    data = {}
    for row in reader:
      for header, value in row.items():
        try:
          data[header.strip()].append(float(value))
        except KeyError:
          data[header.strip()] = [float(value)]
    return data

def writeObjectiveToOutfile(key, val):
  print key, val
  parsed_json = json.load(open(objectivesFile))
  parsed_json[key] = val
  dataString = json.dumps(parsed_json, sort_keys=True, indent=4, separators=(',', ': '))
  with io.open(objectivesFile, 'w', encoding='utf-8') as f:
    f.write(unicode(dataString))

objectivesFile = sys.argv[1] + os.path.sep + "objectives.json"
valve = loadCSV(sys.argv[1] + os.path.sep + "results.csv")[sys.argv[4]]
writeObjectiveToOutfile(sys.argv[2], len([1 for a, b in zip(valve, valve[1:]) if a != b]))
"""


def test_a_published_python2_script_that_opens_its_csv_with_ru_runs_every_task(
    both, tmp_path, dask_scheduler
):
    """The DSE as INTO-CPS's application submits it, its switches script a published Python 2 one that opens
    results.csv with mode 'rU': every task runs (each failed with ``ValueError: invalid mode: 'rU'``), each
    point's value is the Python 3 script's, one warning names the port, and the file is byte for byte as
    written."""
    project = copy_project(tmp_path)
    script = project / "userMetricScripts" / "switches.py"
    script.write_bytes(PUBLISHED_PYTHON2.encode())
    done = dse_runner(
        "submit",
        project / DSE,
        "--out",
        tmp_path / "out",
        "--scheduler",
        dask_scheduler,
        "--no-dashboard",
        "--json",
    )
    assert done.returncode == 0, done.stderr
    summary = strict_loads(done.stdout)
    assert summary["ok"] == summary["ran"] == both[0]["ran"] and summary["failed"] == 0, summary["errors"]
    lines = PUBLISHED_PYTHON2.splitlines()
    printed, opened = lines.index("  print key, val") + 1, lines.index("  with open(f, 'rU') as infile:") + 1
    told = (
        f"{script.resolve()} line {printed}: a Python 2 script (print statement); ported to Python 3 with "
        f"fissix for this run (and line {opened}: open mode 'rU' -> 'r' (Python 3.11 refuses 'U')), the file "
        "unchanged"
    )
    assert done.stderr.count(told) == 1, done.stderr
    pd.testing.assert_frame_equal(totals(summary), totals(both[0]))  # the Python 3 script's switches, and all
    assert script.read_bytes() == PUBLISHED_PYTHON2.encode()


@pytest.mark.parametrize(
    ("code", "line", "what"),
    [
        ("import sys\nprint sys.argv\n", 2, "print statement"),
        ("import sys\nprint >>sys.stderr, 'x'\n", 2, "print statement"),
        ("x = 1\nprint\n", 2, "print statement"),
        ("exec 'x = 1'\n", 1, "exec statement"),
        ("try:\n    pass\nexcept IOError, e:\n    pass\n", 3, "except X, e"),
        ("raise ValueError, 'no'\n", 1, "raise X, message"),
        ("if 1 <> 2:\n    pass\n", 1, "the <> operator"),
        ("x = 10L\n", 1, "a long literal such as 10L"),
        ("x = 0777\n", 1, "an octal literal such as 0777"),
        ("x = `1`\n", 1, "backquotes for repr"),
        ("x = 1\ny = unicode(x)\n", 2, "unicode(), which Python 3 does not have"),
        ("for i in xrange(3):\n    pass\n", 1, "xrange(), which Python 3 does not have"),
        ("d = {}\nif d.has_key('a'):\n    pass\n", 2, ".has_key(), a dict method Python 3 does not have"),
        ("import urllib2\n", 1, "module urllib2, which Python 3 renamed or removed"),
        ("from StringIO import StringIO\n", 1, "module StringIO, which Python 3 renamed or removed"),
        ("import string\nx = string.letters\n", 2, "string.letters, which Python 3 does not have"),
        ("import sys\nx = sys.maxint\n", 2, "sys.maxint, which Python 3 does not have"),
        ("lines = file('a.csv').readlines()\n", 1, "file(), which Python 3 does not have"),
    ],
)
def test_python2_is_told_from_python3(code, line, what):
    with pytest.raises(DseError) as error:
        python2.check(code, Path("/scripts/metric.py"))
    assert str(error.value) == (
        f"/scripts/metric.py line {line}: a Python 2 script ({what}); dse-runner runs "
        "scripts with Python 3 (docs/intocps.md)"
    )
    ported, note = python2.as_python3(code, Path("/scripts/metric.py"))
    told = f"line {line}: a Python 2 script ({what}); ported to Python 3 with fissix for this run"
    assert note.startswith(told) and note.endswith(", the file unchanged")
    python2.check(ported, Path("/scripts/metric.py"))  # what runs is Python 3


@pytest.mark.parametrize(
    ("code", "message"),
    [
        ("x = 1\ndef f(:\n    pass\n", "line 2: not valid Python 3: invalid syntax"),
        ("x = 1\nreturn x\n", "line 2: not valid Python 3: 'return' outside function"),
        ("import sys\nprint('x', file=sys.stderr)\nprinter = print\n", None),
        ("try:\n    unicode\nexcept NameError:\n    unicode = str\nprint(unicode(1))\n", None),  # for both
        ("try:\n    from StringIO import StringIO\nexcept ImportError:\n    from io import StringIO\n", None),
        ("from functools import reduce\nlong = int\nprint(reduce(max, [long(1)]))\n", None),
    ],
)
def test_python3_scripts_pass_and_other_syntax_errors_are_named(code, message):
    if message is None:
        python2.check(code, Path("/scripts/metric.py"))
        return
    with pytest.raises(DseError, match=f"^/scripts/metric.py {message}$"):
        python2.check(code, Path("/scripts/metric.py"))


def test_the_scripts_of_docs_intocps_run_as_written(tmp_path):
    """docs/intocps.md's two valveChanges.py: the Python 2 one, written for the command line without the data
    folder, is ported and called without it; the Python 3 one, written for INTO-CPS's later command line, is
    called with it. Both count the valve's switches as the declared objective does."""
    text = (REPO / "docs" / "intocps.md").read_text().split("## Python 2 scripts and the command line")[1]
    scripts = [block.split("```")[0] for block in text.split("```python\n")[1:3]]
    project = copy_project(tmp_path)
    script = project / "userMetricScripts" / "switches.py"
    for code, python2_line in zip(scripts, ["line 10: a Python 2 script (print statement)", None]):
        script.write_text(code)
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            space = intocps.load_space(project / DSE)
        ported = [str(w.message) for w in said if "ported" in str(w.message)]
        assert ported == (
            [
                (
                    f"{script.resolve()} {python2_line}; ported to Python 3 with fissix for this run, "
                    "the file unchanged"
                )
            ]
            if python2_line
            else []
        )
        assert space.objectives["switches"].data_folder is (python2_line is None)
        switches, changes = switches_and_changes(space)
        assert switches == changes > 0


@pytest.mark.parametrize(
    ("code", "arguments", "takes"),
    [
        (
            "import sys\ncolumn, target = sys.argv[3], float(sys.argv[4])\n",
            2,
            False,
        ),  # INTO-CPS's published ones
        (
            "import sys\ndata, column, target = sys.argv[3], sys.argv[4], sys.argv[5]\n",
            2,
            True,
        ),  # example-fcu's
        ("import sys\nfolder, name, data, a, b, c = sys.argv[1:7]\n", 3, True),  # a fixed slice
        ("from sys import argv\nfolder, name, column = argv[1], argv[2], argv[3]\n", 1, False),
        ("import sys\nname = sys.argv[2]\n", 0, True),  # no parameters: the data folder harms nothing
    ],
)
def test_the_command_line_a_script_expects_is_read_from_it(code, arguments, takes):
    from dse_runner.simulation.script_convention import convention

    assert convention(code, arguments, "s.py") == (convention(code, arguments, "s.py").__class__(takes))


@pytest.mark.parametrize(
    "code",
    [
        "import sys\nrest = sys.argv[3:]\n",
        "import sys\nx = sys.argv[7]\n",
        "import sys\ni = 3\nx = sys.argv[i]\n",
        "print('no arguments read')\n",
    ],
)
def test_a_script_whose_command_line_cannot_be_read_gets_the_data_folder_and_a_line_saying_so(code):
    from dse_runner.simulation.script_convention import convention

    chosen = convention(code, 1, "s.py")
    assert chosen.data_folder and chosen.note.startswith("s.py reads ")
    assert chosen.note.endswith(
        "passing the scenario's data folder as its third argument, as INTO-CPS's DSE "
        "scripts do (data_folder: false leaves it out)"
    )


def test_results_csv_has_the_step_size_column_intocps_writes(tmp_path):
    """0 on the first row, then the step that reached each row (Maestro's outputs.csv: 0.0, 0.05, 0.05...)."""
    import csv

    from dse_runner.simulation.scripts import write_results
    from dse_runner.simulation.trajectory import Trajectory

    time = np.array([0.0, 0.05, 0.1, 0.15000000000000002, 0.2])
    trajectory = Trajectory(time, ["a.x"], np.arange(5.0)[:, None], {})
    write_results(tmp_path / "results.csv", trajectory, {"{a}.a.x": "a.x"})
    with open(tmp_path / "results.csv") as written:
        rows = list(csv.reader(written))
    assert rows[0] == ["time", "step-size", "a.x", "{a}.a.x"]
    assert [float(r[1]) for r in rows[1:]] == [0.0, *np.diff(time)]
