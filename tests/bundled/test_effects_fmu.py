"""The vehicle's effects variant: exactly the baseline with every effect off, and each effect
doing what its hypothesis says, checked against closed-form consequences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import FMU_SOURCES

from dse_runner.errors import DseError
from dse_runner.simulation.cosim import run
from dse_runner.simulation.multimodel import MultiModel
from dse_runner.simulation.plan import make_plan


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
    inputs = {"velocity": 2.0, "delta_f": 0.15, "mass": 1700.0, "cAlphaF": 25000.0, "theta0": 0.4}
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
    assert drive(effects, 30.0, velocity=2.0, speed_lag=1.0).column("vehicle.vx")[-1] == pytest.approx(
        2.0, rel=1e-6
    )


def test_time_offset_delays_everything(effects):
    direct, late = (
        drive(effects, 20.0, velocity=2.0, delta_f=0.1),
        drive(effects, 20.0, velocity=2.0, delta_f=0.1, time_offset=0.5),
    )
    shift = 10  # 0.5 s at 0.05 s per step
    # Equal but for the instant of the switch, which the delayed run already sees at the end of the
    # step before it: under a millimetre, against the metre the vehicle covers in those 0.5 s.
    assert np.abs(late.column("vehicle.x")[shift:] - direct.column("vehicle.x")[:-shift]).max() < 1e-3
    assert np.all(late.column("vehicle.vx")[:shift] == 0.0)


def test_steering_offset_turns_a_straight_command(effects):
    traj = drive(effects, 30.0, velocity=2.0, steering_offset=0.05)
    assert traj.column("vehicle.theta")[-1] < -0.5  # positive = right = clockwise


def test_steering_lag_delays_the_turn_but_not_the_circle(effects):
    direct, lagged = (
        drive(effects, 40.0, velocity=2.0, delta_f=-0.1),
        drive(effects, 40.0, velocity=2.0, delta_f=-0.1, steering_lag=0.5),
    )
    t = direct.time.searchsorted(2.0)
    assert lagged.column("vehicle.theta")[t] < direct.column("vehicle.theta")[t]
    assert lagged.column("vehicle.yaw_rate")[-1] == pytest.approx(
        direct.column("vehicle.yaw_rate")[-1], rel=1e-6
    )


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


# The correction block (docs/research/diagnosis-beyond-library.md §4.3): corr_* coefficients, zero = off.

EFFECTS_SOURCE = FMU_SOURCES / "robotti_vehicle_effects"


def test_every_correction_term_is_a_parameter_of_the_fmu_in_order():
    """correction.TERMS, model.c's CORR_TERMS and modelDescription.xml name the same terms in the same order,
    after gps_y, with value references that are their indices in model.c's enum Real."""
    import re
    import xml.etree.ElementTree as ET

    from dse_runner.cases.robotti_diagnosis import correction

    root = ET.parse(EFFECTS_SOURCE / "modelDescription.xml").getroot()
    described = [
        (v.get("name"), int(v.get("valueReference")), v.get("causality"), v.find("Real").get("start"))
        for v in root.iter("ScalarVariable")
    ]
    gps_y = next(vr for name, vr, *_ in described if name == "gps_y")
    shapes = [s.variable for s in correction.SHAPES.values()]
    corr = [
        (name, vr, causality, start)
        for name, vr, causality, start in described
        if name.startswith("corr_") and name not in shapes
    ]
    assert [name for name, *_ in corr] == correction.variables()
    assert [vr for _, vr, *_ in corr] == list(range(gps_y + 1, gps_y + 1 + len(correction.TERMS)))
    assert {(causality, float(start)) for *_, causality, start in corr} == {("parameter", 0.0)}
    after = [
        (name, vr, causality, float(start)) for name, vr, causality, start in described if name in shapes
    ]
    assert after == [
        (s.variable, gps_y + 1 + len(correction.TERMS) + k, "parameter", s.default)
        for k, s in enumerate(correction.SHAPES.values())
    ]  # after the coefficients, at their defaults
    assert [vr for _, vr, *_ in described] == list(range(len(described)))  # no existing reference moved
    in_c = re.findall(r'X\(\w+, "(corr_\w+)"\)', (EFFECTS_SOURCE / "model.c").read_text())
    assert in_c == correction.variables()
    assert len({t.variable for t in correction.TERMS}) == len(correction.TERMS)


def test_a_steering_term_of_one_is_the_steering_offset_bit_for_bit(effects):
    """corr_steer_1 adds to the steering angle where steering_offset does: (δ + 0) +
    c and (δ + c) + 0 round alike."""
    inputs = {"velocity": 2.0, "delta_f": 0.1, "steering_lag": 0.3, "wheel_slip": 0.05, "theta0": 0.4}
    offset = drive(effects, 20.0, steering_offset=0.03, **inputs)
    corrected = drive(effects, 20.0, corr_steer_1=0.03, **inputs)
    for name in ("x", "y", "theta", "vx", "vy", "yaw_rate", "gps_x", "gps_y"):
        assert np.array_equal(offset.column(f"vehicle.{name}"), corrected.column(f"vehicle.{name}"))


def test_antenna_terms_of_one_are_the_antenna_offset_bit_for_bit(effects):
    inputs = {"velocity": 2.0, "delta_f": -0.1, "theta0": 0.4}
    lever = drive(effects, 10.0, antenna_x=0.7, antenna_y=-0.3, **inputs)
    corrected = drive(effects, 10.0, corr_gps_along_1=0.7, corr_gps_cross_1=-0.3, **inputs)
    for name in ("x", "y", "theta", "vx", "gps_x", "gps_y"):
        assert np.array_equal(lever.column(f"vehicle.{name}"), corrected.column(f"vehicle.{name}"))


def test_a_drive_force_term_of_one_doubles_the_drive_gain_bit_for_bit(effects):
    """d(vx)/dt += 1·F_drive/m on a straight line, below the friction limit, is Kv doubled: 2F/m rounds as
    F/m + F/m. This pins model.c's copy of the drive force to bicycle.h's."""
    doubled = drive(effects, 10.0, velocity=0.3, Kv=16000.0)
    corrected = drive(effects, 10.0, velocity=0.3, Kv=8000.0, corr_acc_fdrive=1.0)
    assert np.array_equal(doubled.column("vehicle.vx"), corrected.column("vehicle.vx"))
    assert np.array_equal(doubled.column("vehicle.x"), corrected.column("vehicle.x"))


def test_an_onset_term_is_off_before_its_time_and_its_feature_after(effects):
    """corr_acc_onset_fdrive = 1 from t₀ = 3 s: up to 3 s the baseline bit for bit (the term adds 0), after it
    the drive gain doubled, as corr_acc_fdrive = 1 from the start is; at t₀ = 0 the two terms are the same."""
    inputs = {"velocity": 0.3, "delta_f": 0.05}
    base = drive(effects, 6.0, **inputs)
    late = drive(effects, 6.0, corr_acc_onset_fdrive=1.0, corr_onset_time=3.0, **inputs)
    early = drive(effects, 6.0, corr_acc_onset_fdrive=1.0, **inputs)
    doubled = drive(effects, 6.0, corr_acc_fdrive=1.0, **inputs)
    before = base.time < 3.0 - 1e-9  # the step that ends at 3 s evaluates its last stage there
    assert np.array_equal(base.column("vehicle.vx")[before], late.column("vehicle.vx")[before])
    assert np.array_equal(early.column("vehicle.vx"), doubled.column("vehicle.vx"))
    # After 3 s the speed leaves the baseline's, towards the doubled gain's: closer to it at the end.
    assert not np.array_equal(base.column("vehicle.vx")[~before], late.column("vehicle.vx")[~before])
    end = -1
    assert abs(late.column("vehicle.vx")[end] - doubled.column("vehicle.vx")[end]) < abs(
        base.column("vehicle.vx")[end] - doubled.column("vehicle.vx")[end]
    )


def test_a_resistance_against_the_motion_lowers_the_cruise_by_its_force_over_the_drive_gain(effects):
    """d(vx)/dt = Kv(u − vx)/m + c·clamp(vx/v_min, −1, 1), straight, c < 0, cruising above v_min: the drive
    settles where Kv(u − vx) = −c·m, vx = u + c·m/Kv (a rolling resistance's speed deficit)."""
    u, c, kv, mass = 1.5, -0.4, 8000.0, 1500.0
    traj = drive(effects, 15.0, velocity=u, corr_acc_sgnv=c, Kv=kv, mass=mass)
    assert traj.column("vehicle.vx")[-1] == pytest.approx(u + c * mass / kv, abs=1e-9)
    standing = drive(effects, 3.0, velocity=0.0, corr_acc_sgnv=c)
    assert np.all(
        standing.column("vehicle.vx") == 0.0
    )  # no motion, no force: a standing vehicle is not pushed


def test_the_rate_limiter_ramps_at_its_limit_then_closes_exponentially():
    """correction.rate_limited, y' = clamp((u − y)/τ, ±L) in closed form, against a fine Euler integration of
    the same equation for a command that steps up, holds, and steps down."""
    from dse_runner.cases.robotti_diagnosis import correction

    t = np.round(np.arange(0.0, 12.0 + 1e-9, 0.05), 2)
    u = np.where(t < 1.0, 0.0, np.where(t < 6.0, 0.1, -0.05))
    y = correction.rate_limited(t, u, 0.04)
    dt, state, fine = 1e-5, 0.0, [0.0]
    for k in range(1, len(t)):
        for _ in range(round((t[k] - t[k - 1]) / dt)):
            state += dt * min(max((u[k - 1] - state) / correction.TAU_TRACK, -0.04), 0.04)
        fine.append(state)
    assert np.abs(y - np.array(fine)).max() < 1e-5
    assert y[t == 2.0][0] == pytest.approx(0.04 * 1.0, abs=1e-3)  # a second into the ramp


def test_a_rate_limited_steering_term_turns_as_the_limited_angle_would(effects):
    """corr_steer_ratelim = 1 makes the steering lim(δ, L): with a step of 0.1 rad at 2 m/s and L = 0.02
    rad/s the heading follows ∫ G(v)·lim(δ, L) dt (G the steady yaw gain; the yaw mode settles in
    hundredths of a second), half the unlimited turn after 5 s (the ramp reaches the step at 5 s); with
    L far above the step's needs it is the unlimited turn but for the limiter's 0.01 s of tracking."""
    from dse_runner.cases.robotti_diagnosis import correction

    inputs = {"velocity": 2.0, "delta_f": 0.1}
    limited = drive(effects, 5.0, corr_steer_ratelim=1.0, corr_rate_limit=0.02, **inputs)
    free = drive(effects, 5.0, **inputs)
    loose = drive(effects, 5.0, corr_steer_ratelim=1.0, corr_rate_limit=100.0, **inputs)
    t, vx = limited.time, limited.column("vehicle.vx")
    mass, lf, lr, c = 1500.0, 0.9, 0.9, 30000.0
    gain = -vx / (lf + lr + mass / (lf + lr) * (lr / c - lf / c) * vx**2)
    delta = correction.rate_limited(t, np.full(len(t), 0.1), 0.02)
    rate = gain * delta
    heading = np.concatenate([[0.0], np.cumsum(np.diff(t) * 0.5 * (rate[1:] + rate[:-1]))])
    assert limited.column("vehicle.theta")[-1] == pytest.approx(heading[-1], rel=0.03)
    assert abs(limited.column("vehicle.theta")[-1]) < 0.6 * abs(free.column("vehicle.theta")[-1])
    assert loose.column("vehicle.theta")[-1] == pytest.approx(free.column("vehicle.theta")[-1], rel=0.01)


def test_an_acceleration_term_in_the_speed_is_an_exponential_approach(effects):
    """d(vx)/dt = Kv(u − vx)/m + c·vx from rest (straight, below the friction limit) is vx = v∞(1 − e^(−λt)),
    λ = Kv/m − c, v∞ = Kv·u/(m·λ): slower than commanded, as wheel slip is, for c < 0."""
    u, c, kv, mass = 0.5, -0.31, 8000.0, 1500.0
    traj = drive(effects, 5.0, velocity=u, corr_acc_v=c, Kv=kv, mass=mass)
    lam = kv / mass - c
    expected = kv * u / (mass * lam) * (1.0 - np.exp(-lam * traj.time))
    assert np.abs(traj.column("vehicle.vx") - expected).max() < 1e-9


def test_the_filtered_command_rate_matches_correction_py(effects):
    """With no drive (Kv = 0), d(vx)/dt = 1·a_cmd integrates to the filtered command w(t) = u(1 − e^(−t/τ_f)),
    which correction.filtered_rate computes in closed form from the command log."""
    from dse_runner.cases.robotti_diagnosis import correction

    traj = drive(effects, 2.0, velocity=0.8, Kv=0.0, corr_acc_acmd=1.0)
    w, rate = correction.filtered_rate(np.array([0.0]), np.array([0.8]), traj.time)
    assert np.abs(traj.column("vehicle.vx") - w).max() < 1e-9
    assert rate[0] == pytest.approx(0.8 / correction.TAU_F)


def test_antenna_terms_use_the_heading_and_speed_as_correction_py_does(effects):
    """gps_along += c1·cos 2ψ + c2·v and gps_cross += c3·sin ψ, checked from
    the FMU's own heading and speed."""
    from dse_runner.cases.robotti_diagnosis import correction

    values = {"corr_gps_along_cos2psi": 0.2, "corr_gps_along_v": 0.1, "corr_gps_cross_sinpsi": -0.3}
    traj = drive(effects, 10.0, velocity=2.0, delta_f=-0.2, **values)
    theta, vx = traj.column("vehicle.theta"), traj.column("vehicle.vx")
    zero = np.zeros_like(theta)
    cols = correction.features(
        correction.FeatureInputs(
            v=vx, psi=theta, r=zero, s=zero, v_cmd=zero, a_cmd=zero, delta=zero, delta_rate=zero, f_drive=zero
        )
    )
    along = sum(v * cols[k] for k, v in values.items() if "along" in k)
    cross = sum(v * cols[k] for k, v in values.items() if "cross" in k)
    gx = traj.column("vehicle.x") + along * np.cos(theta) - cross * np.sin(theta)
    gy = traj.column("vehicle.y") + along * np.sin(theta) + cross * np.cos(theta)
    assert np.abs(traj.column("vehicle.gps_x") - gx).max() < 1e-12
    assert np.abs(traj.column("vehicle.gps_y") - gy).max() < 1e-12


def test_a_non_finite_correction_is_refused_by_name(effects):
    with pytest.raises(DseError, match="corr_yaw_r"):
        drive(effects, 1.0, corr_yaw_r=float("nan"))


def test_correction_terms_read_as_equations():
    from dse_runner.cases.robotti_diagnosis import correction

    assert correction.readable({"vehicle.corr_acc_v": -0.31}) == ["d(v)/dt += -0.31·v"]
    assert correction.readable(
        {"corr_steer_ddelta": -0.4, "corr_steer_1": 0.012, "corr_acc_v": 0.0, "vehicle.mass": 1500.0}
    ) == ["δ += 0.012 - 0.4·δ̇"]
    assert correction.readable(
        {"corr_gps_cross_sinpsi": 0.12, "corr_acc_acmd": 0.05, "corr_acc_v2": -0.02}
    ) == ["d(v)/dt += -0.02·v² + 0.05·a_cmd", "gps_cross += 0.12·sin ψ"]
    assert (
        correction.readable_term(correction.term("corr_acc_v"), -0.31, (-0.34, -0.28))
        == "d(v)/dt += -0.31·v [-0.34, -0.28]"
    )
    assert correction.readable({"vehicle.corr_acc_onset_sgnv": -0.59, "vehicle.corr_onset_time": 10.05}) == [
        "d(v)/dt += -0.59·[t ≥ 10.05 s]·sgn v"
    ]
    assert correction.readable({"corr_acc_onset_fdrive": -0.2}) == ["d(v)/dt += -0.2·[t ≥ t₀]·F_drive/m"]
    assert correction.readable({"corr_steer_ratelim": 1.02, "corr_rate_limit": 0.08}) == [
        "δ += 1.02·(lim(δ, 0.08 rad/s) − δ)"
    ]
    with pytest.raises(DseError, match="not a correction term"):
        correction.term("corr_acc_w")


def test_correction_bounds_scale_with_the_feature():
    from dse_runner.cases.robotti_diagnosis import correction

    acc_v = correction.term("corr_acc_v")
    assert correction.bound(acc_v, rms=2.0) == pytest.approx(1.0)  # 2 m/s² over an RMS speed of 2 m/s
    assert correction.bound(acc_v) == pytest.approx(2.0 / 1.5)  # the typical speed when no runs are given
    from dse_runner.analysis.diagnose.term_search import started

    p = started(correction.parameter(acc_v, "vehicle", rms=2.0), {}, -5.0)  # as discovery starts a term
    assert (p.name, p.start, p.lower, p.upper, p.step) == ("vehicle.corr_acc_v", -1.0, -1.0, 1.0, 1e-3)
    assert "yaw" not in {t.channel for t in correction.searched_terms()}
    assert len(correction.TERMS) == 38


def test_filtered_rate_of_a_piecewise_constant_command():
    """correction.filtered_rate against a fine integration of dw/dt = (u − w)/τ_f, with a delayed look-up."""
    from dse_runner.cases.robotti_diagnosis import correction

    t_cmd, u = np.array([0.0, 0.05, 0.3, 1.0]), np.array([0.1, 0.4, -0.2, 0.0])
    t = np.linspace(-0.2, 2.0, 221)
    w, rate = correction.filtered_rate(t_cmd, u, t)
    fine = np.arange(-0.2, 2.0 + 1e-12, 1e-5)
    held = np.where(
        fine < 0, 0.0, u[np.clip(np.searchsorted(t_cmd, fine + 1e-12, side="right") - 1, 0, None)]
    )
    wf = np.zeros_like(fine)
    for i in range(1, len(fine)):  # exact for a constant input over each step
        wf[i] = held[i] + (wf[i - 1] - held[i]) * np.exp(-1e-5 / correction.TAU_F)
    assert np.abs(w - np.interp(t, fine, wf)).max() < 1e-4
    assert np.all(w[t < 0] == 0.0) and np.all(rate[t < 0] == 0.0)
    assert rate[np.searchsorted(t, 0.5)] == pytest.approx(
        (-0.2 - w[np.searchsorted(t, 0.5)]) / correction.TAU_F
    )
    assert correction.distance(np.array([0.0, 1.0, 2.0]), np.array([1.0, -1.0, 3.0])).tolist() == [
        0.0,
        1.0,
        3.0,
    ]
