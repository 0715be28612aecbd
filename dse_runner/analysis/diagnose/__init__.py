"""Discrepancy diagnosis for any model with recordings: locate where simulation and recordings part,
name what is missing from a hypothesis library, model it and show the held-out fit improve.

The core reads in this order: ``library`` (the plug-in contract and :func:`diagnose`, which finds
the library that serves a space), ``hypotheses`` (what a hypothesis is), ``explain`` (how candidates
are judged: folds, BIC, the noise floor, the verdict), ``noise`` (noise from a recording alone) and
``findings`` (what is named). The built-in library is ``signal_library`` (late, sluggish, scaled or
biased inputs and outputs of any FMU, limits of its states, and physical terms inside its model-exchange
FMUs: ``signal_hypotheses`` and ``term_hypotheses``), with its steps ``signal_screen``, ``signal_claims``,
``signal_locate`` and ``signal_report``; ``derivative_discovery`` holds the earlier linearised proposal of
terms, whose regression the Robotti's discovery borrows. Cases add their libraries by entry point, as the
Robotti does (dse_runner/cases/robotti_diagnosis).
"""

from .hypotheses import EffectParameter, Hypothesis
from .library import HypothesisLibrary, Request, Result, diagnose, libraries, serving, space_with

__all__ = [
    "EffectParameter",
    "Hypothesis",
    "HypothesisLibrary",
    "Request",
    "Result",
    "diagnose",
    "libraries",
    "serving",
    "space_with",
]
