"""Signal effects (delay, lag, gain, offset) do what their names promise, and
nothing at their neutral values."""

from __future__ import annotations

import numpy as np
import pytest

from dse_runner.errors import DseError
from dse_runner.simulation.objectives import Reduce
from dse_runner.simulation.run import simulate
from dse_runner.simulation.scenario import Scenario
from dse_runner.simulation.signal_effects import EFFECTS, NEUTRAL, apply, first_order_lag, on_output, parse
from dse_runner.simulation.trajectory import Series

RNG = np.random.default_rng(7)
TIMES = np.cumsum(RNG.uniform(0.005, 0.03, 400))  # uneven, as recordings are


@pytest.mark.parametrize("kind", sorted(NEUTRAL))
def test_an_effect_at_its_neutral_value_changes_nothing_bit_for_bit(kind):
    series = Series(TIMES, np.sin(TIMES) + RNG.normal(0, 0.1, TIMES.size), "hold")
    t = np.linspace(-1, TIMES[-1] + 1, 777)
    assert np.array_equal(apply(series, kind, NEUTRAL[kind]).at(t), series.at(t))
    assert np.array_equal(on_output(TIMES, series.values, kind, NEUTRAL[kind]), series.values)


def test_a_lag_follows_a_ramp_as_the_differential_equation_says():
    """u = t from rest: y = t − tau·(1 − exp(−t/tau)), exact at every sample of an uneven grid."""
    tau = 0.4
    t = TIMES - TIMES[0]
    y = first_order_lag(t, t.copy(), tau)
    assert np.allclose(y, t - tau * (1 - np.exp(-t / tau)), rtol=0, atol=1e-12)


def test_a_lagged_sine_has_the_gain_and_phase_of_a_first_order_filter():
    tau, omega = 0.25, 2 * np.pi * 0.8
    t = np.arange(0, 30, 0.001)
    y = apply(Series(t, np.sin(omega * t)), "lag", tau).at(t)
    steady = t > 20 * tau  # the start-up transient (from rest) has died away: exp(-20)
    expected = np.sin(omega * t - np.arctan(omega * tau)) / np.hypot(1, omega * tau)
    chord = (
        omega * 0.001
    ) ** 2 / 8  # the input is linear between its samples, a sine bows off the chord by this
    assert np.max(np.abs(y[steady] - expected[steady])) < chord


def test_a_delay_shifts_the_signal_and_holds_its_first_value_before_it_starts():
    series = Series(np.array([0.0, 1.0, 2.0]), np.array([5.0, 7.0, 9.0]), "hold")
    late = apply(series, "delay", 0.5)
    assert late.at(np.array([0.0, 0.4, 0.5, 1.4, 1.5, 9.0])).tolist() == [5.0, 5.0, 5.0, 5.0, 7.0, 9.0]


def test_gain_and_offset_compose_in_the_order_applied():
    series = Series(TIMES, np.cos(TIMES))
    both = apply(apply(series, "gain", 2.0), "offset", -1.0)
    assert np.allclose(both.at(TIMES), 2.0 * np.cos(TIMES) - 1.0, rtol=0, atol=1e-15)


def test_an_output_effect_is_the_sensor_view_at_the_simulation_times():
    t = np.linspace(0, 5, 501)
    values = t**2
    late = on_output(t, values, "delay", 0.2)
    assert late[0] == 0.0 and np.allclose(late[t >= 0.2], (t[t >= 0.2] - 0.2) ** 2, atol=1e-4)


# ---- as parameters of a run: simulate() applies them ---------------------------------------------


def _pushed(delay: float = 0.0) -> Scenario:
    """The mass-spring-damper at rest, pushed by a force switched on at 1 s (later by ``delay``)."""
    t = np.array([0.0, 1.0 + delay, 6.0])
    return Scenario(
        "push", inputs={"msd.F": Series(t, np.array([0.0, 2.0, 2.0]), "hold")}, stop_time=6.0, step=0.01
    )


def test_an_input_delay_is_the_same_run_as_a_recording_that_late():
    from conftest import REPO

    model = REPO / "jobs" / "msd" / "multimodel.yaml"
    values = {"msd.x0": 0.0}
    late = simulate(model, _pushed(), {**values, "input_delay(msd.F)": 0.37})
    shifted = simulate(model, _pushed(0.37), values)
    on_time = simulate(model, _pushed(), values)
    assert np.allclose(late.outputs["msd.x"], shifted.outputs["msd.x"], rtol=0, atol=1e-12)
    assert not np.allclose(late.outputs["msd.x"], on_time.outputs["msd.x"], rtol=0, atol=1e-6)
    assert late.values["input_delay(msd.F)"] == 0.37


def test_an_output_effect_changes_what_the_objectives_compare_not_the_model():
    from conftest import REPO

    model = REPO / "jobs" / "msd" / "multimodel.yaml"
    objectives = {
        "x_end": Reduce(signal="msd.x", reduce="final"),
        "v_end": Reduce(signal="msd.v", reduce="final"),
    }
    plain = simulate(model, _pushed(), {"msd.x0": 0.0}, objectives=objectives)
    biased = simulate(
        model,
        _pushed(),
        {"msd.x0": 0.0, "output_offset(msd.x)": 0.05, "output_gain(msd.x)": 2.0},
        objectives=objectives,
    )
    assert biased.objectives["x_end"] == pytest.approx(2.0 * plain.objectives["x_end"] + 0.05, abs=1e-12)
    assert biased.objectives["v_end"] == plain.objectives["v_end"]  # the model itself ran alike


def test_an_input_effect_on_a_signal_no_scenario_drives_is_named():
    from conftest import REPO

    with pytest.raises(DseError, match=r"input_lag\(msd\.m\): msd\.m is not an input the scenario drives"):
        simulate(REPO / "jobs" / "msd" / "multimodel.yaml", _pushed(), {"input_lag(msd.m)": 0.1})
    with pytest.raises(DseError, match=r"input_delay\(msd\.F\): a delay cannot be negative"):
        simulate(REPO / "jobs" / "msd" / "multimodel.yaml", _pushed(), {"input_delay(msd.F)": -0.1})


def test_effect_names_parse_back_to_what_they_say():
    effect = parse("output_lag(tank.level)")
    assert (effect.side, effect.kind, effect.target, effect.id) == (
        "output",
        "lag",
        "tank.level",
        "output_lag",
    )
    assert parse("tank.level") is None and parse("input_speed(tank.level)") is None
    assert {parse(f"{e}(a.b)").name for e in EFFECTS} == {f"{e}(a.b)" for e in EFFECTS}


def test_saturation_dead_zone_and_square_map_each_value():
    t = np.arange(6.0)
    series = Series(t, np.array([-3.0, -0.5, 0.0, 0.4, 2.0, 5.0]), "hold")
    assert apply(series, "max", 1.5).at(t).tolist() == [-3.0, -0.5, 0.0, 0.4, 1.5, 1.5]
    assert apply(series, "min", -1.0).at(t).tolist() == [-1.0, -0.5, 0.0, 0.4, 2.0, 5.0]
    assert apply(series, "deadzone", 1.0).at(t).tolist() == [-2.0, 0.0, 0.0, 0.0, 1.0, 4.0]
    assert np.allclose(
        apply(series, "square", 0.5).at(t), [1.5, -0.375, 0.0, 0.48, 4.0, 17.5], rtol=0, atol=1e-15
    )


def test_backlash_follows_only_past_its_play_and_a_rate_limit_only_so_fast():
    t = np.arange(8.0)
    u = np.array([0.0, 0.3, 1.0, 2.0, 1.8, 1.2, 0.5, 0.5])
    # play 1: the output waits until the input is half of it away, then is dragged half of it behind
    assert np.allclose(
        apply(Series(t, u, "hold"), "backlash", 1.0).at(t), [0.0, 0.0, 0.5, 1.5, 1.5, 1.5, 1.0, 1.0]
    )
    steps = Series(t, np.array([0.0, 3.0, 3.0, 3.0, -1.0, -1.0, -1.0, -1.0]), "hold")
    assert np.allclose(apply(steps, "rate", 1.5).at(t), [0.0, 1.5, 3.0, 3.0, 1.5, 0.0, -1.0, -1.0])


def test_hard_effects_refuse_negative_sizes_and_keep_their_neutral_out():
    from dse_runner.simulation.signal_effects import split

    with pytest.raises(DseError, match=r"input_deadzone\(msd.F\): a deadzone cannot be negative"):
        split({"input_deadzone(msd.F)": -0.1})
    with pytest.raises(DseError, match=r"an effect is a finite number, not -inf"):
        split({"output_max(msd.x)": -np.inf})
    assert split({"output_max(msd.x)": np.inf, "input_rate(msd.F)": np.inf, "msd.k": 2.0}) == (
        {"msd.k": 2.0},
        {},
    )
