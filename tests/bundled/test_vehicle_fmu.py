"""The vehicle FMU against closed-form cases of the baseline model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import FMU_SOURCES

from dse_runner.simulation.cosim import run
from dse_runner.simulation.multimodel import MultiModel
from dse_runner.simulation.plan import make_plan


@pytest.fixture(scope="module")
def vehicle():
    return make_plan(MultiModel(fmus={"vehicle": str(FMU_SOURCES / "robotti_vehicle")}))


def drive(plan, stop: float, **values: float):
    return run(plan, {f"vehicle.{k}": v for k, v in values.items()}, 0.0, stop, 0.05)


def test_straight_line_at_constant_speed(vehicle):
    x0, y0, theta0, speed = 3.0, -2.0, 0.7, 2.5
    traj = drive(vehicle, 30.0, x0=x0, y0=y0, theta0=theta0, velocity=speed, delta_f=0.0)
    x, y = traj.column("vehicle.x"), traj.column("vehicle.y")
    # Every point lies on the line through the start along theta0.
    across = -(x - x0) * math.sin(theta0) + (y - y0) * math.cos(theta0)
    assert np.abs(across).max() < 1e-9
    assert np.abs(traj.column("vehicle.theta") - theta0).max() < 1e-12
    assert np.abs(traj.column("vehicle.yaw_rate")).max() < 1e-12
    # Once the drive has settled the speed is the command and distance grows at that speed.
    late = traj.time >= 10.0
    assert np.abs(traj.column("vehicle.vx")[late] - speed).max() < 1e-6
    along = (x - x0) * math.cos(theta0) + (y - y0) * math.sin(theta0)
    covered = along[-1] - along[traj.time.searchsorted(20.0)]
    assert covered == pytest.approx(speed * 10.0, abs=1e-6)


def test_at_rest_without_command(vehicle):
    traj = drive(vehicle, 5.0, x0=1.0, y0=2.0, theta0=0.3)
    assert np.all(traj.column("vehicle.x") == 1.0) and np.all(traj.column("vehicle.y") == 2.0)


def steady_turn(plan, speed: float, delta_f: float, **params: float):
    """Radius and yaw rate after a long constant-steer drive, with the speed actually reached."""
    traj = drive(plan, 60.0, velocity=speed, delta_f=delta_f, **params)
    late = traj.time >= 40.0
    vx, vy = traj.column("vehicle.vx")[late], traj.column("vehicle.vy")[late]
    r = traj.column("vehicle.yaw_rate")[late]
    v = np.hypot(vx, vy)
    assert np.ptp(r) < 1e-6 * abs(r.mean())  # steady state reached
    return float(v.mean() / abs(r.mean())), float(r.mean()), traj


@pytest.mark.parametrize("cf, cr", [(30000.0, 30000.0), (20000.0, 40000.0), (40000.0, 25000.0)])
def test_steady_circle_radius_is_kinematic_radius_with_understeer(vehicle, cf, cr):
    mass, lf, lr, delta = 1500.0, 0.9, 0.9, 0.04
    L = lf + lr
    radius, yaw_rate, traj = steady_turn(vehicle, 3.0, delta, cAlphaF=cf, cAlphaR=cr, mass=mass)
    speed = float(np.hypot(traj.column("vehicle.vx")[-1], traj.column("vehicle.vy")[-1]))
    # Linear bicycle model: delta = L/R + K v^2/R, understeer gradient K = m/L (lr/Cf - lf/Cr).
    understeer = mass / L * (lr / cf - lf / cr)
    expected = (L + understeer * speed**2) / delta
    assert radius == pytest.approx(expected, rel=0.01)
    # The path itself is a circle of that radius (least-squares circle through the positions).
    late = traj.time >= 40.0
    x, y = traj.column("vehicle.x")[late], traj.column("vehicle.y")[late]
    (d, e, f), *_ = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), -(x**2 + y**2), rcond=None)
    fitted = math.sqrt(d**2 / 4 + e**2 / 4 - f)
    assert fitted == pytest.approx(radius, rel=1e-3)
    assert yaw_rate < 0  # positive delta_f is a right (clockwise) turn


def test_understeer_widens_the_circle(vehicle):
    neutral, _, _ = steady_turn(vehicle, 3.0, 0.04, cAlphaF=30000.0, cAlphaR=30000.0)
    understeering, _, _ = steady_turn(vehicle, 3.0, 0.04, cAlphaF=15000.0, cAlphaR=45000.0)
    assert understeering > neutral * 1.05


def test_left_turn_is_counter_clockwise(vehicle):
    _, yaw_rate, _ = steady_turn(vehicle, 2.0, -0.05)
    assert yaw_rate > 0


def test_start_values_match_model_description(vehicle):
    """modelDescription.xml and the C defaults describe the same FMU."""
    from dse_runner.simulation import fmu as fmus

    loaded = fmus.load(vehicle.fmu_paths["vehicle"])
    instance = fmus.acquire("vehicle", loaded)
    for variable in loaded.description.modelVariables:
        if variable.start is not None:
            (value,) = instance.slave.getReal([variable.valueReference])
            assert value == pytest.approx(float(variable.start)), variable.name
