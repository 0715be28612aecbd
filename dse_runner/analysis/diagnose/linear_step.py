"""The bounded least-squares step of a linearisation: how far parameters move, each within its bounds, to
cancel residuals as their Jacobian predicts, and the SSE that predicts.

Why one function: the linearised screen (screens/linearised.py: a set of effects, the calibrated parameters
refitted with it) and discovery's ranking of proposed terms (term_ranking.py: a set of terms, the parent's
parameters refitted with them) ask a Jacobian the same question, without simulating: the least SSE of
r + J·x with lower ≤ x ≤ upper (scipy's lsq_linear). Each column is solved multiplied by its ``scale``, so
that parameters of any units (millimetres of antenna, hundreds of kilograms) weigh alike.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear


def bounded_step(
    jacobian: np.ndarray,
    residuals: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    scale: np.ndarray,
    method: str = "bvls",
) -> tuple[np.ndarray, float]:
    """The step x, ``lower`` ≤ x ≤ ``upper`` (in the parameters' units), that minimises the SSE of
    ``residuals`` + ``jacobian``·x, and that SSE. ``method``: lsq_linear's (bounded-variable least squares
    is exact; "trf" iterates, interior to the bounds)."""
    solved = lsq_linear(jacobian * scale, -residuals, bounds=(lower / scale, upper / scale), method=method)
    step = solved.x * scale
    predicted = residuals + jacobian @ step
    return step, float(predicted @ predicted)
