"""The noise floor on the kinds of data real recordings hold: white, coloured, quantised, saturated and
noise-free; and the whiteness test that says when a residual is not the noise."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest
from conftest import REPO

from dse_runner.analysis.diagnose.noise import estimate_noise, flat_extremes, quantum_of, whiteness

RNG = np.random.default_rng(20261128)
N = 2000
T = np.arange(N) * 0.05
SMOOTH = 0.3 * np.sin(2 * np.pi * 0.05 * T) + 0.1 * np.sin(
    2 * np.pi * 0.13 * T + 1.0
)  # slow at the sampling step


def ar1(rho: float, sigma: float, n: int = N) -> np.ndarray:
    """AR(1) noise of stationary σ ``sigma`` and lag-1 correlation ``rho``: benchmarks/coloured_noise.py's."""
    spec = importlib.util.spec_from_file_location("coloured_noise", REPO / "benchmarks" / "coloured_noise.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.ar1(RNG, rho, sigma, n)


def test_white_noise_on_a_smooth_signal_reads_its_sigma():
    found = estimate_noise(SMOOTH + RNG.normal(0.0, 0.002, N))
    assert found.sigma == pytest.approx(0.002, rel=0.1) and found.method == "differences"
    assert "white" in found.assumptions


def test_a_quantised_recording_keeps_a_floor_at_its_resolution():
    """A smooth signal rounded to 1 mm, with 0.1 mm of noise under it: the differences see almost nothing
    (most are 0), but an error below the rounding cannot be seen either: the floor is step/√12."""
    rounded = np.round((SMOOTH + RNG.normal(0.0, 0.0001, N)) / 0.001) * 0.001
    found = estimate_noise(rounded)
    assert quantum_of(rounded) == pytest.approx(0.001)
    assert found.sigma >= 0.001 / math.sqrt(12) * 0.999 and found.sigma < 0.0004
    assert "step 0.001" in found.assumptions


def test_a_noise_free_recording_has_the_floor_of_the_decimals_it_was_written_with():
    """Simulated data written with 6 decimals: not 1e-8, which would count
    every error as millions of floors."""
    written = np.round(SMOOTH, 6)
    found = estimate_noise(written)
    assert found.method == "resolution" and found.sigma == pytest.approx(1e-6 / math.sqrt(12))
    assert quantum_of(np.array([5.205, 5.2154, 5.2215])) == pytest.approx(1e-4)  # the decimals written


def test_flat_stretches_at_a_saturated_extreme_are_left_out():
    """A sensor stuck at its top for a quarter of the record: those zero differences are not the noise."""
    values = SMOOTH * 10 + RNG.normal(0.0, 0.01, N)
    top = np.quantile(values, 0.75)
    clipped = np.minimum(values, top)
    assert flat_extremes(clipped).sum() >= 0.2 * N
    found = estimate_noise(clipped)
    assert found.flat >= 0.2 * N and found.sigma == pytest.approx(0.01, rel=0.15)
    assert "saturated" in found.assumptions


def test_coloured_noise_reads_low_and_says_so_and_whiteness_catches_it():
    """AR(1) with ρ = 0.9: the differences see only its fast part (about √(1 − ρ) of σ). No estimate from the
    recording alone can tell slow noise from signal; the estimate says it assumes white noise, and the
    residuals' whiteness test is what flags it."""
    coloured = ar1(0.9, 0.002)
    found = estimate_noise(SMOOTH + coloured)
    assert found.sigma < 0.6 * 0.002 and "coloured" in found.assumptions
    verdict = whiteness([coloured[: N // 2], coloured[N // 2 :]])
    assert not verdict.white and verdict.rho1 == pytest.approx(0.9, abs=0.05)
    assert whiteness([RNG.normal(0.0, 1.0, N // 2), RNG.normal(0.0, 1.0, N // 2)]).white


def test_the_cascaded_tanks_recording_has_a_floor_and_says_what_it_assumes():
    """The real recording: written with 4 decimals, flat at 10 V where the level sensor saturates."""
    from dse_runner.simulation.scenario import read_recording

    recording = read_recording(REPO / "jobs" / "cascaded_tanks" / "estimation" / "level.csv")
    found = estimate_noise(recording.samples("y")[1])
    assert found.flat > 0 and found.quantum == pytest.approx(1e-4)
    assert 0.001 < found.sigma < 0.1  # a few mV to tens of mV: about 40 dB below the signal's span of 7 V
    assert found.to_json()["assumptions"] == found.assumptions
