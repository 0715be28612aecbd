"""Other tools' FMUs give the right answer: 20-sim tanks and mass-spring-dampers, Overture's VDM controllers
and a hand-written C controller, as INTO-CPS's example projects published them (../shared/fmus-wild).

Each is checked alone against FMPy (every output, 1e-9), with its parameters changed, ten times with varying
values in one process against fresh processes, in the published multi-models against INTO-CPS's own outputs,
and through a whole DSE config against fresh runs of every point.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import strict_loads
from support import wild
from support.wild import ALONE, WILD

from dse_runner.simulation.run import simulate

pytestmark = [
    pytest.mark.skipif(not WILD.is_dir(), reason=f"{WILD} (shared/fmus-wild) is not beside the checkout"),
    pytest.mark.slow,
]  # other tools' FMUs, each also run in fresh processes: 1-3 s a test

FMUS = sorted(ALONE)
TOLERANCE = 1e-9


def assert_same_outputs(
    got: dict[str, np.ndarray], want: dict[str, np.ndarray], tolerance: float = TOLERANCE
):
    assert set(got) == set(want), (sorted(got), sorted(want))
    for name, values in want.items():
        np.testing.assert_allclose(got[name], values, rtol=tolerance, atol=tolerance, err_msg=name)


@pytest.mark.parametrize("fmu", FMUS)
def test_alone_every_output_agrees_with_fmpy(fmu, tmp_path):
    path = WILD / fmu
    stop, step = ALONE[fmu]
    reference = wild.fresh(wild.fmpy_outputs, str(wild.fmpy_ready(path, tmp_path)), stop, step, {})
    assert_same_outputs(wild.ours(str(path), stop, step, {}), reference)
    assert reference["time"][-1] == pytest.approx(stop)  # past any DefaultExperiment's stop time


@pytest.mark.parametrize("fmu", [f for f in FMUS if WILD.is_dir() and wild.changed_parameters(WILD / f)])
def test_changed_parameters_reach_the_fmu_as_in_fmpy(fmu, tmp_path):
    """With its inputs driven, so that a controller acts and a model moves."""
    path = WILD / fmu
    stop, step = ALONE[fmu]
    changed = wild.changed_parameters(path, 1.1)  # a quarter diverges the three-tank model, in FMPy too
    copy = str(wild.fmpy_ready(path, tmp_path))
    reference = wild.fresh(wild.fmpy_outputs, copy, stop, step, changed, True)
    defaults = wild.fresh(wild.fmpy_outputs, copy, stop, step, {}, True)
    assert_same_outputs(wild.ours(str(path), stop, step, changed, True), reference)
    assert any(not np.array_equal(reference[n], defaults[n]) for n in reference if n != "time"), (
        "the changed parameters change no output: this test would not see them lost"
    )


@pytest.mark.parametrize("fmu", FMUS)
def test_ten_runs_in_one_process_are_bit_identical_to_fresh_processes(fmu):
    path = WILD / fmu
    stop, step = ALONE[fmu]
    runs = [
        {name: value for name, value in wild.changed_parameters(path, 1.0 + k / 100).items()}
        for k in range(10)
    ]
    fresh = wild.fresh_all(wild.ours_here, [(str(path), stop, step, values, True) for values in runs])
    for k, values in enumerate(runs):
        here = wild.ours(str(path), stop, step, values, True)
        for name in fresh[k]:
            assert np.array_equal(here[name], fresh[k][name], equal_nan=True), (k, name)


@pytest.mark.parametrize("fmu", FMUS)
def test_describe_lists_every_parameter_and_output_of_the_fmu_by_the_name_simulate_takes(fmu):
    """describe's names are those --set takes (the instance named after the file), and it lists exactly the
    parameters, inputs and outputs FMPy reads from the FMU's model description."""
    from fmpy import read_model_description

    path = WILD / fmu
    done = subprocess.run(
        [sys.executable, "-m", "dse_runner", "describe", str(path), "--json"],
        check=False,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    (instance,) = strict_loads(done.stdout)["instances"]
    listed = {v["name"]: v for v in instance["variables"]}
    prefix = f"{instance['instance']}."
    assert instance["instance"] == re.sub(r"[^A-Za-z0-9_]", "_", path.stem)
    wanted = {
        prefix + v.name: v
        for v in read_model_description(str(path)).modelVariables
        if v.causality in ("parameter", "calculatedParameter", "input", "output")
    }
    assert set(listed) == set(wanted)
    assert all(
        listed[n]["causality"] == v.causality
        and listed[n]["start"] == (None if v.start is None else str(v.start))
        for n, v in wanted.items()
    )


def test_an_fmu_that_declares_one_instance_per_process_runs_in_a_fresh_process():
    fmu = "three_tank_watertank/FMUs/threewatertank1.fmu"
    result = simulate(WILD / fmu, stop_time=5, step=0.05)
    (verdict,) = result.lifecycle.values()
    assert result.fresh_process and "canBeInstantiatedOnlyOncePerProcess" in verdict.reason


def test_simulate_json_says_how_each_instance_lived():
    done = cli(
        "simulate", WILD / "three_tank_watertank/FMUs/threewatertank2.fmu", "--stop-time", "25", "--json"
    )
    assert done.returncode == 0, done.stderr
    lifecycle = strict_loads(done.stdout)["lifecycle"]
    assert lifecycle["threewatertank2"]["mode"] == "process"
    assert strict_loads(done.stdout)["stop_time"] == 25  # past its DefaultExperiment's 20 s


def test_an_fmu_without_a_binary_for_this_platform_is_refused_in_one_line():
    done = cli("simulate", WILD / "single_watertank/FMUs/watertankController-SourceCode.fmu")
    assert done.returncode != 0
    assert done.stderr.strip().count("\n") == 0 and "binar" in done.stderr, done.stderr


# ---- parameters through every door ------------------------------------------------------------------

TANK = WILD / "single_watertank/FMUs/singlewatertank-20sim.fmu"


def tank_parameter() -> tuple[str, float]:
    """A Real parameter of the 20-sim tank and a changed value for it."""
    name, value = next(iter(wild.changed_parameters(TANK, 1.5).items()))
    return name, value


@pytest.mark.parametrize("door", ["set", "values", "multimodel"])
def test_a_parameter_reaches_a_20sim_fmu_by_every_door(door, tmp_path):
    name, value = tank_parameter()
    reference = wild.fresh(wild.fmpy_outputs, str(wild.fmpy_ready(TANK, tmp_path)), 20.0, 0.1, {name: value})
    model, extra = TANK, []
    if door == "set":
        extra = ["--set", f"{name}={value!r}"]
    elif door == "values":
        (tmp_path / "values.yaml").write_text(f"tank.{name}: {value!r}\n")
        model = tmp_path / "mm.yaml"
        model.write_text(f"fmus: {{tank: {TANK}}}\n")
        extra = ["--values", tmp_path / "values.yaml"]
    else:
        model = tmp_path / "mm.yaml"
        model.write_text(f"fmus: {{tank: {TANK}}}\nparameters: {{tank.{name}: {value!r}}}\n")
    done = cli("simulate", model, "--stop-time", "20", "--step", "0.1", "--csv", tmp_path / "out.csv", *extra)
    assert done.returncode == 0, done.stderr
    got = pd.read_csv(tmp_path / "out.csv")
    for column in reference:
        if column != "time":
            ours = got[column] if column in got else got[f"tank.{column}"]
            np.testing.assert_allclose(
                ours, reference[column], rtol=TOLERANCE, atol=TOLERANCE, err_msg=column
            )


def test_set_stop_time_false_leaves_the_fmu_its_own_stop_time(tmp_path):
    """FMPy's set_stop_time=False: the 20-sim tank then ends at its
    DefaultExperiment's stop time, and says so."""
    model = tmp_path / "mm.yaml"
    model.write_text(f"fmus: {{tank: {TANK}}}\ninstances: {{tank: {{set_stop_time: false}}}}\n")
    done = cli("simulate", model, "--stop-time", "20", "--step", "0.1")
    assert done.returncode != 0 and "16" in done.stderr, done.stderr
    assert cli("simulate", model, "--stop-time", "10", "--step", "0.1").returncode == 0


# ---- the published multi-models ---------------------------------------------------------------------

PUBLISHED = {
    "single_watertank/Multi-models/2018may7/fixed/coe.json": "single_watertank-2018may7-fixed.outputs.csv",
    "three_tank_watertank/Multi-models/Non-3D/Experiment1/Non-3D.coe.json": (
        "three_tank_watertank-Non-3D-Experiment1.outputs.csv"
    ),
}


@pytest.mark.parametrize("coe", sorted(PUBLISHED))
def test_published_multimodels_agree_with_intocps_to_one_internal_step(coe):
    """INTO-CPS's engine passes time as a running sum of steps: a 20-sim model's output may lag or lead by
    one of its internal steps. Every value must be within what the published signal moves in one such step
    (its steepest slope beside that point, times the step); Booleans must agree exactly."""
    from dse_runner.interfaces.intocps.formats import CoeConfig, read
    from dse_runner.interfaces.intocps.project import multimodel_of, project_root

    config_path = WILD / coe
    config = read(config_path, CoeConfig)
    multimodel = multimodel_of(config_path, project_root(config_path))
    published = pd.read_csv(WILD / "published-outputs" / PUBLISHED[coe])
    result = simulate(
        multimodel, start_time=config.startTime, stop_time=config.endTime, step=config.algorithm.size
    )
    internal = max(float(wild.default_step(p)) for p in result_fmus(multimodel))
    times = published["time"].to_numpy()
    assert np.allclose(result.time[: len(times)], times, atol=1e-9)  # the same communication points
    for column in published.columns[2:]:
        ours = result.outputs[column.partition("}.")[2]][: len(times)]
        theirs = published[column]
        if theirs.dtype == bool or theirs.dtype == object:
            assert np.array_equal(ours, theirs.astype(str).str.lower().eq("true").astype(float)), column
            continue
        theirs = theirs.to_numpy(dtype=float)
        slope = np.abs(np.diff(theirs)) / np.diff(times)
        steepest = np.maximum(np.r_[slope[0], slope], np.r_[slope, slope[-1]])
        outside = np.abs(ours - theirs) > steepest * internal * (1 + 1e-6) + 1e-9
        assert not outside.any(), (column, times[outside][:5], ours[outside][:5], theirs[outside][:5])


def result_fmus(multimodel: Path) -> list[Path]:
    from dse_runner.simulation.run import as_plan

    return list(as_plan(multimodel).fmu_paths.values())


# ---- a whole DSE -----------------------------------------------------------------------------------

DSES = {  # INTO-CPS's example DSEs as published: (dse.json, its level and valve signals)
    "three_tank_watertank": ("DSEs/ttwt-levels/ttwt-levels.dse.json", "tank2.level", "controller.wt3_valve"),
    "single_watertank": ("DSEs/swt-levels/swt-levels.dse.json", "wt.level", "cont.valve"),
}


@pytest.mark.parametrize("name", sorted(DSES))
def test_a_published_dse_runs_unchanged_and_its_scripts_get_intocps_numbers(name, tmp_path):
    """As INTO-CPS published them: the Python 2 scripts ported for the run (the files unchanged), called with
    the arguments they read (their first parameter at sys.argv[3]), on results.csv whose step-size column is
    INTO-CPS's. Each point's objectives equal a fresh run's, and what the scripts compute from that run's
    trajectory read as INTO-CPS writes it. The single watertank's picker sets aside the configs whose FMUs the
    project lacks; the one left drives Overture's older controller, which refuses a step that is not exactly
    its period: it runs at 0.1 s."""
    project = WILD / name
    scripts = {p: p.read_bytes() for p in (project / "userMetricScripts").glob("*.py")}
    dse_file, level, valve = DSES[name]
    dse = project / dse_file
    three_tanks = name == "three_tank_watertank"
    coe = project / "Multi-models/Non-3D/Experiment1/Non-3D.coe.json" if three_tanks else None
    chosen = ["--coe", coe] if coe else []  # the single watertank's is picked
    done = cli("submit", dse, *chosen, "--out", tmp_path / "out", "--json", "--no-dashboard", timeout=900)
    assert done.returncode == 0, done.stderr
    for script in scripts:
        assert f"{script} line " in done.stderr
    assert done.stderr.count("ported to Python 3 with fissix for this run") == len(scripts)
    assert {p: p.read_bytes() for p in scripts} == scripts  # the user's files are never changed
    if coe is None:
        assert (
            "set aside, their FMUs absent from the project: Multi-models/mm-OM/cosim/cosim.coe.json"
            in done.stderr
        )
    assert not re.search(r"\b[0-9a-f]{16}\.fmu", done.stderr)  # workers name the user's FMU, not a hash
    if coe is None:  # and in one line, as the command's own warnings
        assert "\nwarning: singlewatertank-20sim.fmu: no binaries/linux64/SingleWatertank.so" in done.stderr
    summary = strict_loads(done.stdout)
    from dse_runner.sweeps import store

    rows = store.read_results(tmp_path / "out", summary["sweep"])
    parameters = sorted(c for c in rows.columns if c.startswith(("controller.", "cont.")))
    assert len(rows) == 45 and (rows["status"] == "ok").all(), rows["error"].dropna().head()
    assert (rows["lifecycle"] == "process").all()  # every FMU here declares one instance per process
    points = [{p: float(row[p]) for p in parameters} for _, row in rows.iterrows()]
    checked = wild.fresh_all(
        wild.as_intocps_scripts_compute,
        [(str(dse), coe and str(coe), point, level, 1.0, valve) for point in points],
    )
    for (_, row), (fresh, recomputed) in zip(rows.iterrows(), checked):
        for objective in ("cumulativeDeviation", "vCount"):
            assert row[objective] == fresh[objective], (dict(zip(parameters, row[parameters])), objective)
            assert row[objective] == pytest.approx(recomputed[objective], rel=1e-12, abs=1e-12), objective
    assert rows["vCount"].nunique() > 1 and rows["cumulativeDeviation"].nunique() > 20  # not one row repeated


def cli(*args, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "dse_runner", *map(str, args)],
        check=False,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
