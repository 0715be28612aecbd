"""Noise in a recording, estimated from the recording alone.

Why: a diagnosis that compares held-out error with zero can never tell "explained" from "explained down
to the sensor's noise". Estimating the noise from the recorded samples, never from a model, keeps the
floor out of reach of what is being judged.
"""

from __future__ import annotations

import math

import numpy as np

MAD_TO_SIGMA = 1.4826  # the median absolute deviation of a Gaussian is 0.6745 σ


def sigma_from_differences(d: np.ndarray, order: int) -> float:
    """σ of white noise from its ``order``-th differences: robust MAD, divided by √C(2·order, order) (var of
    the k-th difference of white noise is C(2k, k) σ²)."""
    if d.size == 0:
        return math.nan
    return float(MAD_TO_SIGMA * np.median(np.abs(d - np.median(d))) / math.sqrt(math.comb(2 * order, order)))
