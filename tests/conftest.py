"""Shared fixtures: the repository's real FMUs, multi-model and recordings."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from dse_runner import bundled

REPO = Path(__file__).resolve().parents[1]
MULTIMODEL = bundled.root() / "robotti" / "multimodel.yaml"
SCENARIOS = REPO / "scenarios" / "robotti"
FMU_SOURCES = bundled.fmus_root()


# Every test that needs a real Dask cluster is slow (docs/testing.md): these fixtures start one, and a
# test's fixturenames hold every fixture it needs, also through other fixtures (a module's sweep on the
# cluster). Other slow tests (the browser, diagnosis cases, the wheel, a cluster that submit starts)
# carry @pytest.mark.slow themselves, or their module does (pytestmark).
CLUSTER_FIXTURES = frozenset({"dask_scheduler", "cli_cluster"})


def pytest_collection_modifyitems(config, items):
    for item in items:
        if CLUSTER_FIXTURES.intersection(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session", autouse=True)
def fresh_fmu_cache(tmp_path_factory):
    """Build the FMUs from source once per test session, in a cache of its own, which pytest-xdist's workers
    share (a build is written under a temporary name and renamed, so workers building at once are safe)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        cache = tmp_path_factory.getbasetemp().parent / "fmu-cache"
        cache.mkdir(exist_ok=True)
    else:
        cache = tmp_path_factory.mktemp("fmu-cache")
    old = os.environ.get("DSE_RUNNER_CACHE")
    os.environ["DSE_RUNNER_CACHE"] = str(cache)
    yield cache
    if old is None:
        os.environ.pop("DSE_RUNNER_CACHE", None)
    else:
        os.environ["DSE_RUNNER_CACHE"] = old


@pytest.fixture(scope="session")
def plan():
    from dse_runner.simulation.run import as_plan

    return as_plan(MULTIMODEL)


@pytest.fixture
def scenario_copy(tmp_path):
    """A writable copy of a recorded scenario, for tests that damage it."""

    def copy(name: str = "sin1") -> Path:
        target = tmp_path / name
        shutil.copytree(SCENARIOS / name, target)
        return target

    return copy


SLEEPER = REPO / "tests" / "fmus" / "sleeper"  # a test FMU that sleeps `pause` s of wall time in every step


def sleeper_multimodel(folder: Path, sleeper: Path | str = SLEEPER) -> Path:
    """The bundled replay controller driving a sleeper FMU (a .fmu or a source folder); field data compare
    the sleeper's x, y (the only instance with both outputs: auto-detected)."""
    import yaml

    path = folder / "sleeper.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "fmus": {"controller": "bundled:fmus/replay_controller", "sleeper": str(sleeper)},
                "connections": {"controller.velocity": ["sleeper.velocity"]},
                "scenario": {"controller.file": "steering_inputs"},
            }
        )
    )
    return path


def strict_loads(text: str):
    """json.loads that refuses NaN and Infinity, which are not JSON: what every --json output must pass."""
    import json

    def refuse(constant: str):
        raise ValueError(f"not strict JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


def dse_runner(*args, cwd=REPO):
    """The dse-runner command as a user runs it: a real subprocess, its output captured as text."""
    import subprocess
    import sys

    return subprocess.run(
        [sys.executable, "-m", "dse_runner", *map(str, args)],
        check=False,
        capture_output=True,
        text=True,
        cwd=cwd,
    )


def all_scenarios() -> list[str]:
    return sorted(p.name for p in SCENARIOS.iterdir() if p.is_dir())


@pytest.fixture(scope="session")
def dask_scheduler(tmp_path_factory, fresh_fmu_cache):
    """A real cluster: `dask scheduler` and two single-threaded `dask worker` processes on loopback."""
    from support.cluster import CliCluster

    cluster = CliCluster(tmp_path_factory.mktemp("dask"), workers=2)
    yield cluster.address
    cluster.close()


def write_space(folder: Path, **changes) -> Path:
    """A small space.yaml beside the repository's multi-model, with ``changes`` applied."""
    import yaml

    spec = {
        "name": "small",
        "multimodel": str(MULTIMODEL),
        "scenarios": [str(SCENARIOS / "sin1"), str(SCENARIOS / "speed_step2")],
        "parameters": {
            "vehicle.cAlphaF": [20000, 38000],
            "vehicle.mass": {"start": 1000, "stop": 3000, "num": 3},
        },
        "output": str(folder / "out"),
        "keep_trajectories": 1,
        "chunk_seconds": 0.1,
    }
    spec.update(changes)
    path = folder / "space.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


MSD = REPO / "jobs" / "msd"


def write_msd_search(folder: Path, search: dict, **changes) -> Path:
    """The mass-spring-damper calibration (jobs/msd) over continuous k and c, as a search;
    ``changes`` replace top-level keys (e.g. cluster, objectives, ranking)."""
    spec = {
        "name": "msd-search",
        "multimodel": str(MSD / "multimodel.yaml"),
        "experiment": {"step": 0.05},
        "scenarios": [
            {"name": "ringdown", "recorded": str(MSD / "recording" / "position.csv"), "stop_time": 10}
        ],
        "parameters": {"msd.k": {"low": 5, "high": 25}, "msd.c": {"low": 0.2, "high": 2.0}},
        "objectives": {
            "position_rmse": {"signal": "msd.x", "recorded": "x", "metric": "rmse"},
            "position_residuals": {"signal": "msd.x", "recorded": "x", "metric": "residuals"},
        },
        "search": search,
        "output": str(folder / "out"),
        "keep_trajectories": 0,
    }
    return write_yaml(folder, {**spec, **changes})


def write_yaml(folder: Path, spec: dict) -> Path:
    """``spec`` as ``folder``/space.yaml."""
    import yaml

    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "space.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path
