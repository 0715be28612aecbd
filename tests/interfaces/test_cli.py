"""The dse-runner command as a user runs it: a real subprocess."""

from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import MULTIMODEL, REPO, SCENARIOS, dse_runner, strict_loads


def test_simulate_json_prints_only_json_and_writes_track(tmp_path):
    done = dse_runner(
        "simulate",
        MULTIMODEL,
        "--scenario",
        SCENARIOS / "sin1",
        "--set",
        "vehicle.mass=1500",
        "--out",
        tmp_path,
        "--json",
    )
    assert done.returncode == 0, done.stderr
    report = strict_loads(done.stdout)
    assert set(report["objectives"]) == {"cross_track_error", "max_error", "rms_error", "final_error"}
    assert report["values"]["vehicle.mass"] == 1500.0
    assert 0 < report["objectives"]["cross_track_error"] <= report["objectives"]["max_error"]
    header = (tmp_path / "trajectory.csv").read_text().splitlines()[0]
    assert header.startswith("time,") and "vehicle.x" in header
    assert (tmp_path / "plot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"  # field data: the track
    assert (report["trajectory"], report["plot"]) == (
        str(tmp_path / "trajectory.csv"),
        str(tmp_path / "plot.png"),
    )
    assert report["scenario"] == "sin1" and report["dropouts"] == 0 and "vehicle.x" in report["final"]


def test_simulate_prints_objectives(tmp_path):
    done = dse_runner("simulate", MULTIMODEL, "-s", SCENARIOS / "speed_step2", "--out", tmp_path)
    assert done.returncode == 0, done.stderr
    assert "cross_track_error" in done.stdout and "trajectory:" in done.stdout


def test_unknown_set_variable_exits_2_naming_it(tmp_path):
    done = dse_runner(
        "simulate",
        MULTIMODEL,
        "-s",
        SCENARIOS / "sin1",
        "--set",
        "vehicle.cAlpha=1",
        "--out",
        tmp_path,
        "--json",
    )
    assert done.returncode == 2
    assert done.stdout == ""
    assert "unknown variable 'vehicle.cAlpha'" in done.stderr and "cAlphaF" in done.stderr


def test_missing_multimodel(tmp_path):
    done = dse_runner("simulate", tmp_path / "none.yaml", "-s", SCENARIOS / "sin1")
    assert done.returncode == 2 and "cannot read multi-model" in done.stderr


def test_build_fmus_json(tmp_path):
    done = dse_runner("build-fmus", "--out", tmp_path, "--json")
    assert done.returncode == 0, done.stderr
    built = strict_loads(done.stdout)["fmus"]
    assert set(built) == {
        "robotti_vehicle",
        "robotti_vehicle_effects",
        "replay_controller",
        "path_controller",
    }
    assert all((tmp_path / f"{name}.fmu").is_file() for name in built)


def test_every_commands_help_fits_80_columns_and_names_its_flags_plainly():
    """A terminal of 80 columns shows every option whole (no cut names), and a flag is shown as a flag."""
    import os

    helps = {}
    for command in (
        "submit",
        "rank",
        "dashboard",
        "report",
        "diagnose",
        "simulate",
        "build-fmus",
        "convert-intocps",
        "sensitivity",
    ):
        done = subprocess.run(
            [sys.executable, "-m", "dse_runner", command, "--help"],
            check=False,
            capture_output=True,
            text=True,
            cwd=REPO,
            env={**os.environ, "COLUMNS": "80"},
        )
        assert done.returncode == 0, done.stderr
        helps[command] = done.stdout
    for command, text in helps.items():
        assert not [line for line in text.splitlines() if len(line) > 80], (command, text)
        assert "<bool>" not in text and "…" not in text, (command, text)
    assert "--dashboard-address" in helps["submit"] and "--no-dashboard" in helps["submit"]


ISHIGAMI = REPO / "jobs" / "ishigami"


def ishigami_space(folder, address: str, **changes):
    """jobs/ishigami/space.yaml on the test's cluster, ``changes`` applied."""
    import yaml

    spec = yaml.safe_load((ISHIGAMI / "space.yaml").read_text())
    spec.update(
        multimodel={"fmus": {"ishigami": str(ISHIGAMI / "fmus" / "ishigami")}},
        output=str(folder / "out"),
        cluster={"address": address},
        **changes,
    )
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "space.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return folder / "space.yaml"


def test_sensitivity_json_is_strict_and_warns_of_a_small_sample_on_stderr(tmp_path, dask_scheduler):
    """200 base rows: indices with intervals, and a warning naming the budget that would narrow them."""
    space = ishigami_space(tmp_path, dask_scheduler, search={"strategy": "sobol_indices", "max_points": 1000})
    assert dse_runner("submit", space, "--no-dashboard", "--json").returncode == 0
    done = dse_runner("sensitivity", tmp_path / "out", "--json")
    assert done.returncode == 0, done.stderr
    found = strict_loads(done.stdout)
    assert (found["method"], found["design"]["blocks"], found["design"]["block"]) == ("sobol", 200, 5)
    x1 = found["objectives"]["y"]["parameters"]["ishigami.x1"]
    assert set(x1) == {"S1", "S1_conf", "ST", "ST_conf"} and 0 < x1["S1"] < x1["ST"] < 1
    assert found["objectives"]["y"]["groups"] == {}  # one scenario
    assert "warning: y (all scenarios): intervals up to +/-" in done.stderr and "max_points >=" in done.stderr
    text = dse_runner("sensitivity", tmp_path / "out")
    assert (
        text.returncode == 0 and "ishigami.x3" in text.stdout and "S1" in text.stdout and "+/-" in text.stdout
    )


def test_sensitivity_errors_name_the_culprit(tmp_path, dask_scheduler):
    """A grid sweep, an objective the sweep lacks, too small a budget, text values: each one line, exit 2."""
    grid = ishigami_space(
        tmp_path / "grid",
        dask_scheduler,
        search={"strategy": "exhaustive"},
        parameters={"ishigami.x1": [0, 1], "ishigami.x2": [0, 1], "ishigami.x3": [0, 1]},
    )
    assert dse_runner("submit", grid, "--no-dashboard", "--json").returncode == 0
    done = dse_runner("sensitivity", tmp_path / "grid" / "out")
    assert done.returncode == 2 and done.stdout == ""
    assert "sampled by 'exhaustive'; sensitivity reads a sweep sampled for it" in done.stderr

    small = ishigami_space(
        tmp_path / "small", dask_scheduler, search={"strategy": "sobol_indices", "max_points": 20}
    )
    assert dse_runner("submit", small, "--no-dashboard", "--json").returncode == 0
    done = dse_runner("sensitivity", tmp_path / "small" / "out", "--objective", "z")
    assert done.returncode == 2 and "objective 'z' is not among sweep 'ishigami''s (y)" in done.stderr
    # a misspelt name suggests the nearest (issue 63)
    done = dse_runner("sensitivity", tmp_path / "small" / "out", "--objective", "Y")
    assert done.returncode == 2 and "is not among sweep 'ishigami''s (y) (did you mean y?)" in done.stderr
    done = dse_runner("rank", tmp_path / "small" / "out", "--sweep", "ishigam")
    assert (
        done.returncode == 2
        and "no sweep 'ishigam' (did you mean ishigami?); it holds ishigami" in done.stderr
    )
    done = dse_runner("rank", tmp_path / "small" / "out", "--objective", "Y")
    assert done.returncode == 2 and "not among the sweep's (y) (did you mean y?)" in done.stderr

    few = ishigami_space(
        tmp_path / "few", dask_scheduler, search={"strategy": "sobol_indices", "max_points": 4}
    )
    done = dse_runner("submit", few, "--no-dashboard")
    assert (
        done.returncode == 2
        and "search: sobol_indices needs at least 5 points for 3 parameters" in done.stderr
    )

    spent = ishigami_space(
        tmp_path / "spent",
        dask_scheduler,
        search={"strategy": "morris", "max_points": 60},
        parameters={"ishigami.x1": {"low": -1, "high": 1}, "ishigami.x2": {"low": -1, "high": 1}},
    )
    done = dse_runner(
        "submit", spent, "--no-dashboard", "--json"
    )  # the budget's line on stderr: JSON stays strict
    assert done.returncode == 0 and strict_loads(done.stdout)["tasks"] == 16
    assert "warning: search: morris runs 16 distinct points of max_points 60" in done.stderr

    text = ishigami_space(
        tmp_path / "text",
        dask_scheduler,
        search={"strategy": "morris", "max_points": 40},
        parameters={"ishigami.x1": {"low": -1, "high": 1}, "ishigami.a": [7, "seven"]},
    )
    done = dse_runner("submit", text, "--no-dashboard")
    assert done.returncode == 2 and "ishigami.a" in done.stderr


@pytest.mark.parametrize(
    "option, named",
    [
        (["--folds", "1"], "--folds 1: cross-validation needs 2 folds or more"),
        (["--noise-factor", "0"], "--noise-factor 0.0: must be a positive number"),
        (["--screen", "newton"], "--screen 'newton': no such combination screen (known: linearised, mixed)"),
    ],
)
def test_diagnose_refuses_what_no_diagnosis_can_honour_in_one_line(tmp_path, option, named):
    done = dse_runner(
        "diagnose", "--space", str(REPO / "jobs" / "msd" / "space.yaml"), "--out", str(tmp_path), *option
    )
    assert done.returncode == 2
    (line,) = done.stderr.strip().splitlines()  # one line, no traceback
    assert line.startswith(f"error: {named}"), done.stderr


def test_simulate_on_a_new_record_prints_its_error_against_the_recording(tmp_path):
    """Predicting a record: a scenario whose recording has a column named like an output (y, tanks.y) is
    compared with it, in text and in --json, the error being the RMS of simulated minus recorded."""
    import numpy as np

    tanks = REPO / "jobs" / "cascaded_tanks"
    values = tmp_path / "values.yaml"
    values.write_text(
        "tanks.k1: 0.046\ntanks.k2: 0.063\ntanks.k3: 0.09\ntanks.k4: 0.055\ntanks.x1_0: 10.4\n"
        "tanks.x2_0: 5.13\nstate_max(tanks.x2): 10.0\n"
    )
    done = dse_runner(
        "simulate",
        tanks / "multimodel.yaml",
        "-s",
        tanks / "estimation",
        "--values",
        values,
        "--csv",
        tmp_path / "predicted.csv",
        "--json",
    )
    assert done.returncode == 0, done.stderr
    found = strict_loads(done.stdout)
    predicted = np.genfromtxt(tmp_path / "predicted.csv", delimiter=",", names=True)
    recorded = np.genfromtxt(tanks / "estimation" / "level.csv", delimiter=",", names=True)
    assert np.array_equal(predicted["time"], recorded["time"])  # the record's 4 s step
    by_hand = float(np.sqrt(np.mean((predicted["tanksy"] - recorded["y"]) ** 2)))
    assert found["objectives"] == {"y_rmse": pytest.approx(by_hand, rel=1e-12)}
    text = dse_runner("simulate", tanks / "multimodel.yaml", "-s", tanks / "estimation", "--values", values)
    assert f"  {'y_rmse':<20} {by_hand:10.4f}" in text.stdout.splitlines()


def test_simulate_takes_objectives_written_as_a_space_writes_them():
    """--objective takes a spec in YAML's flow form, as the error text and space.yaml write
    them (it used to answer "cannot import '{signal'"): unnamed, it is named for what it
    reads and how; a misspelt key is named."""
    tanks = REPO / "jobs" / "cascaded_tanks"
    done = dse_runner(
        "simulate",
        tanks / "multimodel.yaml",
        "-s",
        tanks / "estimation",
        "--json",
        "--objective",
        "{signal: tanks.y, recorded: y, metric: max_abs}",
        "--objective",
        "{peak: {signal: tanks.x1, reduce: max}}",
        "--objective",
        "{signal: tanks.y, reduce: min}",
    )
    assert done.returncode == 0, done.stderr
    found = strict_loads(done.stdout)["objectives"]
    assert set(found) == {"y_max_abs", "peak", "y_min"} and found["peak"] > found["y_min"] > 0
    bad = dse_runner(
        "simulate",
        tanks / "multimodel.yaml",
        "-s",
        tanks / "estimation",
        "--objective",
        "{signal: tanks.y, recorded: y, metrc: rmse}",
    )
    assert bad.returncode != 0
    assert (
        "--objective {signal: tanks.y, recorded: y, metrc: rmse}: fit.metrc: Extra inputs are not permitted"
        in bad.stderr
    )


def test_simulate_a_space_runs_its_own_model_so_values_named_as_the_space_names_them_replay(tmp_path):
    """A space whose model is inline (instance ``vdp`` of an FMU file named otherwise): its values, as a
    fit or a diagnosis writes them, replay with ``simulate SPACE.yaml`` on its experiment and
    objectives; a scenario is chosen by name; several without one is one line listing them."""
    import yaml

    vdp = REPO / "tests" / "fmus" / "vdp_me"
    spec = {
        "name": "inline",
        "multimodel": {"fmus": {"vdp": str(vdp)}, "instances": {"vdp": {"interface": "me"}}},
        "experiment": {"stop_time": 2.0, "step": 0.1},
        "scenarios": [
            {"name": "low", "parameters": {"vdp.x0": 0.5}},
            {"name": "high", "parameters": {"vdp.x0": 2.5}},
        ],
        "parameters": {"vdp.mu": {"low": 0.5, "high": 2.0}},
        "objectives": {"x_end": {"signal": "vdp.x0", "reduce": "final"}},
        "output": str(tmp_path / "out"),
    }
    space = tmp_path / "space.yaml"
    space.write_text(yaml.safe_dump(spec))
    values = tmp_path / "values.yaml"
    values.write_text("vdp.mu: 1.5\n")
    done = dse_runner("simulate", space, "--scenario", "high", "--values", values, "--json")
    assert done.returncode == 0, done.stderr
    found = strict_loads(done.stdout)
    assert found["scenario"] == "high" and found["values"]["vdp.mu"] == 1.5 and found["stop_time"] == 2.0
    direct = dse_runner(
        "simulate",
        vdp,
        "--set",
        "mu=1.5",
        "--set",
        "x0=2.5",
        "--stop-time",
        "2",
        "--step",
        "0.1",
        "--interface",
        "me",
        "--objective",
        "{x_end: {signal: x0, reduce: final}}",
        "--json",
    )
    assert strict_loads(direct.stdout)["objectives"]["x_end"] == found["objectives"]["x_end"]
    both = dse_runner("simulate", space, "--values", values)
    assert (
        both.returncode != 0
        and "the space has 2 scenarios (low, high): name one with --scenario" in both.stderr
    )


def test_simulate_a_space_at_its_best_point_replays_what_rank_writes(tmp_path, dask_scheduler):
    """``simulate SPACE --best`` runs the point rank ranks best, as ``rank --best-values``' file does, and
    scores it as the sweep did; --set overrides it; before any submit it is one line saying what to do."""
    import yaml

    vdp = REPO / "tests" / "fmus" / "vdp_me"
    spec = {
        "name": "best",
        "multimodel": {"fmus": {"vdp": str(vdp)}, "instances": {"vdp": {"interface": "me"}}},
        "experiment": {"stop_time": 2.0, "step": 0.1},
        "parameters": {"vdp.mu": [0.5, 1.0, 2.0]},
        "objectives": {"x_end": {"signal": "vdp.x0", "reduce": "final"}},
        "output": str(tmp_path / "out"),
        "cluster": {"address": dask_scheduler},
    }
    space = tmp_path / "space.yaml"
    space.write_text(yaml.safe_dump(spec))
    early = dse_runner("simulate", space, "--best")
    assert early.returncode == 2 and "--best:" in early.stderr and "submit the space first" in early.stderr
    assert dse_runner("submit", space, "--no-dashboard", "--json").returncode == 0
    ranked = strict_loads(
        dse_runner("rank", tmp_path / "out", "--best-values", tmp_path / "best.yaml", "--json").stdout
    )
    best = strict_loads(dse_runner("simulate", space, "--best", "--json").stdout)
    replay = strict_loads(dse_runner("simulate", space, "--values", tmp_path / "best.yaml", "--json").stdout)
    assert best["values"] == replay["values"] == ranked["best"]
    assert best["objectives"]["x_end"] == replay["objectives"]["x_end"] == ranked["best_total"]
    other = strict_loads(dse_runner("simulate", space, "--best", "--set", "vdp.mu=3", "--json").stdout)
    assert other["values"] == {"vdp.mu": 3}


def test_describe_lists_what_a_model_offers_by_the_names_every_command_uses(tmp_path):
    """An FMU source folder's instance is named after it; its parameters and inputs are settable, with start
    value, unit and description; the names given replay in --set; --json is strict."""
    msd = REPO / "jobs" / "msd" / "fmus" / "msd"
    done = dse_runner("describe", msd, "--json")
    assert done.returncode == 0, done.stderr
    (instance,) = strict_loads(done.stdout)["instances"]
    assert (instance["instance"], instance["interface"], instance["stop_time"]) == ("msd", "me", 10.0)
    by_name = {v["name"]: v for v in instance["variables"]}
    assert by_name["msd.k"] == {
        "name": "msd.k",
        "causality": "parameter",
        "type": "Real",
        "start": "10",
        "unit": "N/m",
        "description": "spring stiffness [N/m]",
        "settable": True,
        "fed_by": None,
    }
    assert by_name["msd.F"]["settable"] and not by_name["msd.x"]["settable"]
    text = dse_runner("describe", msd).stdout.splitlines()
    assert text[0] == "msd: msd, FMI 2.0, model exchange; default experiment start 0, stop 10"
    assert any(line.split()[:3] == ["msd.k", "parameter", "10"] for line in text)
    ran = dse_runner(
        "simulate",
        msd,
        *[f"--set={v['name']}={v['start']}" for v in by_name.values() if v["settable"]],
        "--json",
    )
    assert ran.returncode == 0, ran.stderr
    missing = dse_runner("describe", tmp_path / "nowhere.fmu")
    assert missing.returncode == 2 and "nowhere.fmu" in missing.stderr


def test_describe_names_the_output_a_connected_input_is_set_from():
    """An input a connection feeds is not offered as settable (the master sets it from its output at every
    step, whatever a value given before would say): describe names that output instead."""
    space = REPO / "jobs" / "robotti" / "space.yaml"
    done = dse_runner("describe", space, "--json")
    assert done.returncode == 0, done.stderr
    by_name = {v["name"]: v for i in strict_loads(done.stdout)["instances"] for v in i["variables"]}
    steering = by_name["vehicle.delta_f"]
    assert (steering["causality"], steering["settable"], steering["fed_by"]) == (
        "input",
        False,
        "controller.delta_f",
    )
    assert by_name["vehicle.mass"]["settable"] and by_name["vehicle.mass"]["fed_by"] is None
    (line,) = [
        line for line in dse_runner("describe", space).stdout.splitlines() if "vehicle.delta_f" in line
    ]
    assert line.split()[:4] == ["vehicle.delta_f", "input", "0", "connected"]
    assert line.endswith("(set from controller.delta_f at every step)")


def test_a_file_that_is_not_what_its_place_expects_is_one_line_naming_it(tmp_path):
    """An .fmu, a CSV, a list or a space.yaml where a values file or a space is expected: one line naming the
    file and what was expected, never a decoding error or a validation error per key."""
    fmu = tmp_path / "model.fmu"
    fmu.write_bytes(b"PK\x03\x04\x14\x00\x00\x00\x08\x00\xe3\x9c\xff" * 20)  # a zip's start, not text
    csv = tmp_path / "position.csv"
    csv.write_text("time,x\n0.0,0.1\n0.05,0.09\n")
    listed = tmp_path / "list.yaml"
    listed.write_text("- a\n- b\n")
    space = tmp_path / "space.yaml"
    space.write_text(
        f"name: s\nmultimodel: {REPO / 'jobs' / 'msd' / 'fmus' / 'msd'}\n"
        "parameters: {msd.k: [10]}\nobjectives: {x: {signal: msd.x, reduce: final}}\n"
    )
    msd = REPO / "jobs" / "msd" / "fmus" / "msd"
    for args, named in [
        (["simulate", msd, "--values", fmu], f"{fmu}: not a values file: it is not text (an FMU archive;"),
        (["simulate", msd, "--values", csv], f"{csv}: not a values file: a values file is a YAML mapping"),
        (["simulate", msd, "--values", listed], "this file holds a list"),
        (["simulate", msd, "--values", space], f"{space}: a space.yaml, not a values file"),
        (["submit", fmu], "not a space.yaml: it is not text (an FMU archive; a space.yaml is YAML)"),
        (
            ["submit", csv],
            (
                "not a space.yaml: a space.yaml is a YAML mapping of keys to values, this file holds "
                "text that is not a YAML mapping (a CSV file?)"
            ),
        ),
        (["diagnose", "--space", fmu], "not a space.yaml: it is not text"),
    ]:
        done = dse_runner(*args)
        assert done.returncode == 2, (args, done.stderr)
        (line,) = done.stderr.strip().splitlines()
        assert line.startswith("error: ") and named in line, (args, line)
    described = dse_runner("describe", space)  # a space's model, described
    assert described.returncode == 0 and described.stdout.startswith("msd: msd, FMI 2.0, model exchange")
