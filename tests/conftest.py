"""Shared fixtures: the repository's real FMUs, multi-model and recordings."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
MULTIMODEL = REPO / "jobs" / "robotti" / "multimodel.yaml"
SCENARIOS = REPO / "scenarios" / "robotti"
FMU_SOURCES = REPO / "fmus"


@pytest.fixture(scope="session", autouse=True)
def fresh_fmu_cache(tmp_path_factory):
    """Build the FMUs from source once per test session, in a cache of its own."""
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
    from dse_runner.simulate import as_plan

    return as_plan(MULTIMODEL)


@pytest.fixture
def scenario_copy(tmp_path):
    """A writable copy of a recorded scenario, for tests that damage it."""

    def copy(name: str = "sin1") -> Path:
        target = tmp_path / name
        shutil.copytree(SCENARIOS / name, target)
        return target

    return copy


def all_scenarios() -> list[str]:
    return sorted(p.name for p in SCENARIOS.iterdir() if p.is_dir())
