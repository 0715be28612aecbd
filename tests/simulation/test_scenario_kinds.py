"""The scenario-kind contract (ScenarioKind): every installed kind holds to it, and a plug-in with only
the required parts (detect, load) works, its optional views falling back to the general ones."""

from __future__ import annotations

from importlib.metadata import entry_points

import pytest
from conftest import REPO
from support.plugins import register

from dse_runner.errors import DseError
from dse_runner.interfaces.plots import result_plot
from dse_runner.simulation import scenario
from dse_runner.simulation.comparison import compare
from dse_runner.simulation.run import simulate

MINIMAL = """
from pathlib import Path

from dse_runner.simulation.scenario import Scenario, ScenarioKind


class Minimal(ScenarioKind):
    name = "minimal"

    def detect(self, folder: Path) -> bool:
        return (folder / "stop.txt").is_file()

    def load(self, folder: Path, options=None) -> Scenario:
        stop = float((folder / "stop.txt").read_text())
        return Scenario(folder.name, kind=self.name, stop_time=stop, sources=(folder / "stop.txt",))


MINIMAL = Minimal()


class Duck:  # detect and load, but not a ScenarioKind
    name = "duck"
    default_objectives = ()

    def detect(self, folder):
        return False

    def load(self, folder, options=None):
        raise AssertionError("never loaded")


DUCK = Duck()
"""


def test_every_installed_kind_holds_to_the_contract():
    installed = scenario.kinds()
    assert {"signals", *(e.name for e in entry_points(group="dse_runner.scenarios"))} == set(installed)
    for name, found in installed.items():
        assert isinstance(found, scenario.ScenarioKind), name
        assert found.name == name  # scenarios carry it as their kind, and the views look the kind up by it
        assert all(isinstance(o, str) for o in found.default_objectives)


def test_a_kind_with_only_detect_and_load_gets_the_general_views(tmp_path, monkeypatch):
    register(
        monkeypatch,
        tmp_path / "plugin",
        "minimal_kind_plugin",
        MINIMAL,
        {"dse_runner.scenarios": {"minimal": "minimal_kind_plugin:MINIMAL"}},
    )
    folder = tmp_path / "run1"
    folder.mkdir()
    (folder / "stop.txt").write_text("4.0")
    loaded = scenario.load_scenario(folder)  # found by detect, among every installed kind
    assert (loaded.kind, loaded.stop_time) == ("minimal", 4.0)

    result = simulate(REPO / "jobs" / "watertank" / "multimodel.yaml", loaded, step=0.1)
    assert result.time[-1] == pytest.approx(4.0)
    kind = scenario.kind("minimal")
    assert kind.draw(result, None) is False and kind.compare(result) is None  # the defaults
    shown = compare(result)  # the general comparison: the first recorded signal over time
    assert (shown.x_label, shown.y_label, shown.recorded) == ("time [s]", result.trajectory.names[0], None)
    figure = result_plot(result, tmp_path / "run1.png")  # signals against time
    assert figure.stat().st_size > 0


def test_a_kind_that_is_not_a_scenario_kind_is_named(tmp_path, monkeypatch):
    register(
        monkeypatch,
        tmp_path / "plugin",
        "duck_kind_plugin",
        MINIMAL,
        {"dse_runner.scenarios": {"duck": "duck_kind_plugin:DUCK"}},
    )
    with pytest.raises(
        DseError,
        match=r"^scenario kind 'duck' \(duck_kind_plugin:DUCK\) is not an instance of "
        r"dse_runner\.simulation\.scenario\.ScenarioKind",
    ):
        scenario.kind("duck")
