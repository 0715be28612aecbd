"""The bounded least-squares step of a linearisation: how far parameters move, each within its bounds, to
cancel residuals as their Jacobian predicts, and the SSE that predicts.

Why one function: the linearised screen (screens/linearised.py: a set of effects, the calibrated parameters
refitted with it) and discovery's ranking of proposed terms (term_ranking.py: a set of terms, the parent's
parameters refitted with them) ask a Jacobian the same question, without simulating: the least SSE of
r + J·x with lower ≤ x ≤ upper (scipy's lsq_linear). The columns are solved on one scale, so that
parameters of any units (millimetres, hundreds of kilograms) weigh alike: each column times its
parameter's finite-difference step (what one step does: the screen's), or else at unit norm (the
ranking's). The two agree to rounding; each caller keeps its own so that its answers stay bit for bit.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear


def bounded_step(
    jacobian: np.ndarray,
    residuals: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    steps: np.ndarray | None = None,
    method: str = "bvls",
) -> tuple[np.ndarray, float]:
    """The step x, ``lower`` ≤ x ≤ ``upper`` (in the parameters' units), that minimises the SSE of
    ``residuals`` + ``jacobian``·x, and that SSE; each column solved times its parameter's ``steps``, or at
    unit norm without them. ``method``: lsq_linear's (bounded-variable least squares is exact; "trf"
    iterates, interior to the bounds)."""
    if steps is None:
        norm = np.linalg.norm(jacobian, axis=0)
        norm = np.where(norm > 0, norm, 1.0)
        solved = lsq_linear(jacobian / norm, -residuals, bounds=(lower * norm, upper * norm), method=method)
        step = solved.x / norm
    else:
        scaled = jacobian * steps
        solved = lsq_linear(scaled, -residuals, bounds=(lower / steps, upper / steps), method=method)
        step = solved.x * steps
    predicted = residuals + jacobian @ step
    return step, float(predicted @ predicted)
