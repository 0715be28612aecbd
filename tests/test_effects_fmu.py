"""The vehicle's effects variant: exactly the baseline with every effect off, and each effect
doing what its hypothesis says, checked against closed-form consequences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import FMU_SOURCES

from dse_runner.simulation.cosim import make_plan, run
from dse_runner.errors import DseError
from dse_runner.simulation.multimodel import MultiModel


def plan_of(fmu: str):
    return make_plan(MultiModel(fmus={"vehicle": str(FMU_SOURCES / fmu)}))


@pytest.fixture(scope="module")
def baseline():
    return plan_of("robotti_vehicle")


@pytest.fixture(scope="module")
def effects():
    return plan_of("robotti_vehicle_effects")


def drive(plan, stop: float, **values: float):
    return run(plan, {f"vehicle.{k}": v for k, v in values.items()}, 0.0, stop, 0.05)


def test_effects_off_is_the_baseline_bit_for_bit(baseline, effects):
    inputs = dict(velocity=2.0, delta_f=0.15, mass=1700.0, cAlphaF=25000.0, theta0=0.4)
    a, b = drive(baseline, 20.0, **inputs), drive(effects, 20.0, **inputs)
    for name in ("x", "y", "theta", "vx", "vy", "yaw_rate"):
        assert np.array_equal(a.column(f"vehicle.{name}"), b.column(f"vehicle.{name}"))
    assert np.array_equal(b.column("vehicle.gps_x"), b.column("vehicle.x"))


def test_wheel_slip_scales_the_ground_speed(effects):
    traj = drive(effects, 30.0, velocity=2.0, wheel_slip=0.1)
    assert traj.column("vehicle.vx")[-1] == pytest.approx(0.9 * 2.0, rel=1e-6)


def test_speed_lag_slows_the_approach_to_the_commanded_speed(effects):
    quick, slow = drive(effects, 3.0, velocity=2.0), drive(effects, 3.0, velocity=2.0, speed_lag=1.0)
    t = quick.time.searchsorted(1.0)
    assert slow.column("vehicle.vx")[t] < 0.7 * quick.column("vehicle.vx")[t]
    assert drive(effects, 30.0, velocity=2.0, speed_lag=1.0).column("vehicle.vx")[-1] == pytest.approx(2.0, rel=1e-6)


def test_time_offset_delays_everything(effects):
    direct, late = drive(effects, 20.0, velocity=2.0, delta_f=0.1), drive(effects, 20.0, velocity=2.0, delta_f=0.1,
                                                                        time_offset=0.5)
    shift = 10  # 0.5 s at 0.05 s per step
    # Equal but for the instant of the switch, which the delayed run already sees at the end of the
    # step before it: under a millimetre, against the metre the vehicle covers in those 0.5 s.
    assert np.abs(late.column("vehicle.x")[shift:] - direct.column("vehicle.x")[:-shift]).max() < 1e-3
    assert np.all(late.column("vehicle.vx")[:shift] == 0.0)


def test_steering_offset_turns_a_straight_command(effects):
    traj = drive(effects, 30.0, velocity=2.0, steering_offset=0.05)
    assert traj.column("vehicle.theta")[-1] < -0.5  # positive = right = clockwise


def test_steering_lag_delays_the_turn_but_not_the_circle(effects):
    direct, lagged = drive(effects, 40.0, velocity=2.0, delta_f=-0.1), drive(effects, 40.0, velocity=2.0,
                                                                           delta_f=-0.1, steering_lag=0.5)
    t = direct.time.searchsorted(2.0)
    assert lagged.column("vehicle.theta")[t] < direct.column("vehicle.theta")[t]
    assert lagged.column("vehicle.yaw_rate")[-1] == pytest.approx(direct.column("vehicle.yaw_rate")[-1], rel=1e-6)


def test_antenna_rotates_with_the_heading(effects):
    traj = drive(effects, 1.0, theta0=math.pi / 2, antenna_x=1.0, antenna_y=0.5)
    assert traj.column("vehicle.gps_x")[0] == pytest.approx(-0.5)
    assert traj.column("vehicle.gps_y")[0] == pytest.approx(1.0)


def test_uphill_is_slower_by_the_drive_gain(effects):
    grade, mass, kv = 0.05, 1500.0, 8000.0
    traj = drive(effects, 40.0, velocity=2.0, grade_x=grade, mass=mass, Kv=kv)  # heading east, uphill
    assert traj.column("vehicle.vx")[-1] == pytest.approx(2.0 - mass * 9.81 * grade / kv, rel=1e-4)


@pytest.mark.parametrize("name,value", [("speed_lag", -0.1), ("time_offset", -1.0), ("wheel_slip", 0.95)])
def test_impossible_effect_values_are_refused_by_name(effects, name, value):
    with pytest.raises(DseError, match=name):
        drive(effects, 1.0, **{name: value})


