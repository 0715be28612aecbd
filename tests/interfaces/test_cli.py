"""The dse-runner command as a user runs it: a real subprocess."""

from __future__ import annotations

import subprocess
import sys

from conftest import MULTIMODEL, REPO, SCENARIOS, dse_runner, strict_loads


def test_simulate_json_prints_only_json_and_writes_track(tmp_path):
    done = dse_runner("simulate", MULTIMODEL, "--scenario", SCENARIOS / "sin1",
                      "--set", "vehicle.mass=1500", "--out", tmp_path, "--json")
    assert done.returncode == 0, done.stderr
    report = strict_loads(done.stdout)
    assert set(report["objectives"]) == {"cross_track_error", "max_error", "rms_error", "final_error"}
    assert report["values"]["vehicle.mass"] == 1500.0
    assert 0 < report["objectives"]["cross_track_error"] <= report["objectives"]["max_error"]
    header = (tmp_path / "trajectory.csv").read_text().splitlines()[0]
    assert header.startswith("time,") and "vehicle.x" in header
    assert (tmp_path / "plot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"  # field data: the track
    assert (report["trajectory"], report["plot"]) == (str(tmp_path / "trajectory.csv"), str(tmp_path / "plot.png"))
    assert report["scenario"] == "sin1" and report["dropouts"] == 0 and "vehicle.x" in report["final"]


def test_simulate_prints_objectives(tmp_path):
    done = dse_runner("simulate", MULTIMODEL, "-s", SCENARIOS / "speed_step2", "--out", tmp_path)
    assert done.returncode == 0, done.stderr
    assert "cross_track_error" in done.stdout and "trajectory:" in done.stdout


def test_unknown_set_variable_exits_2_naming_it(tmp_path):
    done = dse_runner("simulate", MULTIMODEL, "-s", SCENARIOS / "sin1", "--set", "vehicle.cAlpha=1",
                      "--out", tmp_path, "--json")
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
    assert set(built) == {"robotti_vehicle", "robotti_vehicle_effects", "replay_controller", "path_controller"}
    assert all((tmp_path / f"{name}.fmu").is_file() for name in built)


def test_every_commands_help_fits_80_columns_and_names_its_flags_plainly():
    """A terminal of 80 columns shows every option whole (no cut names), and a flag is shown as a flag."""
    import os

    helps = {}
    for command in ("submit", "rank", "dashboard", "report", "diagnose", "simulate", "build-fmus", "convert-intocps"):
        done = subprocess.run([sys.executable, "-m", "dse_runner", command, "--help"], capture_output=True, text=True,
                              cwd=REPO, env={**os.environ, "COLUMNS": "80"})
        assert done.returncode == 0, done.stderr
        helps[command] = done.stdout
    for command, text in helps.items():
        assert not [line for line in text.splitlines() if len(line) > 80], (command, text)
        assert "<bool>" not in text and "…" not in text, (command, text)
    assert "--dashboard-address" in helps["submit"] and "--no-dashboard" in helps["submit"]
