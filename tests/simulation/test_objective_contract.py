"""The objective contract (objectives.Objective): every registered objective is one (plain functions
wrapped, their ``vector`` mark kept), and a plug-in subclass with only ``__call__`` scores a real run."""

from __future__ import annotations

from importlib.metadata import entry_points

import numpy as np
import pytest
from conftest import REPO
from support.plugins import register

from dse_runner.errors import DseError
from dse_runner.simulation import objectives as objs
from dse_runner.simulation.run import simulate

PLUGIN = """
import numpy as np

from dse_runner.simulation.objectives import Objective


class PeakLevel(Objective):
    def __call__(self, trajectory, scenario):
        return float(np.max(trajectory.column("tank.level")))


class LevelSamples(Objective):
    vector = True

    def __call__(self, trajectory, scenario):
        return trajectory.column("tank.level")


PEAK_LEVEL = PeakLevel()
LEVEL_SAMPLES = LevelSamples()
NOT_AN_OBJECTIVE = 42
"""


def test_every_registered_objective_holds_to_the_contract():
    registered = objs.registered()
    assert set(registered) == {e.name for e in entry_points(group="dse_runner.objectives")}
    for name, objective in registered.items():
        assert isinstance(objective, objs.Objective) and callable(objective), name
    assert (
        registered["fix_residuals"].vector and not registered["cross_track_error"].vector
    )  # kept from .vector


def test_an_objective_with_only_call_scores_a_run(tmp_path, monkeypatch):
    register(
        monkeypatch,
        tmp_path / "plugin",
        "objective_plugin",
        PLUGIN,
        {
            "dse_runner.objectives": {
                "peak_level": "objective_plugin:PEAK_LEVEL",
                "level_samples": "objective_plugin:LEVEL_SAMPLES",
            }
        },
    )
    result = simulate(
        REPO / "jobs" / "watertank" / "multimodel.yaml",
        stop_time=5,
        step=0.1,
        objectives=["peak_level", "level_samples"],
    )
    level = result.trajectory.column("tank.level")
    assert result.objectives["peak_level"] == float(np.max(level))
    assert result.objectives["level_samples"] == level.tolist()
    assert not objs.is_vector("peak_level") and objs.is_vector(
        "level_samples"
    )  # the default, and the override


def test_a_registered_name_that_is_no_objective_is_named(tmp_path, monkeypatch):
    register(
        monkeypatch,
        tmp_path / "plugin",
        "bad_objective_plugin",
        PLUGIN,
        {"dse_runner.objectives": {"answer": "bad_objective_plugin:NOT_AN_OBJECTIVE"}},
    )
    with pytest.raises(
        DseError,
        match=r"objective 'answer' \(bad_objective_plugin:NOT_AN_OBJECTIVE\) is neither a "
        r"dse_runner Objective nor a function but 42",
    ):
        objs.registered()
