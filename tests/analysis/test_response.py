"""The engine's response fit: a known delay, lag or gain of a model's signal is recovered as that form, with
its size, and fits better than the other forms; the LLR between two forms."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from dse_runner.analysis.diagnose import response
from dse_runner.analysis.diagnose.response import ResponseFit

STEP, STEADY = "step", "steady"


@dataclass(frozen=True)
class Sampled:
    """A recording sampled at its own times, seeing the model's signal as it is there (no window)."""

    time: np.ndarray
    recorded: np.ndarray
    kinds: np.ndarray
    model_time: np.ndarray
    model: np.ndarray
    free_offset: bool = False

    def seen(self, model: np.ndarray) -> np.ndarray:
        return np.interp(self.time, self.model_time, model)


def model() -> tuple[np.ndarray, np.ndarray]:
    """A 20 Hz model signal: up 1 at 2 s, up another 0.5 at 12 s, down by 1 at 22 s, each held 10 s; each
    step a ramp of half a second, so that a delay between two samples still moves the samples."""
    t = np.round(np.arange(0.0, 32.0 + 1e-9, 0.05), 2)
    ramp = lambda at: np.clip((t - at) / 0.5, 0.0, 1.0)  # noqa: E731
    return t, 1.0 + 1.0 * ramp(2.0) + 0.5 * ramp(12.0) - 1.0 * ramp(22.0)


def channel(truth, seed: int = 1, offset: float = 0.0, free_offset: bool = False, noise: float = 0.003):
    """The model's signal through ``truth`` (time, signal -> recorded), sampled at 10 Hz with a few samples
    missing, plus noise; samples within 4 s after a step are ``step``, the rest ``steady``."""
    t, u = model()
    rng = np.random.default_rng(seed)
    times = np.round(np.arange(0.0, 32.0, 0.1), 2)
    times = times[rng.random(times.size) >= 0.05]
    recorded = np.interp(times, t, truth(t, u)) + offset + rng.normal(0, noise, times.size)
    after = np.zeros(times.size, bool)
    for at in (2.0, 12.0, 22.0):
        after |= (times >= at) & (times < at + 4.0)
    kinds = np.where(after, STEP, STEADY).astype(object)
    return Sampled(times, recorded, kinds, t, u, free_offset)


def fits(c: Sampled, kinds=(STEP, STEADY)) -> dict[str, ResponseFit]:
    return {r.kind: r for r in response.response_fit([c], "signal", kinds)}


def test_a_delay_is_recovered_as_a_delay_of_its_size_and_fits_better_than_a_lag():
    step = fits(channel(lambda t, u: response.delayed(t, u, 0.4)))[STEP]
    assert step.best == "delay"
    assert step.delay == pytest.approx(0.4, abs=0.02)
    assert step.delay_sse < 0.5 * min(step.lag_sse, step.gain_sse) and step.delay_sse < 0.05 * step.sse
    assert step.samples == int(np.sum(channel(lambda t, u: u).kinds == STEP))


def test_a_first_order_lag_is_recovered_as_a_lag_of_its_time_constant():
    step = fits(channel(lambda t, u: response.lagged(t, u, 0.6)))[STEP]
    assert step.best == "lag"
    assert step.lag == pytest.approx(0.6, abs=0.03)
    assert step.lag_sse < 0.5 * min(step.delay_sse, step.gain_sse)


def test_a_gain_is_recovered_everywhere_and_a_phase_leaves_the_steady_state_at_gain_one():
    scaled = fits(channel(lambda t, u: 0.8 * u))
    assert scaled[STEP].best == scaled[STEADY].best == "gain"
    assert scaled[STEADY].gain == pytest.approx(0.8, abs=0.005)
    late = fits(channel(lambda t, u: response.lagged(t, u, 0.6)))
    assert late[STEADY].gain == pytest.approx(1.0, abs=0.02)  # settled: a phase, no attenuation


def test_a_recording_the_model_already_matches_needs_no_form():
    assert {r.best for r in fits(channel(lambda t, u: u)).values()} == {"none"}


def test_a_signal_known_up_to_a_constant_is_compared_about_its_mean_difference():
    shifted = channel(lambda t, u: response.delayed(t, u, 0.4), offset=3.0, free_offset=True)
    step = fits(shifted)[STEP]
    assert step.best == "delay" and step.delay == pytest.approx(0.4, abs=0.02)
    assert fits(channel(lambda t, u: response.delayed(t, u, 0.4), offset=3.0))[STEP].best == "gain"


def test_samples_the_recording_cannot_see_do_not_count_and_rare_kinds_are_left_out():
    c = channel(lambda t, u: response.delayed(t, u, 0.4))
    blind = Sampled(c.time, np.where(c.time < 16.0, c.recorded, np.nan), c.kinds, c.model_time, c.model)
    step = fits(blind)[STEP]
    assert step.samples == int(np.sum((c.kinds == STEP) & (c.time < 16.0)))
    assert step.delay == pytest.approx(0.4, abs=0.02)
    assert fits(c, kinds=(STEP, STEADY, "absent")).keys() == {STEP, STEADY}
    few = Sampled(c.time, np.where(c.time < 3.0, c.recorded, np.nan), c.kinds, c.model_time, c.model)
    assert STEP not in fits(few)  # under 20 usable samples of a step


def test_delayed_holds_the_first_value_and_lagged_starts_settled():
    t, u = model()
    late = response.delayed(t, u, 0.5)
    assert late[0] == 1.0 and late[t == 2.5][0] == 1.0 and late[t == 3.0][0] == 2.0
    assert late[t == 22.75][0] == pytest.approx(u[t == 22.25][0])
    slow = response.lagged(t, u, 1.0)
    assert slow[0] == pytest.approx(1.0) and slow[t == 1.95][0] == pytest.approx(1.0)
    assert 1.0 < slow[t == 3.0][0] < 2.0 - np.exp(-1.0)  # a ramp is slower than a step: under 63 % after τ
    assert slow[t == 11.95][0] == pytest.approx(2.0, abs=1e-3)  # settled


def fit(delay_sse: float, lag_sse: float, gain_sse: float = 9.0, samples: int = 100) -> ResponseFit:
    return ResponseFit("signal", STEP, samples, 10.0, 0.4, delay_sse, 0.5, lag_sse, 1.0, gain_sse)


def test_the_llr_between_two_forms_favours_the_smaller_sse_in_units_of_its_own_scatter():
    assert response.form_llr(fit(1.0, 2.0), "delay", "lag") == pytest.approx((2.0 - 1.0) / (2 * 1.0 / 100))
    assert response.form_llr(fit(1.0, 2.0), "lag", "delay") == pytest.approx(-50.0)
    assert response.form_llr(fit(1.0, 2.0, samples=400), "delay", "lag") == pytest.approx(200.0)
    assert response.form_llr(fit(0.0, 2.0), "delay", "lag") == 0.0  # no scatter to scale by


def test_a_fit_in_json_names_its_samples_as_the_library_calls_them():
    saved = fit(1.0, 2.0).to_json("fixes")
    assert saved["fixes"] == 100 and "samples" not in saved
    assert saved["best"] == "delay" and saved["segment"] == STEP
    assert fit(9.6, 9.7, 9.8).best == "none"  # within 5 % of the model as it is
