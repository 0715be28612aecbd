"""Objectives on hand-made tracks whose answers are known."""

from __future__ import annotations

import sys
import textwrap

import numpy as np
import pytest

from dse_runner import DseError
from dse_runner.cases import fielddata
from dse_runner.simulation import objectives as objs
from dse_runner.simulation.scenario import load_scenario
from dse_runner.simulation.trajectory import Trajectory


@pytest.fixture
def recorded(tmp_path):
    """A scenario whose GPS fixes lie on the line y = 0 at x = t, with a dropout at t = 2."""
    folder = tmp_path / "line"
    folder.mkdir()
    (folder / "scenario.yaml").write_text(
        "name: line\ngroup: test\nduration: 4.0\ninitial_pose: {x: 0, y: 0, theta: 0}\n"
    )
    (folder / "steering_inputs.csv").write_text("time,velocity,delta_f\n0,1,0\n0.5,1,0\n")
    (folder / "gps_position.csv").write_text("time,x,y\n0,0,0\n1,1,0\n3,3,0\n4,4,0\n")
    return load_scenario(folder)


def track(time, x, y):
    values = np.column_stack([x, y])
    return Trajectory(np.asarray(time, float), ("v.x", "v.y"), values)


def test_the_position_is_the_only_instance_with_x_and_y(recorded):
    assert recorded.kind == "field_data"
    assert fielddata.position_of(track([0.0, 4.0], [0.0, 4.0], [0.0, 0.0]).names, recorded) == ("v.x", "v.y")


def test_constant_offset(recorded):
    t = np.linspace(0, 4, 9)
    traj = track(t, t + 3.0, np.full_like(t, 4.0))  # 5 m from every fix
    scores = objs.evaluate(objs.normalise(list(fielddata.FieldData.default_objectives)), traj, recorded)
    assert scores == pytest.approx(
        {"cross_track_error": 5.0, "max_error": 5.0, "rms_error": 5.0, "final_error": 5.0}
    )


def test_distances_interpolate_between_communication_points(recorded):
    # Simulated positions only at t = 0 and 4; the fix at t = 1 is compared with (1, 1).
    traj = track([0.0, 4.0], [0.0, 4.0], [0.0, 4.0])
    distances = fielddata.fix_distances(traj, recorded)
    assert distances == pytest.approx([0.0, 1.0, 3.0, 4.0])
    assert fielddata.cross_track_error(traj, recorded) == pytest.approx(2.0)  # Equation 1: the mean
    assert fielddata.rms_error(traj, recorded) == pytest.approx(np.sqrt((0 + 1 + 9 + 16) / 4))
    assert fielddata.max_error(traj, recorded) == pytest.approx(4.0)
    assert fielddata.final_error(traj, recorded) == pytest.approx(4.0)


def test_fixes_after_the_simulation_are_not_counted(recorded):
    traj = track([0.0, 1.0], [0.0, 1.0], [0.0, 0.0])
    assert len(fielddata.fix_distances(traj, recorded)) == 2


def test_user_objective_by_import_path(tmp_path, monkeypatch, recorded):
    (tmp_path / "my_objectives.py").write_text(
        textwrap.dedent("""
        def final_x(trajectory, scenario):
            return trajectory.column("v.x")[-1]
    """)
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    traj = track([0.0, 4.0], [0.0, 7.5], [0.0, 0.0])
    assert objs.evaluate(objs.normalise(["my_objectives:final_x"]), traj, recorded) == {
        "my_objectives:final_x": 7.5
    }
    sys.modules.pop("my_objectives", None)


@pytest.mark.parametrize(
    "name, message",
    [
        ("cross_trak_error", "unknown objective 'cross_trak_error'"),
        ("no_such_module:f", "cannot import 'no_such_module'"),
        ("json:no_such_function", "json has no function 'no_such_function'"),
    ],
)
def test_bad_objective_names(name, message, recorded):
    with pytest.raises(DseError, match=message):
        objs.function(name)
