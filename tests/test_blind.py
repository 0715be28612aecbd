"""The blind cases themselves (tests/blind.py): every pair of library effects is a case with its own noise,
and the synthetic steering steps are what the recordings replay."""

from __future__ import annotations

from itertools import combinations

import blind
import numpy as np
import pytest

from dse_runner.analysis.diagnose.hypotheses import LIBRARY
from dse_runner.simulation.scenario import load_scenario


def test_every_pair_of_library_effects_is_a_case():
    effects = [h for h in LIBRARY if h != "none"]
    assert {frozenset(blind.CASES[p].effects) for p in blind.PAIRS} == {frozenset(c) for c in combinations(effects, 2)}
    for pair in blind.PAIRS:
        case = blind.CASES[pair]
        assert case.truth == {k: v for e in case.effects for k, v in blind.EFFECTS[e].items()}
        assert set(case.truth) == {v for e in case.effects for v in LIBRARY[e].variables}
    assert len({c.seed for c in blind.CASES.values()}) == len(blind.CASES)  # no two cases share a noise draw


def test_steer_steps_steps_the_steering_while_moving():
    info, lines = blind.synthetic_run("steer_steps", 20.0)
    t, speed, steer = np.loadtxt(lines[1:], delimiter=",").T
    assert t[-1] == pytest.approx(info["duration"])
    assert set(np.round(steer, 4)) == {0.0, 0.1, -0.1}
    jumps = t[1:][np.diff(steer) != 0]
    assert np.allclose(np.diff(jumps), 5.0) and np.all(speed[steer != 0] > 0)  # a step every 5 s, never at rest


def test_a_recorded_synthetic_run_is_a_field_data_scenario(tmp_path):
    folder = blind.record(tmp_path, "steering_lag", ["steer_steps"], 20.0, seed=0)
    scenario = load_scenario(folder / "steer_steps")
    fixes = np.loadtxt(folder / "steer_steps" / "gps_position.csv", delimiter=",", skiprows=1)
    assert scenario.name == "steer_steps" and scenario.group == "steer_steps"
    t = np.arange(2.0, 20.0, 1.0)  # chords 1.2 m long: heading errors of about 0.02 rad from the noise
    x, y = (np.interp(t, fixes[:, 0], fixes[:, k]) for k in (1, 2))
    heading = np.unwrap(np.arctan2(np.diff(y), np.diff(x)))
    assert np.ptp(heading) > 10 * blind.NOISE / 1.2  # the steps turn the vehicle, and back
