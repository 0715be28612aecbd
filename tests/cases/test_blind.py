"""The blind cases themselves (tests/support/blind.py): every pair of library effects is a case with its
own noise, the synthetic runs are what the recordings replay, the cases outside the library are recorded
by the truth FMU with their effect, and the noise cases' receivers are as heavy as they say."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest
from support import blind

from dse_runner.cases.robotti_diagnosis.hypotheses import LIBRARY
from dse_runner.simulation.run import simulate
from dse_runner.simulation.scenario import load_scenario


def test_every_pair_of_library_effects_is_a_case():
    effects = [h for h in LIBRARY if h != "none"]
    assert {frozenset(blind.CASES[p].effects) for p in blind.PAIRS} == {
        frozenset(c) for c in combinations(effects, 2)
    }
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
    assert np.allclose(np.diff(jumps), 5.0) and np.all(
        speed[steer != 0] > 0
    )  # a step every 5 s, never at rest


def test_a_recorded_synthetic_run_is_a_field_data_scenario(tmp_path):
    folder = blind.record(tmp_path, "steering_lag", ["steer_steps"], 20.0, seed=0)
    scenario = load_scenario(folder / "steer_steps")
    fixes = np.loadtxt(folder / "steer_steps" / "gps_position.csv", delimiter=",", skiprows=1)
    assert scenario.name == "steer_steps" and scenario.group == "steer_steps"
    t = np.arange(2.0, 20.0, 1.0)  # chords 1.2 m long: heading errors of about 0.02 rad from the noise
    x, y = (np.interp(t, fixes[:, 0], fixes[:, k]) for k in (1, 2))
    heading = np.unwrap(np.arctan2(np.diff(y), np.diff(x)))
    assert np.ptp(heading) > 10 * blind.NOISE / 1.2  # the steps turn the vehicle, and back


def antenna(folder, name: str, case: blind.Case, values: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """A recorded run's fixes (t, x, y) and the truth's antenna simulated with ``values`` at the fix times."""
    fixes = np.loadtxt(folder / name / "gps_position.csv", delimiter=",", skiprows=1)
    traj = simulate(
        blind.truth_plan(case.vehicle), load_scenario(folder / name), values, objectives=(), step=blind.STEP
    ).trajectory
    track = np.column_stack(
        [np.interp(fixes[:, 0], traj.time, traj.column(f"vehicle.gps_{a}")) for a in "xy"]
    )
    return fixes, track


@pytest.mark.parametrize("name", list(blind.OUTSIDE))
def test_cases_outside_the_library_are_recorded_by_the_truth_with_their_effect(tmp_path, name):
    """Each records on tests/fmus/robotti_truth, the noise away from that truth with its effect on, which
    differs from it with the effect off on the run that shows the effect: its parameters reach the vehicle.
    (Not by much for relaxation: at these speeds the yaw rate follows the steering kinematically, so a
    lagging tyre force moves the antenna 5 cm at most.)"""
    case = blind.CASES[name]
    assert case.vehicle == "truth" and case.effects == () and set(case.truth) == set(blind.OUTSIDE[name][0])
    run = next((r for r in reversed(case.runs) if r in blind.SYNTHETIC), "speed_step1")
    folder = blind.record(tmp_path, name, [run], blind.SECONDS, seed=case.seed)
    files = {p.name for p in (folder / run).iterdir()}
    assert files >= {"gps_position.csv", "steering_inputs.csv", "scenario.yaml"}
    fixes, with_effect = antenna(folder, run, case, blind.truth_values(case))
    _, without = antenna(folder, run, case, blind.TRUTH_VEHICLE)
    assert np.sqrt(np.mean((fixes[:, 1:] - with_effect) ** 2)) < 1.3 * case.noise
    assert np.hypot(*(with_effect - without).T).max() > 2 * case.noise


def test_the_new_synthetic_runs_vary_what_their_effects_depend_on():
    slow, fast = (
        np.loadtxt(blind.synthetic_run(n, 20.0)[1][1:], delimiter=",") for n in ("slalom_slow", "slalom_fast")
    )
    assert np.array_equal(slow[:, 2], fast[:, 2])  # the same steering
    assert set(slow[slow[:, 0] >= 1, 1]) == {0.8} and set(fast[fast[:, 0] >= 1, 1]) == {2.0}
    info, lines = blind.synthetic_run("loop", blind.SECONDS)
    loop = np.loadtxt(lines[1:], delimiter=",")
    assert info["duration"] >= 2.0 + blind.LOOP_TURNING  # never cut short of a whole turn
    turning = loop[:, 0] >= 2.0
    assert np.all(loop[turning, 2] == blind.LOOP_STEERING) and np.all(loop[turning, 1] == blind.LOOP_SPEED)
    info_left, lines = blind.synthetic_run("loop_left", blind.SECONDS)
    left = np.loadtxt(lines[1:], delimiter=",")
    assert np.array_equal(left[:, 2], -loop[:, 2]) and np.array_equal(left[:, 1], loop[:, 1])  # the other way
    assert info["group"] == info_left["group"]  # one group, so the folds split the loops


def test_the_heavy_noise_receiver_has_two_long_outages_and_more_dropouts():
    case = blind.CASES["noise_heavy"]
    ex, ey, keep = blind.receiver(case, 401, np.random.default_rng(case.seed))  # 40 s of fixes
    edges = np.flatnonzero(np.diff(np.r_[1, keep.astype(int), 1]) != 0)
    gaps = np.diff(edges)[::2]  # the lengths of the runs of missing fixes
    assert np.sum(gaps >= round(case.outage_s / blind.FIX_PERIOD)) == 2
    assert np.std(np.r_[ex, ey]) == pytest.approx(case.noise, rel=0.1)
    coloured = blind.CASES["noise_coloured"]
    e = blind.receiver(coloured, 20000, np.random.default_rng(0))[0]
    assert np.corrcoef(e[1:], e[:-1])[0, 1] == pytest.approx(coloured.colour, abs=0.02)
    assert np.std(e) == pytest.approx(coloured.noise, rel=0.1)
