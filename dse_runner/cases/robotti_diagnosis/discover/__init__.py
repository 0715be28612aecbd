"""Discover: a sparse correction for what no effect of the library explains, proposed from
the GPS and proven by the fits.

When the chosen library set R (possibly ``none``) leaves held-out error well above the noise floor, the
missing physics is sought among the correction block's terms (correction.py), in three stages
(docs/research/diagnosis-beyond-library.md, §4):

1. **Propose** (no simulation). The recorded state comes from the fixes alone (kinematics.py): speed,
   course, yaw rate and acceleration. At that state the calibrated reference R says what the vehicle
   should do; the difference is the *equation error* of each channel, the standard SINDy target for
   residual dynamics: for ``acc`` in speed (the drive's stiff speed loop turns an added acceleration into
   a speed change), for ``steer`` in yaw rate (steering enters it through the steady-state gain
   G(v) = −v / (L + K_us·v²); the yaw mode settles in hundredths of a second at these speeds). The features
   are taken at R's state, and every model-side signal is seen through the same local-polynomial window
   as the fixes, so neither side is sharper. The antenna's channels (``gps_along``, ``gps_cross``) are
   outputs, not dynamics, so equation error cannot see them: their target is R's fix residuals turned
   into the vehicle's axes (one sweep of points the fits mostly simulated already), where a term's
   column is its feature itself. PySINDy's sequentially thresholded least squares (STLSQ) picks the few
   terms that explain each channel; the threshold comes from leave-one-run-out error, and a term is kept
   only if it is picked in most of a seeded bootstrap over *runs* (rows within a run are correlated, so
   resampling rows would overstate the evidence). Some terms depend on a *shape* of the block (the time a
   change mid-run sets in, a steering rate limit): each shape is first scanned for the value at which its
   channel's equation error is least (:func:`find_shape`), and its terms are offered only if they then cut
   that channel's leave-one-run-out error by SHAPE_GAIN (:func:`shape_gain`); the fits hold the value.
2. **Rank on positions** (one sweep, the engine's: analysis/diagnose/term_ranking.py). Equation error sees
   the model's own misfit too, so the order it gives mixes channels unfairly (a pair of steering terms can
   outrank the antenna terms they stand in for). The terms every channel supports compete instead on what
   each does to the fix residuals, linearised at the parent fit (one probe per term, as the linearised
   screen does for effects): forward selection, the parent's parameters refitted within their bounds, while
   the predicted BIC falls by the extended margin's share of each term. The search says only which
   parameter a term is and which shapes its probe holds (search.py).
3. **Prove** (the same sweeps as the library). The chosen terms are freed as ``corr_*`` parameters of
   the effects FMU and fitted on positions jointly with the calibrated parameters and R's effects (R + D),
   and without R (D alone). Terms within two standard errors of zero are pruned, their slots refilled in
   the ranked order. Each fold re-does the proposal and the ranking on its training runs only, so the
   held-out error does not leak the choice of terms. D is accepted only if it beats R and every fitted
   part of itself by the library's rule, with the BIC margin raised for the search among many terms
   (extended BIC).

Equation-error coefficients are biased by noise in the recorded state, so they are only starting values:
the fits size the terms on positions.

The stages live in their own modules, in the order data flows: observe, propose, and search, the term
search the engine's discovery runs (analysis/diagnose/discovery.py: the ranking on positions, per-fold
proposals, settling, the proof, acceptance and the resemblance to library effects are the engine's); this
package re-exports what the workflow and the tests use.
"""

from .observe import OUTPUT, ChannelRegression, Observed, observe, vehicle_values
from .propose import (
    INCLUSION,
    MAX_BINDING,
    RATE_LIMITS,
    CorrectionProposal,
    binding,
    candidates,
    find_shape,
    propose,
    regressions,
    searched_count,
)
from .search import CorrectionSearch

__all__ = [
    "INCLUSION",
    "MAX_BINDING",
    "OUTPUT",
    "RATE_LIMITS",
    "ChannelRegression",
    "CorrectionProposal",
    "CorrectionSearch",
    "Observed",
    "binding",
    "candidates",
    "find_shape",
    "observe",
    "propose",
    "regressions",
    "searched_count",
    "vehicle_values",
]
