"""The sparse regression a library's term proposer runs: PySINDy's sequentially thresholded least squares
(STLSQ), its threshold chosen by leave-one-run-out error, and the pruning of fitted terms.

Why here: choosing few terms among many from noisy rows is statistics, not a case's physics; the Robotti's
discovery proposes its correction block's terms with it (cases/robotti_diagnosis/discover/propose.py).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence

import numpy as np

from ...sweeps.fit import FitResult

THRESHOLDS = (0.02, 0.05, 0.1, 0.2, 0.35, 0.5)  # STLSQ thresholds tried, as shares of the target's RMS
RIDGE = 0.05  # STLSQ's ridge weight per row on unit-RMS columns: keeps look-alike columns from cancelling
TIE = 1.02  # thresholds within this factor of the least held-out error tie; the largest (sparsest) wins
PRUNE_SE = 2.0  # a fitted term within this many standard errors of zero is dropped


def stlsq(theta: np.ndarray, y: np.ndarray, threshold: float, unbias: bool = True) -> np.ndarray:
    """PySINDy's sequentially thresholded least squares, one coefficient per column; ``unbias``: refit the
    kept columns without the ridge (PySINDy's default), or keep the ridge's shrinkage."""
    import pysindy as ps
    import sklearn

    if len(y) == 0:
        return np.zeros(theta.shape[1])
    optimizer = ps.STLSQ(
        threshold=threshold, alpha=RIDGE * len(y), max_iter=20, normalize_columns=False, unbias=unbias
    )
    # sklearn checks the options of every fit (STLSQ's, ridge_regression's); ours are fixed and valid, and in
    # the test suite's blind diagnoses the check took 5.0 of STLSQ's 11.2 CPU s (docs/performance.md)
    with warnings.catch_warnings(), sklearn.config_context(skip_parameter_validation=True):
        warnings.filterwarnings(
            "ignore", category=UserWarning
        )  # "eliminated all coefficients" is an answer here
        optimizer.fit(theta, y)
    return np.asarray(optimizer.coef_, float).reshape(-1)


def held_out_error(
    z: np.ndarray,
    y: np.ndarray,
    run: np.ndarray,
    threshold: float,
    solve: Callable[[np.ndarray, np.ndarray, float], np.ndarray] = stlsq,
) -> float:
    """Leave-one-scenario-out squared error of a sparse regression (``solve``, STLSQ as set up here unless a
    caller brings its own) at ``threshold`` (inf threshold: the empty model)."""
    total = 0.0
    for k in np.unique(run):
        out = run == k
        coef = np.zeros(z.shape[1]) if math.isinf(threshold) else solve(z[~out], y[~out], threshold)
        total += float(np.sum((y[out] - z[out] @ coef) ** 2))
    return total


def choose_threshold(
    z: np.ndarray,
    y: np.ndarray,
    run: np.ndarray,
    solve: Callable[[np.ndarray, np.ndarray, float], np.ndarray] = stlsq,
) -> float:
    """The threshold of THRESHOLDS (shares of the target's RMS) of least leave-one-run-out error (the largest
    of those that tie with it), or inf when none predicts held-out runs better than no term at all.
    ``solve``: the sparse regression (STLSQ as set up here unless a caller, such as the Robotti's
    discovery, brings its own)."""
    size = float(np.sqrt(np.mean(y**2))) if len(y) else 0.0
    if size == 0.0 or len(np.unique(run)) < 2:
        return math.inf
    errors = {share * size: held_out_error(z, y, run, share * size, solve) for share in THRESHOLDS}
    best = min(errors.values())
    if best >= float(np.sum(y**2)):
        return math.inf
    return max(th for th, e in errors.items() if e <= TIE * best)


def pruned(result: FitResult, names: Sequence[str], factor: float = PRUNE_SE) -> list[str]:
    """Of ``names`` (fitted terms), those at least ``factor`` cluster-robust standard errors from zero."""
    kept = []
    for name in names:
        se = result.standard_error.get(name, math.inf)
        if result.values[name] != 0.0 and math.isfinite(se) and abs(result.values[name]) >= factor * se:
            kept.append(name)
    return kept
