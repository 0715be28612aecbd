"""The proof of terms found by searching: one record and one rule for every diagnosis that seeks what its
library lacks, the signal library's terms inside a model and a case's discovered correction alike.

Why: a term picked among many on all the data has already seen the scenarios it is then judged on, so its
held-out error flatters it. Terms are proven only by the procedure that chose them, run again on each
fold's fitting scenarios alone (:class:`Proof`), and the claim is that procedure's held-out error
(:func:`honest`). They must then do clearly better than the answer without them (:meth:`Proof.bears_out`),
pay for the search among all the terms offered in the BIC (:func:`extended_margin`), and face the noise
rule like every other member (explain.claimed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from .explain import MIN_GAIN, search_charge

RULE = "each fold chose its terms among every term offered on its fitting scenarios alone"


@dataclass
class Proof:
    """The answer's terms chosen again on each fold's fitting scenarios, among every term offered: the
    held-out error of the procedure that chose them, not of the choice made on all the data."""

    terms: tuple[str, ...]  # the answer's terms, as chosen on all the data
    chosen: list[tuple[str, ...]] = field(default_factory=list)  # each fold's choice in their place
    held_out: dict[str, float] = field(default_factory=dict)  # scenario -> error of its fold's choice
    offered: int = 0  # how many terms the search chose among

    @property
    def agree(self) -> int:
        """How many folds chose the answer's terms themselves."""
        return sum(1 for c in self.chosen if set(c) == set(self.terms))

    @property
    def error(self) -> float:
        """The mean held-out error of each fold's own choice."""
        return sum(self.held_out.values()) / len(self.held_out) if self.held_out else math.inf

    def bears_out(self, without: float, min_gain: float = MIN_GAIN) -> bool:
        """Whether the folds' own choices predict held-out scenarios clearly better (by ``min_gain``) than
        the answer without the terms does (``without``: its held-out error)."""
        return self.error <= (1.0 - min_gain) * without

    def failed(self, without: float, unit: str = "") -> str:
        """Why the terms go when the proof does not bear them out, for the report."""
        return (
            f"chosen again on each fold's fitting part, the terms predicted held-out scenarios with "
            f"{self.error:.3g}{unit}, not clearly better than {without:.3g}{unit} without them"
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "terms": list(self.terms),
            "offered": self.offered,
            "folds": [list(c) for c in self.chosen],
            "agree": self.agree,
            "held_out": self.error,
            "rule": RULE,
        }


def honest(cross_validated: float, proof: Proof | None) -> float:
    """The held-out error to claim for an answer: its folds' (``cross_validated``), or its proof's when
    that did worse (a choice made on all the data has seen the held-out scenarios)."""
    return cross_validated if proof is None else max(cross_validated, proof.error)


def extended_margin(bic_margin: float, offered: int, chosen: int) -> float:
    """The BIC margin ``chosen`` terms found among ``offered`` must beat: the library's ``bic_margin`` plus
    the extended BIC's charge for the search (explain.search_charge)."""
    return bic_margin + search_charge(offered, chosen)
