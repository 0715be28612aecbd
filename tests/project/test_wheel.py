"""The package as users install it: a wheel in a fresh virtual environment, used from an empty
folder outside the checkout. Everything it finds at run time (FMU sources, the Robotti
multi-model and calibration space) must ship inside the wheel."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest
import yaml
from conftest import MULTIMODEL, REPO, SCENARIOS, strict_loads

from dse_runner.simulation.run import simulate

pytestmark = pytest.mark.slow  # builds the wheel and installs it into a fresh virtual environment

RUNS = ["speed_step1", "speed_step3", "turn_ramp1"]  # three of the bundled runs


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> dict:
    """Build the wheel from a copy of what the package is made of, install it into a new venv."""
    root = tmp_path_factory.mktemp("wheel")
    source = root / "source"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, source / name)
    for folder in ("dse_runner", "fmus"):  # the package, and the FMU sources pyproject.toml maps into it
        shutil.copytree(REPO / folder, source / folder, ignore=shutil.ignore_patterns("__pycache__"))
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "-w",
            str(root / "dist"),
            str(source),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    (wheel,) = (root / "dist").glob("dse_runner-*.whl")
    # The dependencies come from this interpreter's site-packages (named in a .pth file, whose own .pth
    # files, this checkout's editable install among them, are then not read); dse-runner itself only
    # from the wheel. (--system-site-packages would give the base interpreter's, not those of the
    # environment the tests run in.)
    venv = root / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    target = subprocess.run(
        [venv / "bin" / "python", "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    ours = dict.fromkeys([sysconfig.get_path("purelib"), sysconfig.get_path("platlib")])
    (Path(target) / "dependencies.pth").write_text("".join(f"{path}\n" for path in ours))
    subprocess.run(
        [
            venv / "bin" / "python",
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--ignore-installed",
            str(wheel),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    work = root / "empty"  # the user's folder: nothing of the checkout in it
    work.mkdir()
    env = {
        **os.environ,
        "DSE_RUNNER_CACHE": str(root / "cache"),
        "PATH": f"{venv / 'bin'}:{os.environ['PATH']}",
    }
    env.pop("PYTHONPATH", None)
    return {"venv": venv, "work": work, "env": env, "wheel": wheel}


def command(installed: dict, *args, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(installed["venv"] / "bin" / "dse-runner"), *map(str, args)],
        check=False,
        cwd=installed["work"],
        env=installed["env"],
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def test_the_wheel_carries_the_fmu_sources_and_examples(installed):
    located = subprocess.run(
        [installed["venv"] / "bin" / "python", "-c", "import dse_runner.bundled as b; print(b.root())"],
        cwd=installed["work"],
        env=installed["env"],
        capture_output=True,
        text=True,
        check=True,
    )
    root = Path(located.stdout.strip())
    assert root.is_relative_to(installed["venv"]) and not root.is_relative_to(REPO)
    for name in (
        "fmus/common/slave.c",
        "fmus/robotti_vehicle_effects/model.c",
        "robotti/multimodel.yaml",
        "robotti/calibration.yaml",
    ):
        assert (root / name).is_file(), name


def test_simulate_a_multimodel_of_its_own_fmus(installed):
    built = command(installed, "build-fmus", "--out", "fmus", "--json")
    assert built.returncode == 0, built.stderr
    fmus = strict_loads(built.stdout)["fmus"]
    assert set(fmus) == {"path_controller", "replay_controller", "robotti_vehicle", "robotti_vehicle_effects"}
    shutil.copytree(SCENARIOS / "sin1", installed["work"] / "sin1")
    model = yaml.safe_load(MULTIMODEL.read_text())
    model["fmus"] = {"controller": "fmus/replay_controller.fmu", "vehicle": "fmus/robotti_vehicle.fmu"}
    (installed["work"] / "mm.yaml").write_text(yaml.safe_dump(model))
    done = command(
        installed,
        "simulate",
        "mm.yaml",
        "--scenario",
        "sin1",
        "--set",
        "vehicle.mass=1500",
        "--json",
        "--out",
        "out/sin1",
    )
    assert done.returncode == 0, done.stderr
    printed = strict_loads(done.stdout)
    here = simulate(MULTIMODEL, SCENARIOS / "sin1", {"vehicle.mass": 1500})
    # the field-data objectives come from the wheel's own entry points (the kind is a plug-in)
    assert set(printed["objectives"]) == {"cross_track_error", "max_error", "rms_error", "final_error"}
    assert printed["objectives"] == pytest.approx(here.objectives, rel=1e-12)
    assert (installed["work"] / "out" / "sin1" / "trajectory.csv").is_file()
    assert (installed["work"] / printed["trajectory"]).samefile(
        installed["work"] / "out" / "sin1" / "trajectory.csv"
    )


def test_diagnose_three_bundled_runs_with_a_small_grid(installed):
    runs = installed["work"] / "runs"
    for name in RUNS:
        shutil.copytree(SCENARIOS / name, runs / name)
    (installed["work"] / "grid.yaml").write_text(
        yaml.safe_dump(
            {
                "name": "small-grid",
                "multimodel": "bundled:robotti/multimodel.yaml",
                "parameters": {"vehicle.cAlphaF": [20000, 38000], "vehicle.mass": [1000, 3000]},
                "objectives": ["cross_track_error"],
                "cluster": {"n_workers": 2},
            }
        )
    )
    # Two hypotheses keep it short; which ones win is test_diagnose's business, not this test's.
    done = command(
        installed,
        "diagnose",
        "--scenarios",
        "runs",
        "--space",
        "grid.yaml",
        "--out",
        "diagnosis",
        "--hypothesis",
        "wheel_slip",
        "--hypothesis",
        "steering_lag",
        "--json",
    )
    assert done.returncode == 0, done.stderr
    result = strict_loads(done.stdout)
    tried = {c["id"] for c in result["candidates"]}
    assert {"none", "wheel_slip", "steering_lag"} <= tried
    assert all(set(label.split("+")) <= {"wheel_slip", "steering_lag"} for label in tried - {"none"})
    assert result["effects"] and result["held_out_after"] <= result["held_out_before"]
    written = installed["work"] / "diagnosis"
    assert (written / "report" / "report.md").is_file()
    if result["effects"][0]["id"] != "none":  # the model it writes names the bundled effects vehicle
        model = yaml.safe_load((written / "augmented-multimodel.yaml").read_text())
        assert model["fmus"]["vehicle"] == "bundled:fmus/robotti_vehicle_effects"
    default = command(installed, "diagnose", "--scenarios", "nowhere")  # the bundled default space is found
    assert default.returncode == 2 and "--scenarios nowhere: not a folder" in default.stderr
