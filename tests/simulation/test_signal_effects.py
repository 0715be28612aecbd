"""Signal effects (delay, lag, gain, offset) do what their names promise, and nothing at their neutral values."""

from __future__ import annotations

import numpy as np
import pytest

from dse_runner.simulation.scenario import Series
from dse_runner.simulation.signal_effects import NEUTRAL, apply, first_order_lag, on_output

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
    chord = (omega * 0.001) ** 2 / 8  # the input is linear between its samples, a sine bows off the chord by this
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
    values = t ** 2
    late = on_output(t, values, "delay", 0.2)
    assert late[0] == 0.0 and np.allclose(late[t >= 0.2], (t[t >= 0.2] - 0.2) ** 2, atol=1e-4)
