"""Discrepancy diagnosis for any model with recordings: locate where simulation and recordings part,
name what is missing from a hypothesis library, model it and show the held-out fit improve.

The core reads in this order: ``library`` (the plug-in contract and :func:`diagnose`, which finds
the library that serves a space), ``hypotheses`` (what a hypothesis is), ``validation`` (what is held out),
``fitter`` and ``engine`` (the fits and the stages every library runs), ``screens`` (the combination
screen, a strategy chosen by name), ``explain`` (how candidates are judged: BIC, the noise floor, the
verdict), ``lookalike`` (which answers are twins, the evidence between them and the rule by which it
decides), ``response`` (a response's form: a delay, a lag or a gain, which tells twins apart), ``proof``
(searched terms chosen again on each fold), ``discovery`` (terms beyond a library: ``term_search`` the
contract a case's search implements, ``term_ranking`` which proposed terms the residuals want first, with
the bounded step of ``linear_step`` the linearised screen uses too),
``noise`` (noise from a recording alone), ``findings`` and ``answer`` (what is named, in the one JSON
shape), ``outcome`` (what a diagnosis found, which every library's result subclasses and which builds that
JSON), ``report`` (the page every diagnosis is read on, drawn from that JSON; a library adds its own
sections) and ``report_html``. The built-in library is ``signal_library`` (late, sluggish, scaled or biased
inputs and outputs of any FMU, limits of its states, and physical terms inside its model-exchange FMUs:
``signal_hypotheses``, ``term_hypotheses`` over ``derivatives``), with its steps
``signal_claims``, ``signal_locate`` and ``signal_report`` (its sections of the report); ``sparse_regression``
is the regression the Robotti's discovery proposes its terms with. Cases add their libraries by entry point,
as the Robotti does (dse_runner/cases/robotti_diagnosis).
"""

from .hypotheses import EffectParameter, Hypothesis
from .library import (
    HypothesisLibrary,
    Request,
    Result,
    diagnose,
    libraries,
    report_again,
    serving,
    space_with,
)
from .outcome import Outcome
from .report import Section

__all__ = [
    "EffectParameter",
    "Hypothesis",
    "HypothesisLibrary",
    "Outcome",
    "Request",
    "Result",
    "Section",
    "diagnose",
    "libraries",
    "report_again",
    "serving",
    "space_with",
]
