"""Objectives declared as data: reductions of a signal, fits to a recording, checked where they load."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from dse_runner.errors import DseError
from dse_runner.simulation import objectives as objs
from dse_runner.simulation.scenario import Recording, Scenario
from dse_runner.simulation.trajectory import Trajectory

TIME = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
LEVEL = np.array([0.0, 2.0, 1.0, 3.0, 3.0])
VALVE = np.array([0.0, 1.0, 1.0, 0.0, 1.0])
TRAJECTORY = Trajectory(TIME, ("tank.level", "ctrl.valve"), np.column_stack([LEVEL, VALVE]))
PLAIN = Scenario("nominal")


def value(**spec) -> float:
    return objs.evaluate({"o": objs.Reduce(**spec)}, TRAJECTORY, PLAIN)["o"]


@pytest.mark.parametrize(
    ("reduce", "expected"),
    [
        ("final", 3.0),
        ("min", 0.0),
        ("max", 3.0),
        ("integral", 1.0 + 1.5 + 2.0 + 3.0),  # trapezoids
        ("mean", 7.5 / 4),  # the time average: integral over the span
        ("rms", np.sqrt((2.0 + 2.5 + 5.0 + 9.0) / 4)),  # trapezoids of the squared samples
    ],
)
def test_reductions_of_a_signal(reduce, expected):
    assert value(signal="tank.level", reduce=reduce) == pytest.approx(expected, rel=1e-12)


def test_a_target_reduces_the_deviation_from_it():
    assert value(signal="tank.level", reduce="max", target=1.0) == pytest.approx(2.0)
    assert value(signal="tank.level", reduce="min", target=1.0) == pytest.approx(-1.0)


def test_changes_counts_switches_of_a_boolean_recorded_as_0_1():
    assert value(signal="ctrl.valve", reduce="changes") == 3.0


def test_time_above_and_below_hold_each_value_until_the_next_point():
    assert value(signal="tank.level", reduce="time_above", threshold=1.5) == 2.0  # at t=1 and t=3
    assert value(signal="tank.level", reduce="time_below", threshold=1.5) == 2.0  # at t=0 and t=2


def test_settling_time_is_when_the_signal_last_enters_its_band():
    time = np.linspace(0.0, 10.0, 101)
    response = 1.0 - np.exp(-time) * np.cos(3 * time)  # a damped step response to 1
    trajectory = Trajectory(time, ("y",), response[:, None])
    spec = objs.Reduce(signal="y", reduce="settling_time", target=1.0, band=0.05)
    settled = objs.reduce(spec, trajectory, PLAIN)
    outside = np.flatnonzero(np.abs(response - 1.0) > 0.05)
    assert settled == pytest.approx(time[outside[-1] + 1])
    assert np.all(np.abs(response[time >= settled] - 1.0) <= 0.05)
    # Relative band: 2 % of the step from the initial value to the (default: final) target.
    relative = objs.reduce(objs.Reduce(signal="y", reduce="settling_time"), trajectory, PLAIN)
    assert np.all(np.abs(response[time >= relative] - response[-1]) <= 0.02 * abs(response[-1] - response[0]))
    never = Trajectory(time, ("y",), np.sin(time)[:, None])
    assert (
        objs.reduce(objs.Reduce(signal="y", reduce="settling_time", target=5.0, band=0.1), never, PLAIN)
        == 10.0
    )


def test_a_fit_compares_at_the_recorded_times_and_skips_missing_samples():
    recorded = Recording(
        Path("level.csv"),
        np.array([0.5, 1.5, 2.5, 3.5, 9.0]),
        {"level": np.array([1.0, np.nan, 2.0, 3.0, 100.0])},
        missing=1,
    )
    scenario = Scenario("run", recorded=recorded)
    simulated = np.interp([0.5, 2.5, 3.5], TIME, LEVEL)  # t=9 lies after the simulation: not compared
    errors = simulated - np.array([1.0, 2.0, 3.0])
    for metric, expected in [
        ("rmse", np.sqrt(np.mean(errors**2))),
        ("mae", np.mean(np.abs(errors))),
        ("max_abs", np.max(np.abs(errors))),
    ]:
        spec = objs.Fit(signal="tank.level", recorded="level", metric=metric)
        assert objs.fit(spec, TRAJECTORY, scenario) == pytest.approx(expected, rel=1e-12)


def test_a_fit_without_a_recording_or_column_names_the_scenario():
    with pytest.raises(DseError, match="scenario nominal has no recording"):
        objs.fit(objs.Fit(signal="tank.level", recorded="level"), TRAJECTORY, PLAIN)
    recorded = Recording(Path("r.csv"), TIME, {"depth": LEVEL})
    with pytest.raises(DseError, match=r"r\.csv: no recorded column 'level'; it has depth"):
        objs.fit(
            objs.Fit(signal="tank.level", recorded="level"), TRAJECTORY, Scenario("run", recorded=recorded)
        )


def test_an_unknown_signal_names_what_is_recorded():
    with pytest.raises(DseError, match=r"no recorded signal 'tank.levle' \(did you mean tank.level\?\)"):
        value(signal="tank.levle", reduce="max")


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({"signal": "a.b", "reduce": "time_above"}, "needs a 'threshold'"),
        (
            {"signal": "a.b", "reduce": "max", "threshold": 1},
            "'threshold' applies to time_above and time_below",
        ),
        ({"signal": "a.b", "reduce": "max", "band": 1}, "'band' applies to settling_time"),
        ({"signal": "a.b", "reduce": "changes", "target": 1}, "'target' does not apply to changes"),
        ({"signal": "a.b", "reduce": "median"}, "Input should be 'final', 'min'"),
    ],
)
def test_declared_objectives_are_checked_when_read(spec, message):
    with pytest.raises(ValidationError, match=message):
        objs.Reduce(**spec)


def test_a_non_finite_value_fails_naming_the_objective():
    trajectory = Trajectory(TIME, ("x",), np.array([0.0, 1.0, np.inf, 1.0, 0.0])[:, None])
    with pytest.raises(DseError, match="objective 'peak' is not a finite number on scenario nominal"):
        objs.evaluate({"peak": objs.Reduce(signal="x", reduce="max")}, trajectory, PLAIN)


def _space(tmp_path, **spec):
    import yaml
    from conftest import REPO

    from dse_runner.sweeps.spec import load_space

    base = {
        "name": "s",
        "multimodel": str(REPO / "jobs" / "msd" / "multimodel.yaml"),
        "experiment": {"step": 0.05},
        "parameters": {"msd.k": [14]},
    }
    path = tmp_path / "space.yaml"
    path.write_text(yaml.safe_dump(base | spec))
    return lambda: load_space(path)


def test_a_space_names_an_objectives_unknown_signal(tmp_path):
    load = _space(
        tmp_path,
        experiment={"stop_time": 1, "step": 0.1},
        objectives={"m": {"signal": "msd.xx", "reduce": "max"}},
    )
    with pytest.raises(
        DseError, match=r"space\.yaml: objectives\.m: unknown variable 'msd\.xx'.*did you mean x"
    ):
        load()


@pytest.mark.parametrize(
    "objectives, problems",
    [
        (
            ["max_error", {"peak": {"signal": "msd.x", "reduce": "max"}}],
            [
                (
                    "objectives.list.1: a list holds names only (an objective with options goes in a "
                    "mapping, objectives: {name: {signal: ..., reduce: ...}})"
                )
            ],
        ),
        (
            {"peak": {"signl": "msd.x", "reduce": "max"}},
            [
                "objectives.mapping.peak.reduce.signal: Field required",
                "objectives.mapping.peak.reduce.signl: Extra inputs are not permitted",
            ],
        ),
        (
            {"fit": {"signal": "msd.x", "recorded": "x", "metric": "rms"}},
            [
                "objectives.mapping.fit.fit.metric: Input should be 'rmse', 'mae', 'max_abs', 'sum_squares' "
                + "or 'residuals'"
            ],
        ),
        (
            {"peak": {"signal": "msd.x", "reduc": "max"}},
            [
                "objectives.mapping.peak.reduce.reduce: Field required",
                "objectives.mapping.peak.reduce.reduc: Extra inputs are not permitted",
            ],
        ),
        (
            {"peak": {"sgnal": "msd.x"}},
            [
                (
                    "objectives.mapping.peak: expected a name, {signal, "
                    "reduce}, {signal, recorded, metric} or {script, args}"
                )
            ],
        ),
    ],
)
def test_a_wrong_objective_entry_gets_the_messages_of_its_own_form(tmp_path, objectives, problems):
    """An entry is judged by the form its keys choose (a name, reduce, fit or script), so a typo gives its own
    message, not one per form the entry might have been."""
    with pytest.raises(DseError) as caught:
        _space(tmp_path, objectives=objectives)()
    assert str(caught.value).split(": ", 1)[1].split("; ") == problems


def test_a_space_names_a_recorded_column_its_recording_lacks(tmp_path):
    from conftest import REPO

    recording = REPO / "jobs" / "msd" / "recording" / "position.csv"
    load = _space(
        tmp_path,
        scenarios=[{"name": "r", "recorded": str(recording), "stop_time": 10}],
        objectives={"fit": {"signal": "msd.x", "recorded": "position"}},
    )
    with pytest.raises(
        DseError,
        match=r"objectives\.fit: scenario r's recording .*position\.csv has no column "
        r"'position' \(it has x\)",
    ):
        load()
    nothing = _space(
        tmp_path,
        experiment={"stop_time": 1, "step": 0.1},
        objectives={"fit": {"signal": "msd.x", "recorded": "x"}},
    )
    with pytest.raises(DseError, match="compares with recorded 'x', but scenario nominal has no recording"):
        nothing()


def test_simulate_reads_objectives_written_as_space_yaml_writes_them():
    """simulate(objectives=...) takes plain mappings, as a user copies them from
    space.yaml, and names a bad one."""
    from conftest import REPO

    from dse_runner.simulation.run import simulate

    tank = REPO / "jobs" / "watertank" / "fmus" / "tank"
    given = simulate(
        tank,
        stop_time=5,
        values={"valvecontrol": 1.0},
        objectives={"peak": {"signal": "tank.level", "reduce": "max"}},
    )
    typed = simulate(
        tank,
        stop_time=5,
        values={"valvecontrol": 1.0},
        objectives={"peak": objs.Reduce(signal="tank.level", reduce="max")},
    )
    assert given.objectives == typed.objectives
    with pytest.raises(DseError, match=r"^objectives\.peak: .*reduce: Input should be 'final'"):
        simulate(tank, stop_time=5, objectives={"peak": {"signal": "tank.level", "reduce": "maxx"}})
