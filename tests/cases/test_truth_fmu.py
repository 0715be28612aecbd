"""The blind tests' truth (tests/fmus/robotti_truth): with its own right-hand side it computes what the
effects variant computes, library effects included, and each effect outside the library does what its
form says, checked against closed-form consequences computed from its parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import SCENARIOS
from support import blind

from dse_runner.errors import DseError
from dse_runner.simulation.cosim import run
from dse_runner.simulation.multimodel import MultiModel
from dse_runner.simulation.plan import make_plan
from dse_runner.simulation.run import simulate
from dse_runner.simulation.scenario import load_scenario

TRUTH = blind.REPO / "tests" / "fmus" / "robotti_truth"
OUTPUTS = ("x", "y", "theta", "vx", "vy", "yaw_rate", "gps_x", "gps_y")


@pytest.fixture(scope="module")
def truth():
    return make_plan(MultiModel(fmus={"vehicle": str(TRUTH)}))


def drive(plan, stop: float, **values: float):
    """Constant commands and parameters from t = 0, at the logs' 0.05 s step."""
    return run(plan, {f"vehicle.{k}": v for k, v in values.items()}, 0.0, stop, 0.05)


def at(traj, name: str, t: float) -> float:
    return float(traj.column(f"vehicle.{name}")[traj.time.searchsorted(t - 1e-9)])


@pytest.mark.parametrize("effect", list(blind.EFFECTS))  # "none": everything off
def test_the_truth_is_the_effects_variant_on_a_recorded_run(effect):
    """Each library effect, and none, replayed on a bundled run: the same trajectory from independent code."""
    scenario = load_scenario(SCENARIOS / "sin1")
    values = {**blind.TRUTH_VEHICLE, **{f"vehicle.{k}": v for k, v in blind.EFFECTS[effect].items()}}
    a = simulate(blind.truth_plan("effects"), scenario, values, objectives=(), step=blind.STEP).trajectory
    b = simulate(blind.truth_plan("truth"), scenario, values, objectives=(), step=blind.STEP).trajectory
    assert np.array_equal(a.time, b.time)
    for name in OUTPUTS:
        assert np.abs(a.column(f"vehicle.{name}") - b.column(f"vehicle.{name}")).max() <= 1e-9, name


def test_relaxation_delays_the_turn_but_not_the_circle(truth):
    """A lagging tyre force settles to the same force: the same circle, reached later. (With the yaw inertia
    the lag makes the turn-in ring; at 2 m/s and 0.8 m it overshoots the circle's yaw rate.)"""
    inputs = {"velocity": 2.0, "delta_f": -0.1}
    direct, relaxed = drive(truth, 40.0, **inputs), drive(truth, 40.0, relaxation=0.8, **inputs)
    steady = direct.column("vehicle.yaw_rate")[-1]
    assert at(relaxed, "yaw_rate", 0.2) < 0.5 * at(direct, "yaw_rate", 0.2)
    assert relaxed.column("vehicle.yaw_rate").max() > 1.1 * steady
    assert relaxed.column("vehicle.yaw_rate")[-1] == pytest.approx(steady, rel=1e-6)


def test_a_steering_rate_limit_turns_the_wheels_at_the_limit(truth):
    limit, target = 0.08, 0.2
    traj = drive(truth, 5.0, velocity=1.0, delta_f=target, steer_rate_limit=limit)
    t, delta = traj.time, traj.column("vehicle.delta_wheels")
    ramp = (t > 0.2) & (t < target / limit - 0.2)
    assert np.diff(delta[ramp]) / np.diff(t[ramp]) == pytest.approx(limit, rel=1e-9)
    assert delta[-1] == pytest.approx(target, abs=1e-9)
    unlimited = drive(truth, 5.0, velocity=1.0, delta_f=target)
    assert np.all(unlimited.column("vehicle.delta_wheels")[1:] == target)  # [0]: before the first command


def test_payload_adds_mass_and_a_draft_at_its_time(truth):
    """Before t_p the commanded speed; after it, a first-order approach (time constant (m + dm) / Kv) to the
    speed at which the drive pulls the draft: a deficit of draft * (m + dm) * g / Kv."""
    mass, extra, when, draft, kv, speed, g = 1500.0, 400.0, 10.0, 0.06, 8000.0, 2.0, 9.81
    traj = drive(
        truth, 30.0, velocity=speed, mass=mass, Kv=kv, payload=extra, payload_time=when, payload_draft=draft
    )
    deficit = draft * (mass + extra) * g / kv
    assert at(traj, "vx", when - 0.05) == pytest.approx(speed, rel=1e-9)
    assert traj.column("vehicle.vx")[-1] == pytest.approx(speed - deficit, rel=1e-9)
    t = np.array([0.1, 0.2, 0.5])
    approach = speed - deficit * (1 - np.exp(-t * kv / (mass + extra)))
    seen = np.array([at(traj, "vx", when + dt) for dt in t])
    assert seen == pytest.approx(approach, abs=0.01 * deficit)  # the lowering falls within a 1 ms RK4 step


def test_payload_draft_is_pulled_through_slipping_wheels(truth):
    """On soil the drive regulates wheel speed: ground speed = (1 - slip) * (v - F / Kv)."""
    mass, extra, draft, kv, slip, speed = 1500.0, 400.0, 0.06, 8000.0, 0.05, 2.0
    traj = drive(
        truth,
        30.0,
        velocity=speed,
        mass=mass,
        Kv=kv,
        payload=extra,
        payload_time=1.0,
        payload_draft=draft,
        wheel_slip=slip,
    )
    assert traj.column("vehicle.vx")[-1] == pytest.approx(
        (1 - slip) * (speed - draft * (mass + extra) * 9.81 / kv), rel=1e-9
    )


@pytest.mark.parametrize("speed", [0.8, 2.0])
def test_rolling_resistance_slows_every_speed_by_the_same_deficit(truth, speed):
    """The drive, Kv (v - vx), pulls c m g at a deficit of c m g / Kv, whatever the speed (wheel slip's grows
    with it); m is the current mass, so lowering a payload deepens it to c (m + dm) g / Kv."""
    c, mass, extra, when, kv, g = 0.05, 1500.0, 400.0, 10.0, 8000.0, 9.81
    traj = drive(
        truth, 30.0, velocity=speed, mass=mass, Kv=kv, payload=extra, payload_time=when, rolling_resistance=c
    )
    assert at(traj, "vx", when - 0.05) == pytest.approx(speed - c * mass * g / kv, rel=1e-9)
    assert traj.column("vehicle.vx")[-1] == pytest.approx(speed - c * (mass + extra) * g / kv, rel=1e-9)


def test_rolling_resistance_from_rest_is_the_closed_form(truth):
    """From rest at u = 0.8 m/s (Kv u < mu m g: the drive never saturates), m dv/dt = Kv (u - v) - c m g s,
    s = min(v / v_min, 1). Below v_min it is linear with rate k = Kv + c m g / v_min: v = v_a (1 -
    exp(-k t / m)), v_a = Kv u / k, reaching v_min at t1 = -(m / k) ln(1 - v_min / v_a); from there the
    exponential of time constant m / Kv to v_ss = u - c m g / Kv."""
    c, mass, kv, v_min, g, u = 0.05, 1500.0, 8000.0, 0.5, 9.81, 0.8
    assert kv * u < 0.5 * mass * g and u - c * mass * g / kv > v_min
    traj = drive(truth, 10.0, velocity=u, mass=mass, Kv=kv, v_min=v_min, rolling_resistance=c)
    k = kv + c * mass * g / v_min
    v_a = kv * u / k
    t1 = -(mass / k) * math.log(1 - v_min / v_a)
    v_ss = u - c * mass * g / kv
    below = np.array([0.05, 0.1, 0.2])
    above = np.array([0.3, 0.5, 1.0, 2.0])
    assert below[-1] < t1 < above[0]
    assert at(traj, "vx", 0.0) == 0.0
    seen = np.array([at(traj, "vx", t) for t in below])
    assert seen == pytest.approx(v_a * (1 - np.exp(-k * below / mass)), abs=1e-9)  # smooth: RK4 at 1 ms
    seen = np.array([at(traj, "vx", t) for t in above])
    # at v_min the force's slope jumps, and dv2/dt2 by (c g / v_min) dv/dt ~ 1.1 m/s^3: the RK4 step across it
    # errs by about h^3 times that, 1e-9 m/s (h = 1 ms)
    assert seen == pytest.approx(v_ss + (v_min - v_ss) * np.exp(-kv * (above - t1) / mass), abs=1e-8)
    assert traj.column("vehicle.vx")[-1] == pytest.approx(v_ss, rel=1e-9)


def test_mast_roll_moves_the_antenna_sideways_with_the_heading(truth):
    """Over a full loop the antenna is h*gamma * sin(theta - psi_s) to the left of the reference point:
    furthest left at psi_s + pi/2, furthest right at psi_s - pi/2, never forward or back."""
    lean, heading = 0.2, 0.7
    traj = drive(truth, 40.0, velocity=1.6, delta_f=0.25, mast_roll=lean, mast_roll_heading=heading)
    theta = traj.column("vehicle.theta")
    dx = traj.column("vehicle.gps_x") - traj.column("vehicle.x")
    dy = traj.column("vehicle.gps_y") - traj.column("vehicle.y")
    left, forward = -dx * np.sin(theta) + dy * np.cos(theta), dx * np.cos(theta) + dy * np.sin(theta)
    assert np.ptp(theta) > 2 * math.pi
    assert left == pytest.approx(lean * np.sin(theta - heading), abs=1e-12)
    assert np.abs(forward).max() < 1e-12
    assert left.max() == pytest.approx(lean, rel=1e-3) and left.min() == pytest.approx(-lean, rel=1e-3)
    furthest_left = theta[np.argmax(left)]
    assert math.remainder(furthest_left - heading - math.pi / 2, 2 * math.pi) == pytest.approx(0, abs=0.05)


@pytest.mark.parametrize("speed", [0.8, 2.0])
def test_steering_loses_authority_with_speed(truth, speed):
    """The wheels turn delta * (1 - k vx): the circle of a vehicle steered that much less, and in the linear
    tyre range a yaw rate smaller by that factor."""
    k, delta = 0.12, -0.05
    lost = drive(truth, 40.0, velocity=speed, delta_f=delta, steer_gain_speed=k)
    vx = lost.column("vehicle.vx")
    assert lost.column("vehicle.delta_wheels")[1:] == pytest.approx(delta * (1 - k * vx[1:]), abs=1e-15)
    factor = 1 - k * vx[-1]
    same = drive(truth, 40.0, velocity=speed, delta_f=delta * factor)
    full = drive(truth, 40.0, velocity=speed, delta_f=delta)
    assert lost.column("vehicle.yaw_rate")[-1] == pytest.approx(same.column("vehicle.yaw_rate")[-1], rel=1e-6)
    assert lost.column("vehicle.yaw_rate")[-1] / full.column("vehicle.yaw_rate")[-1] == pytest.approx(
        1 - k * speed, rel=2e-3
    )


def test_slip_grows_with_the_pull(truth):
    """slip = i0 + k |F| / (m g): i0 on the flat at cruise (no pull), i0 + k * grade uphill (F = m g grade),
    and the ground speed (1 - slip) * (v - F / Kv)."""
    i0, k, grade, mass, kv, speed = 0.03, 0.3, 0.05, 1500.0, 8000.0, 2.0
    flat = drive(truth, 30.0, velocity=speed, wheel_slip=i0, slip_pull=k, mass=mass, Kv=kv)
    assert flat.column("vehicle.slip")[-1] == pytest.approx(i0, abs=1e-9)
    assert flat.column("vehicle.vx")[-1] == pytest.approx((1 - i0) * speed, rel=1e-9)
    hill = drive(truth, 30.0, velocity=speed, wheel_slip=i0, slip_pull=k, mass=mass, Kv=kv, grade_x=grade)
    slip = i0 + k * grade
    assert hill.column("vehicle.slip")[-1] == pytest.approx(slip, rel=1e-9)
    pull = mass * 9.81 * grade
    assert hill.column("vehicle.vx")[-1] == pytest.approx((1 - slip) * (speed - pull / kv), rel=1e-9)


@pytest.mark.parametrize(
    "name", ["relaxation", "payload", "payload_draft", "slip_pull", "steer_rate_limit", "rolling_resistance"]
)
def test_impossible_effect_values_are_refused_by_name(truth, name):
    with pytest.raises(DseError, match=name):
        drive(truth, 1.0, **{name: -0.1})


def test_the_truth_is_its_own_code():
    """A bug shared with the model under diagnosis could hide in both: the truth includes no vehicle model."""
    assert '#include "bicycle.h"' not in (TRUTH / "model.c").read_text()
