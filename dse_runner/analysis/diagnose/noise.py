"""Noise in a recording, estimated from the recording alone.

Why: a diagnosis that compares held-out error with zero can never tell "explained" from "explained down
to the sensor's noise". Estimating the noise from the recorded samples, never from a model, keeps the
floor out of reach of what is being judged.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

MAD_TO_SIGMA = 1.4826  # the median absolute deviation of a Gaussian is 0.6745 σ


def sigma_from_differences(d: np.ndarray, order: int) -> float:
    """σ of white noise from its ``order``-th differences: robust MAD, divided by √C(2·order, order) (var of
    the k-th difference of white noise is C(2k, k) σ²)."""
    if d.size == 0:
        return math.nan
    return float(MAD_TO_SIGMA * np.median(np.abs(d - np.median(d))) / math.sqrt(math.comb(2 * order, order)))


# ---- a recording's noise, with what the estimate assumes ---------------------------------------------------

ORDERS = (
    2,
    3,
    4,
    5,
    6,
)  # differences of these orders; the smallest estimate is the least swollen by the signal
FLAT = 3  # a value repeated at the record's extreme this many times in a row is a flat (saturated) stretch
DECIMALS = 12  # a recording written with more decimals than this is read as unrounded


@dataclass(frozen=True)
class NoiseEstimate:
    """σ of a recording's noise and how it was found: the floor every error is counted in."""

    sigma: float  # the floor: the largest of the estimate from differences and the resolution's
    differences: float  # σ from the k-th differences (white noise assumed), saturated stretches left out
    quantum: float  # the recording's step: its values are whole multiples of it (0: none found)
    flat: int  # samples left out as flat stretches at the record's extremes
    samples: int

    @property
    def method(self) -> str:
        if self.quantum > 0 and self.sigma == self.quantum / math.sqrt(12.0):
            return "resolution"
        return "differences"

    @property
    def assumptions(self) -> str:
        """What a user must know to trust the floor, in one sentence."""
        said = (
            "the noise is white (independent from sample to sample) and the signal smooth at the sampling "
            "step; noise correlated over several samples (coloured) is counted as signal, so the floor "
            "reads low: the residuals' whiteness tells"
        )
        if self.method == "resolution":
            said = (
                f"no noise above the recording's resolution was found, so the floor is the rounding to its "
                f"step {self.quantum:.3g} (σ = step/√12)"
            )
        elif self.quantum > 0:
            said += f"; the floor is at least the rounding to the recording's step {self.quantum:.3g}"
        if self.flat:
            said += f"; {self.flat} samples flat at the record's extremes (saturated) were left out"
        return said

    def to_json(self) -> dict[str, Any]:
        return {
            "sigma": self.sigma,
            "method": self.method,
            "differences": self.differences,
            "quantum": self.quantum,
            "flat": self.flat,
            "samples": self.samples,
            "assumptions": self.assumptions,
        }


def quantum_of(values: np.ndarray) -> float:
    """The step a recording's values are whole multiples of (an ADC's, or the decimals it was written with):
    the greatest common divisor of the differences between its distinct values, read at the fewest
    decimals that write every value exactly. 0 when it has more than DECIMALS decimals (unrounded)."""
    distinct = np.unique(values[np.isfinite(values)])
    if distinct.size < 2:
        return 0.0
    for decimals in range(DECIMALS + 1):
        scaled = distinct * 10.0**decimals
        if np.all(np.abs(scaled - np.round(scaled)) <= 1e-9 * np.maximum(1.0, np.abs(scaled))):
            steps = np.diff(np.round(scaled)).astype(np.int64)
            return float(np.gcd.reduce(steps[steps > 0])) / 10.0**decimals
    return 0.0


def flat_extremes(values: np.ndarray, run: int = FLAT) -> np.ndarray:
    """Samples in stretches of at least ``run`` equal values at the record's maximum or minimum: a sensor
    or an actuator at its limit, whose zero differences are not an absence of noise."""
    flat = np.zeros(values.size, dtype=bool)
    for extreme in (np.max(values), np.min(values)):
        at = values == extreme
        edges = np.flatnonzero(np.diff(np.concatenate(([0], at.astype(np.int8), [0]))))
        for start, stop in zip(edges[::2], edges[1::2]):
            if stop - start >= run:
                flat[start:stop] = True
    return flat


def estimate_noise(values: np.ndarray, orders: Sequence[int] = ORDERS) -> NoiseEstimate:
    """σ of a recording's noise from its samples alone. The k-th differences of white noise have σ·√C(2k, k),
    measured robustly (MAD); the signal adds to every order, less at higher ones while it is smooth at the
    sampling step, so the smallest estimate is taken. Differences that touch a flat stretch at the record's
    extremes are left out (a saturated sensor is not noise-free). The floor is never below the rounding to the
    recording's own step (σ = step/√12), so a quantised or noise-free record does not make every error
    count as thousands of floors."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    flat = flat_extremes(v) if v.size else np.zeros(0, dtype=bool)
    estimates = []
    for k in orders:
        if v.size <= k + 2:
            continue
        touched = (
            np.convolve(flat.astype(float), np.ones(k + 1), mode="valid") > 0
        )  # a difference's k+1 samples
        d = np.diff(v, n=k)[~touched]
        if d.size > 2:
            estimates.append(sigma_from_differences(d, k))
    differences = min(estimates) if estimates else math.nan
    quantum = quantum_of(v)
    floor = quantum / math.sqrt(12.0)
    sigma = max(differences, floor) if math.isfinite(differences) else (floor or math.nan)
    return NoiseEstimate(sigma, differences, quantum, int(flat.sum()), int(v.size))


# ---- whether residuals are white ---------------------------------------------------------------------------

WHITE_LAGS = 10  # the Ljung-Box test's lags
WHITE_P = 0.001  # residuals whose Ljung-Box p-value is below this are not white


@dataclass(frozen=True)
class Whiteness:
    """Whether residuals look like independent noise: their lag-1 autocorrelation and the Ljung-Box test over
    WHITE_LAGS lags, pooled over runs."""

    rho1: float
    q: float
    p: float
    lags: int
    samples: int

    @property
    def white(self) -> bool:
        return not self.p < WHITE_P

    def to_json(self) -> dict[str, Any]:
        return {
            "rho1": self.rho1,
            "ljung_box_q": self.q,
            "p": self.p,
            "lags": self.lags,
            "samples": self.samples,
            "white": self.white,
            "rule": f"white unless Ljung-Box p < {WHITE_P:g}",
        }


def whiteness(runs: Sequence[np.ndarray], lags: int = WHITE_LAGS) -> Whiteness:
    """Ljung-Box Q = n(n+2) Σ ρ_k²/(n−k) over lags 1..``lags``, each run's autocorrelations weighted by its
    length; the p-value from χ² with ``lags`` degrees of freedom (scipy.stats)."""
    from scipy.stats import chi2

    rhos, weights = np.zeros(lags), 0
    for r in runs:
        r = np.asarray(r, dtype=float)
        r = r[np.isfinite(r)]
        if r.size <= lags + 2:
            continue
        c = r - r.mean()
        denominator = float(c @ c)
        if denominator <= 0:
            continue
        rhos += r.size * np.array([float(c[:-k] @ c[k:]) / denominator for k in range(1, lags + 1)])
        weights += r.size
    if not weights:
        return Whiteness(math.nan, math.nan, math.nan, lags, 0)
    rho = rhos / weights
    n = weights
    q = float(n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, lags + 1))))
    return Whiteness(float(rho[0]), q, float(chi2.sf(q, lags)), lags, int(n))
