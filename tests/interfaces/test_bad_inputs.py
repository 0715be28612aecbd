"""Bad input, tried as a user would through the command: every case gives one line naming the
culprit on stderr, exit code 2 and no traceback (unless --debug). docs/bad-inputs.md lists
each case with its message; the ids below are the ones the table names.

Recordings follow one policy (docs/recordings.md): an empty or NaN GPS fix is a dropout,
skipped like a missing row and counted; any other value that is not a finite number is an
error naming the file, the line and the column.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from conftest import MULTIMODEL, REPO, SCENARIOS, SLEEPER, sleeper_multimodel, strict_loads, write_space
from typer.testing import CliRunner

from dse_runner import strict_json
from dse_runner.interfaces.cli import app
from dse_runner.simulation.build import build_fmu
from dse_runner.sweeps import store


def run(*args) -> tuple[int, str, str]:
    """The command in this process (a subprocess per case would triple the time)."""
    done = CliRunner().invoke(app, [str(a) for a in args])
    return done.exit_code, done.stdout, done.stderr


def one_line_error(code: int, err: str) -> str:
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return lines[0]


# ---- recordings -----------------------------------------------------------------------------


def edit(folder: Path, file: str, line: int, text: str) -> Path:
    path = folder / file
    lines = path.read_text().splitlines()
    lines[line - 1] = text
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(
    "file, line, text, message",
    [
        (
            "gps_position.csv",
            5,
            "0.30,abc,1.0",
            r"gps_position\.csv line 5, column x: 'abc' is not a finite number",
        ),
        (
            "gps_position.csv",
            6,
            "0.40,inf,1.0",
            r"gps_position\.csv line 6, column x: 'inf' is not a finite number",
        ),
        (
            "gps_position.csv",
            7,
            "nan,1.0,1.0",
            r"gps_position\.csv line 7, column time: 'nan' is not a finite number",
        ),
        ("gps_position.csv", 8, ",1.0,1.0", r"gps_position\.csv line 8, column time: is empty"),
        ("gps_position.csv", 9, "0.7,1.0", r"gps_position\.csv line 9: expected 3 fields"),
        (
            "gps_position.csv",
            11,
            "0.90,nan,abc",
            r"gps_position\.csv line 11, column y: 'abc' is not a finite number",
        ),
        (
            "gps_position.csv",
            12,
            "nan,nan,nan",
            r"gps_position\.csv line 12, column time: 'nan' is not a finite number",
        ),
        (
            "gps_position.csv",
            10,
            "0.1,1.0,1.0",
            r"gps_position\.csv line 10, column time: 0\.1 does not increase",
        ),
        (
            "steering_inputs.csv",
            5,
            "0.15,nan,0.0",
            r"steering_inputs\.csv line 5, column velocity: 'nan' is not a finite",
        ),
        (
            "steering_inputs.csv",
            6,
            "0.20,1.0,-inf",
            r"steering_inputs\.csv line 6, column delta_f: '-inf' is not a finite",
        ),
        ("steering_inputs.csv", 7, "0.25,,0.0", r"steering_inputs\.csv line 7, column velocity: is empty"),
        ("scenario.yaml", 3, "duration: .nan", r"scenario\.yaml: duration: Input should be a finite number"),
        (
            "scenario.yaml",
            4,
            "initial_pose: {x: 0.0, y: .inf, theta: 0}",
            r"scenario\.yaml: initial_pose\.y: Input should be a finite number",
        ),
    ],
    ids=[
        "gps-text",
        "gps-inf",
        "gps-time-nan",
        "gps-time-empty",
        "gps-fields",
        "gps-dropout-with-text",
        "gps-dropout-time-nan",
        "gps-time-order",
        "steering-nan",
        "steering-inf",
        "steering-empty",
        "yaml-duration-nan",
        "yaml-pose-inf",
    ],
)
def test_a_wrong_recorded_value_names_file_line_and_column(
    scenario_copy, tmp_path, file, line, text, message
):
    folder = scenario_copy("sin1")
    edit(folder, file, line, text)
    code, out, err = run("simulate", MULTIMODEL, "-s", folder, "--out", tmp_path / "out")
    assert out == ""
    assert re.search(message, one_line_error(code, err)), err


def test_gps_dropouts_are_skipped_like_missing_rows_and_counted(scenario_copy, tmp_path):
    """NaN and empty fixes give the same objectives as deleting those rows, and are counted."""
    dropped = scenario_copy("sin1")
    for line, text in [(5, "0.30,nan,1.0"), (9, "0.70,NaN,-nan"), (12, "1.00,1.0,"), (20, "1.80,,")]:
        edit(dropped, "gps_position.csv", line, text)
    deleted = tmp_path / "deleted"
    shutil.copytree(SCENARIOS / "sin1", deleted)
    lines = (deleted / "gps_position.csv").read_text().splitlines()
    (deleted / "gps_position.csv").write_text(
        "\n".join(t for i, t in enumerate(lines, 1) if i not in (5, 9, 12, 20))
    )

    code, out, err = run("simulate", MULTIMODEL, "-s", dropped, "--out", tmp_path / "a", "--json")
    assert code == 0, err
    with_dropouts = strict_loads(out)
    code, out, err = run("simulate", MULTIMODEL, "-s", deleted, "--out", tmp_path / "b", "--json")
    without_rows = strict_loads(out)
    assert with_dropouts["dropouts"] == 4 and without_rows["dropouts"] == 0
    assert with_dropouts["objectives"] == without_rows["objectives"]
    code, out, err = run("simulate", MULTIMODEL, "-s", dropped, "--out", tmp_path / "c")
    assert "recorded values skipped as dropouts (empty or NaN): sin1 4" in out


def test_a_recording_of_only_dropouts_is_an_error(scenario_copy, tmp_path):
    folder = scenario_copy("sin1")
    (folder / "gps_position.csv").write_text("time,x,y\n0.0,nan,nan\n0.2,,\n")
    code, _, err = run("simulate", MULTIMODEL, "-s", folder, "--out", tmp_path / "out")
    assert "gps_position.csv: no GPS fix" in one_line_error(code, err)


def test_an_objective_that_is_not_finite_fails_its_row_with_a_message(tmp_path):
    """A user's objective returning NaN: simulate refuses it, naming the objective."""
    (tmp_path / "nan_objective.py").write_text("def score(trajectory, scenario):\n    return float('nan')\n")
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "dse_runner",
            "simulate",
            str(MULTIMODEL),
            "-s",
            str(SCENARIOS / "sin1"),
            "--objective",
            "nan_objective:score",
            "--out",
            str(tmp_path / "out"),
            "--json",
        ],
        check=False,
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(tmp_path)},
    )
    assert done.stdout == ""
    assert "objective 'nan_objective:score' is not a finite number on scenario sin1" in one_line_error(
        done.returncode, done.stderr
    )


# ---- FMUs -------------------------------------------------------------------------------------


def test_an_fmu_that_is_not_a_zip(tmp_path):
    fake = tmp_path / "model.fmu"
    fake.write_text("not a zip")
    code, _, err = run("simulate", sleeper_multimodel(tmp_path, fake), "-s", SCENARIOS / "sin1")
    assert f"{fake}: not an FMU: an FMU is a zip archive" in one_line_error(code, err)


def test_an_fmu_without_a_binary_for_this_platform(tmp_path):
    built = build_fmu(SLEEPER)
    foreign = tmp_path / "foreign.fmu"
    with zipfile.ZipFile(built) as source, zipfile.ZipFile(foreign, "w") as target:
        for item in source.infolist():
            name = item.filename.replace("binaries/linux64/sleeper.so", "binaries/win64/sleeper.dll")
            target.writestr(name, source.read(item))
    code, _, err = run("simulate", sleeper_multimodel(tmp_path, foreign), "-s", SCENARIOS / "sin1")
    line = one_line_error(code, err)
    assert (
        "no binary for this platform: binaries/linux64/sleeper.so is missing (it has binaries for win64)"
        in line
    )


def test_an_fmu_whose_instantiate_returns_null(tmp_path):
    """The sleeper's sources with another GUID in modelDescription.xml: our FMI layer refuses to
    instantiate (returns NULL) and logs why."""
    sources = tmp_path / "sleeper"
    shutil.copytree(SLEEPER, sources)
    description = sources / "modelDescription.xml"
    description.write_text(description.read_text().replace("{0b7d8f3e", "{ffffffff"))
    code, _, err = run("simulate", sleeper_multimodel(tmp_path, sources), "-s", SCENARIOS / "sin1")
    line = one_line_error(code, err)
    assert re.search(
        r"^error: sleeper \(sleeper\): fmi2Instantiate failed \(sleeper-[0-9a-f]+\.fmu\): "
        r"GUID does not match this FMU's modelDescription\.xml$",
        line,
    ), line


def test_a_value_outside_its_declared_min_or_max(tmp_path):
    mm = sleeper_multimodel(tmp_path, SLEEPER)
    code, _, err = run("simulate", mm, "-s", SCENARIOS / "sin1", "--set", "sleeper.pause=20")
    assert "sleeper.pause = 20 is above its declared max 10" in one_line_error(code, err)
    space = write_space(tmp_path, multimodel=str(mm), parameters={"sleeper.pause": [0, -1]})
    code, _, err = run("submit", space, "--no-dashboard")
    assert (
        "space.yaml: parameters.sleeper.pause: sleeper.pause = -1 is below its declared min 0"
        in one_line_error(code, err)
    )


def test_a_value_for_an_input_a_connection_feeds(tmp_path):
    """The connection would overwrite it before the first step, so the value would do nothing: one line
    names the input and what feeds it, from --set, and from a space's parameters or a scenario's input
    signal (before anything runs)."""
    fed = "vehicle.delta_f is fed by the connection from controller.delta_f"
    code, _, err = run("simulate", MULTIMODEL, "-s", SCENARIOS / "sin1", "--set", "vehicle.delta_f=0.1")
    assert fed in one_line_error(code, err)
    space = write_space(tmp_path, parameters={"vehicle.delta_f": [0.1, 0.2]})
    code, _, err = run("submit", space, "--no-dashboard")
    assert f"space.yaml: parameters.vehicle.delta_f: {fed}" in one_line_error(code, err)
    assert not (tmp_path / "out").exists()  # refused before anything ran
    # a scenario's input signal there was refused already, by the same rule
    (tmp_path / "valve.csv").write_text("time,valvecontrol\n0,0.0\n10,1.0\n")
    code, _, err = run(
        "submit",
        write_space(
            tmp_path,
            multimodel=str(REPO / "jobs" / "watertank" / "multimodel.yaml"),
            scenarios=[{"name": "s", "inputs": {"tank.valvecontrol": {"csv": str(tmp_path / "valve.csv")}}}],
            parameters={"tank.inflow": [1.0]},
            objectives={"level_max": {"signal": "tank.level", "reduce": "max"}},
        ),
        "--no-dashboard",
    )
    said = "scenario s: inputs.tank.valvecontrol: tank.valvecontrol is fed by the connection from "
    said += "controller.valve"
    assert said in one_line_error(code, err)


# ---- specs and multi-models -------------------------------------------------------------------


@pytest.mark.parametrize(
    "changes, message",
    [
        (
            {"parameters": {"vehicle.mass": {"start": float("nan"), "stop": 2, "num": 2}}},
            r"space\.yaml: parameters\.vehicle\.mass\.range\.start: Input should be a finite number",
        ),
        (
            {"parameters": {"vehicle.mass": [1000, float("inf")]}},
            r"space\.yaml: parameters\.vehicle\.mass\.values\.1: inf is not a finite number",
        ),
        ({"timeout": -1}, r"space\.yaml: timeout: Input should be greater than 0"),
        ({"chunk_seconds": "fast"}, r"space\.yaml: chunk_seconds: Input should be a valid number"),
        (
            {"parameters": {"vehicle.mass": "heavy"}},
            (
                r"space\.yaml: parameters\.vehicle\.mass: expected a list of values, "
                r"a grid \{start, stop, step or num\} or an interval \{low, high\}"
            ),
        ),
        (
            {"parameters": {"vehicle.mass": ["heavy"]}},
            r"parameters\.vehicle\.mass: vehicle\.mass: 'heavy' is not a valid Real",
        ),
        # no scenarios: the one scenario "nominal", which has no kind's default objectives ...
        ({"scenarios": []}, r"space\.yaml: objectives: name at least one, e\.g\. "),
        # ... nor the fields the multi-model binds: checked when the space loads
        (
            {"scenarios": [], "objectives": {"x_final": {"signal": "vehicle.x", "reduce": "final"}}},
            (
                r"space\.yaml: the multi-model binds controller\.file to 'steering_inputs': "
                r"scenario nominal: no field 'steering_inputs' \(a signals scenario has no fields\)"
            ),
        ),
        (
            {
                "multimodel": {
                    **yaml.safe_load(MULTIMODEL.read_text()),
                    "scenario": {"controller.file": "steering"},
                }
            },
            (
                r"space\.yaml: the multi-model binds controller\.file to 'steering': "
                r"scenario sin1: no field 'steering' \(did you mean steering_inputs\?\); it has duration, "
                r"gps_position, initial_pose\.theta, initial_pose\.x, initial_pose\.y, steering_inputs"
            ),
        ),
        ({"multimodel": "nowhere.yaml"}, r"cannot read multi-model .*nowhere\.yaml"),
        ({"multimodel": "bundled:nothing.yaml"}, r"'bundled:nothing\.yaml': dse-runner bundles no such file"),
    ],
    ids=[
        "range-nan",
        "list-inf",
        "timeout-negative",
        "chunk-text",
        "values-not-list",
        "value-type",
        "no-scenarios",
        "no-scenarios-bound-field",
        "scenario-field",
        "multimodel-missing",
        "bundled-missing",
    ],
)
def test_a_bad_spec_value(tmp_path, changes, message):
    code, out, err = run("submit", write_space(tmp_path, **changes), "--no-dashboard", "--json")
    assert out == ""
    assert re.search(message, one_line_error(code, err)), err


@pytest.mark.parametrize(
    "changes, message",
    [
        (
            {"parameters": {"vehicle.mass": float("nan")}},
            r"mm\.yaml: parameters\.vehicle\.mass.*finite number",
        ),
        ({"parameters": {"vehicle.mass": -1e400}}, r"mm\.yaml: parameters\.vehicle\.mass.*finite number"),
        ({"fmus": {}}, r"mm\.yaml: fmus: Dictionary should have at least 1 item"),
        (
            {"connections": {"controller.velocity": "vehicle.velocity"}},
            r"mm\.yaml: connections\.controller\.velocity: Input should be a valid list",
        ),
        ({"step": 0}, r"mm\.yaml: step: Input should be greater than 0"),
        # a binding to a field no scenario has: checked against the scenario at simulate
        (
            {"scenario": {"controller.file": "steering"}},
            (
                r"error: the multi-model binds controller\.file to 'steering': scenario "
                r"sin1: no field 'steering' \(did you mean steering_inputs\?\); it has duration, "
                r"gps_position, initial_pose\.theta, initial_pose\.x, initial_pose\.y, steering_inputs$"
            ),
        ),
        ({"parameters": {"vehicle": 1}}, r"mm\.yaml: parameters: 'vehicle' is not of the form"),
    ],
    ids=[
        "parameter-nan",
        "parameter-inf",
        "no-fmus",
        "connection-not-list",
        "step-zero",
        "scenario-field",
        "parameter-ref",
    ],
)
def test_a_bad_multimodel_value(tmp_path, changes, message):
    data = yaml.safe_load(MULTIMODEL.read_text())
    data.update(changes)
    path = tmp_path / "mm.yaml"
    path.write_text(yaml.safe_dump(data))
    code, _, err = run("simulate", path, "-s", SCENARIOS / "sin1", "--out", tmp_path / "out")
    assert re.search(message, one_line_error(code, err)), err


def test_an_output_folder_that_is_a_file(tmp_path):
    (tmp_path / "taken").write_text("")
    code, _, err = run("simulate", MULTIMODEL, "-s", SCENARIOS / "sin1", "--out", tmp_path / "taken")
    assert f"cannot write {tmp_path / 'taken'}: File exists" in one_line_error(code, err)


def test_a_multimodel_that_is_not_yaml(tmp_path):
    path = tmp_path / "mm.yaml"
    path.write_text("fmus: [unclosed\n")
    code, _, err = run("simulate", path, "-s", SCENARIOS / "sin1")
    assert f"{path} line 2, column 1: not valid YAML: expected ',' or ']'" in one_line_error(code, err)


# ---- a recording compared with nothing, and names (issue 63) ------------------------------------


def room(folder: Path) -> Path:
    """A model whose output is ``T``: the mass-spring-damper's sources, its position renamed (the C code
    knows value references, not names), as a user's room model outputs its temperature."""
    source = folder / "room"
    shutil.copytree(REPO / "jobs" / "msd" / "fmus" / "msd", source)
    description = source / "modelDescription.xml"
    description.write_text(description.read_text().replace('name="x"', 'name="T"'))
    return source


def recorded(folder: Path, header: str, name: str = "rec") -> Path:
    """A scenario folder whose recording has ``header``'s columns, three rows of numbers."""
    folder = folder / name
    folder.mkdir()
    columns = header.count(",")
    rows = "".join(f"{t}," + ",".join(["0.05"] * columns) + "\n" for t in (0, 1, 2))
    (folder / "measured.csv").write_text(f"{header}\n{rows}")
    (folder / "scenario.yaml").write_text(f"name: {name}\nrecorded: measured.csv\nstop_time: 2\n")
    return folder


@pytest.mark.parametrize(
    "header, has",
    [("time,t", r"it has t \(did you mean T\?\)"), ("time,humidity", r"it has humidity;")],
    ids=["typo", "other-signal"],
)
def test_a_recording_that_names_no_output_is_refused_saying_what_it_has_and_looked_for(tmp_path, header, has):
    """``simulate MODEL --scenario REC`` compares every recorded column named like an output; a recording
    none of whose columns is one compared nothing and exited 0 with ``"objectives": {}`` (issue 63). Now it
    is refused, with --json too (nothing on stdout), saying what the recording has and what was looked for."""
    model, scenario = room(tmp_path), recorded(tmp_path, header)
    column = header.split(",")[1]
    for json_flag in ([], ["--json"]):
        code, out, err = run("simulate", model, "--scenario", scenario, *json_flag)
        line = one_line_error(code, err)
        assert out == ""
        assert re.search(
            r"scenario rec: no column of its recording measured\.csv names an output of the model, so "
            rf"nothing would be compared: {has}.* the outputs looked for are T, v; rename a column as the "
            r"output it records, or name the comparison: --objective "
            rf"'\{{signal: room\.T, recorded: {column}, metric: rmse\}}'",
            line,
        ), line


def test_objectives_asked_for_run_and_warn_of_a_recording_none_of_them_reads(tmp_path):
    """With objectives asked for, the run is what was asked: it runs, and a warning (stderr, and --json's
    ``warnings``) says that the recording was compared by none of them."""
    model, scenario = room(tmp_path), recorded(tmp_path, "time,humidity")
    code, out, err = run(
        "simulate", model, "--scenario", scenario, "--objective", "{signal: T, reduce: max}", "--json"
    )
    assert code == 0, err
    found = strict_loads(out)
    note = (
        "scenario rec: its recording measured.csv is compared by no objective (those that ran, T_max, read "
        "no recorded column); it has humidity, the outputs are T, v"
    )
    assert found["objectives"] == {"T_max": pytest.approx(0.1)} and found["warnings"] == [note]
    assert err.strip() == f"warning: {note}"


def test_a_recording_compares_the_columns_named_like_outputs_and_warns_of_the_others(tmp_path):
    model, scenario = room(tmp_path), recorded(tmp_path, "time,T,humidity,t_room")
    code, out, err = run("simulate", model, "--scenario", scenario, "--json")
    assert code == 0, err
    assert list(strict_loads(out)["objectives"]) == ["T_rmse"]
    assert err.strip() == (
        "warning: scenario rec: recorded humidity, t_room named no output of the model, so "
        "they were not compared (the outputs are T, v)"
    )


def test_a_fit_to_a_column_differing_in_case_suggests_it(tmp_path):
    """An objective naming the column ``T`` of a recording headed ``t``: the message says which it has, and
    suggests it (here, the case alone differs: difflib alone finds no match)."""
    model, scenario = room(tmp_path), recorded(tmp_path, "time,t")
    code, _, err = run("simulate", model, "--scenario", scenario, "--objective", "{signal: T, recorded: T}")
    assert "measured.csv: no recorded column 'T' (did you mean t?); it has t" in one_line_error(code, err)


def test_a_column_that_several_instances_output_is_refused_naming_them(tmp_path):
    """Two instances with an output ``x``: a column ``x`` cannot say which; it was dropped without a word."""
    msd = REPO / "jobs" / "msd" / "fmus" / "msd"
    path = tmp_path / "mm.yaml"
    path.write_text(yaml.safe_dump({"fmus": {"a": str(msd), "b": str(msd)}}))
    code, _, err = run("simulate", path, "--scenario", recorded(tmp_path, "time,x"))
    line = one_line_error(code, err)
    assert "it has x (output by a.x and b.x: name which); the outputs looked for are a.x, a.v, b.x, b.v" in (
        line
    )


def test_a_space_whose_objectives_read_no_recording_warns_when_simulated(tmp_path):
    """``simulate SPACE --scenario FOLDER``: the space's objectives are the ones asked for."""
    model, scenario = room(tmp_path), recorded(tmp_path, "time,T")
    space = tmp_path / "space.yaml"
    peak = {"peak": {"signal": "T", "reduce": "max"}}
    space.write_text(
        yaml.safe_dump({"name": "s", "multimodel": str(model), "parameters": {"k": [12]}, "objectives": peak})
    )
    code, _, err = run("simulate", space, "--scenario", scenario)
    assert code == 0, err
    assert err.strip().startswith(
        "warning: scenario rec: its recording measured.csv is compared by no objective"
    )


@pytest.mark.parametrize(
    "given, message",
    [
        (
            "set K=3",
            r"setting: unknown variable 'room\.K': instance 'room' \(msd\) has no variable 'K' "
            + r"\(did you mean k\?\)",
        ),
        ("set Room.k=3", r"names instance 'Room', but the multi-model has room \(did you mean room\?\)"),
        ("set t=3", r"has no variable 't' \(did you mean T\?\)"),
        ("pair k=3", r"setting: 'k' is not of the form instance\.variable \(did you mean a\.k, b\.k\?\)"),
        ("pair a.K=3", r"instance 'a' \(msd\) has no variable 'K' \(did you mean k\?\)"),
    ],
    ids=["case", "instance-case", "output-case", "no-instance", "pair-case"],
)
def test_a_name_that_differs_in_case_or_lacks_its_instance_suggests_the_right_one(tmp_path, given, message):
    """``--set``: difflib alone finds ``K`` no match for ``k``; a multi-model's bare name suggests each
    instance that has it."""
    kind, assignment = given.split()
    model = room(tmp_path)
    if kind == "pair":
        model = tmp_path / "mm.yaml"
        msd = str(REPO / "jobs" / "msd" / "fmus" / "msd")
        model.write_text(yaml.safe_dump({"fmus": {"a": msd, "b": msd}}))
    code, _, err = run("simulate", model, "--set", assignment, "--stop-time", "1", "--step", "0.1")
    assert re.search(message, one_line_error(code, err)), err


@pytest.mark.parametrize(
    "name, content, message",
    [
        (
            "measured.csv",
            "time,T\n0,1\n",
            (
                r"measured\.csv: a CSV file \(columns time,T\), not a model \(a model is an \.fmu file, an "
                r"FMU source folder, a multi-model YAML file or INTO-CPS's mm\.json\); a recording or input "
                r"signals go in a scenario \(recorded:, inputs:\), given with --scenario"
            ),
        ),
        (
            "tuned.yaml",
            "room.k: 12\nroom.c: 0.7\n",
            r"tuned\.yaml: a values file \(instance\.variable: value lines\), not a model \(.*\); give it "
            + r"with --values beside the model",
        ),
        (
            "other.yaml",
            "name: s\nmultimodel: room\nparameters: {k: [1]}\n",
            r"other\.yaml: a space\.yaml, not a model \(.*\); its model is the one its 'multimodel' names",
        ),
        (
            "rec/scenario.yaml",
            "name: rec\nrecorded: measured.csv\n",
            r"scenario\.yaml: a scenario\.yaml, not a model \(.*\); give its folder with --scenario",
        ),
        ("rec", None, r"rec: a scenario folder, not a model \(.*\); give it with --scenario"),
    ],
    ids=["csv", "values", "space-in-a-space", "scenario-file", "scenario-folder"],
)
def test_a_file_given_where_a_model_goes_is_named_for_what_it_is(tmp_path, name, content, message):
    """A CSV given as the model said "expected a mapping with 'fmus', 'connections', 'parameters'" (issue 63):
    now one line says what it is, what was expected, and where it goes; in ``simulate``, ``describe`` and a
    space's ``multimodel:`` alike."""
    room(tmp_path)
    recorded(tmp_path, "time,T")
    path = tmp_path / name
    if content is not None:
        path.write_text(content)
    for command in (["simulate", path], ["describe", path]) if name != "other.yaml" else ():  # a space runs
        code, _, err = run(*command)
        assert re.search(message, one_line_error(code, err)), err
    space = tmp_path / "space.yaml"
    peak = {"p": {"signal": "T", "reduce": "max"}}
    space.write_text(
        yaml.safe_dump({"name": "s", "multimodel": str(path), "parameters": {"k": [1]}, "objectives": peak})
    )
    code, _, err = run("submit", space, "--no-dashboard")
    assert re.search(message, one_line_error(code, err)), err


def test_a_misspelt_scenario_of_a_space_suggests_its_own():
    code, _, err = run("simulate", REPO / "jobs" / "quickstart" / "calibrate.yaml", "--scenario", "step")
    assert one_line_error(code, err).endswith(
        "(pulses, ramp, sine, steps) nor a folder (did you mean steps?)"
    )


def test_an_objective_function_with_another_signature_is_refused_before_it_runs(tmp_path, monkeypatch):
    """An objective is called as ``f(trajectory, scenario)``: one that cannot take that failed every task
    with a TypeError; now ``simulate`` (and a space, before any cluster: test_user_modules.py) says so."""
    (tmp_path / "mine.py").write_text("def peak(trajectory):\n    return 1.0\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    code, _, err = run("simulate", room(tmp_path), "--objective", "mine:peak", "--stop-time", "1")
    assert (
        "objective 'mine:peak': peak(trajectory) cannot be called as an objective is, with (trajectory, "
        "scenario): too many positional arguments"
    ) in one_line_error(code, err)


# ---- the real command: exit code, one line, --debug ---------------------------------------------


def test_the_installed_command_prints_one_line_and_the_traceback_only_with_debug(tmp_path):
    fake = tmp_path / "model.fmu"
    fake.write_text("not a zip")
    mm = sleeper_multimodel(tmp_path, fake)
    command = [sys.executable, "-m", "dse_runner"]
    quiet = subprocess.run(
        [*command, "simulate", str(mm), "-s", str(SCENARIOS / "sin1")],
        check=False,
        capture_output=True,
        text=True,
    )
    assert "not an FMU" in one_line_error(quiet.returncode, quiet.stderr)
    loud = subprocess.run(
        [*command, "--debug", "simulate", str(mm), "-s", str(SCENARIOS / "sin1")],
        check=False,
        capture_output=True,
        text=True,
    )
    assert (
        loud.returncode == 2
        and "Traceback" in loud.stderr
        and loud.stderr.strip().endswith(quiet.stderr.strip())
    )


def test_json_we_write_has_null_where_python_would_write_nan():
    """Missing numbers of every kind we hold (float, numpy, pandas, 0-d arrays) become null."""
    data = {
        "nan": float("nan"),
        "inf": -math.inf,
        "numpy": np.float32("nan"),
        "array": np.array([1.0, np.inf]),
        "scalar": np.array(2.5),
        "na": pd.NA,
        "frame": pd.Series([1.0, None]).to_list(),
        "ok": np.int64(3),
    }
    assert "NaN" in json.dumps(data, default=str)  # what Python's json would print
    assert strict_loads(strict_json.dumps(data)) == {
        "nan": None,
        "inf": None,
        "numpy": None,
        "array": [1.0, None],
        "scalar": 2.5,
        "na": None,
        "frame": [1.0, None],
        "ok": 3,
    }
    with pytest.raises(ValueError):
        strict_loads('{"a": NaN}')  # and the check every --json test uses refuses NaN


@pytest.mark.slow  # a sweep on a local cluster
def test_a_sweep_row_whose_objective_is_not_finite_fails_with_its_message(tmp_path, monkeypatch):
    """On real workers (started with the user's module on their path): the row is failed with the
    message, never ok with NaN; the other objective's rows are ok."""
    (tmp_path / "nan_objective.py").write_text(
        "def score(trajectory, scenario):\n    return float('nan') if scenario.name == 'sin1' else 1.0\n"
    )
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    monkeypatch.syspath_prepend(str(tmp_path))
    space = write_space(
        tmp_path,
        objectives=["cross_track_error", "nan_objective:score"],
        cluster={"n_workers": 1},
        parameters={"vehicle.mass": [1500]},
        keep_trajectories=0,
    )
    _, out, err = run("submit", space, "--no-dashboard", "--json")
    report = strict_loads(out)
    assert (report["ok"], report["failed"]) == (1, 1), err
    rows = store.read_results(tmp_path / "out", "small", columns=["status", "error", "nan_objective:score"])
    failed = rows[rows["scenario"] == "sin1"].iloc[0]
    assert failed["status"] == "failed" and pd.isna(failed["nan_objective:score"])
    assert "objective 'nan_objective:score' is not a finite number on scenario sin1" in failed["error"]
    assert rows[rows["scenario"] == "speed_step2"].iloc[0]["status"] == "ok"


def test_submit_counts_dropouts_and_keeps_its_json_strict(scenario_copy, tmp_path, dask_scheduler):
    folder = scenario_copy("sin1")
    for line, text in [(5, "0.30,nan,1.0"), (9, "0.70,,")]:
        edit(folder, "gps_position.csv", line, text)
    space = write_space(
        tmp_path,
        scenarios=[str(folder)],
        cluster={"address": dask_scheduler},
        parameters={"vehicle.mass": [1000, 3000]},
    )
    code, out, err = run("submit", space, "--no-dashboard", "--json")
    assert code == 0, err
    report = strict_loads(out)
    assert report["dropouts"] == {"sin1": 2} and (report["ok"], report["failed"]) == (2, 0)
    code, out, err = run("submit", space, "--no-dashboard")
    assert "recorded values skipped as dropouts (empty or NaN): sin1 2" in out
