"""The engine's discovery rules (analysis/diagnose/discovery.py) on hand-made fits: what every case's term
search is judged by, whatever its terms are."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pytest

from dse_runner.analysis.diagnose import discovery
from dse_runner.analysis.diagnose.explain import Candidate
from dse_runner.analysis.diagnose.term_search import TermSearch
from dse_runner.sweeps.fit import FitResult, Parameter


class Terms(TermSearch):
    """A search whose terms are the parameters named ``<instance>.term_*``, chosen among ten."""

    offered = 10

    def is_term(self, name: str) -> bool:
        return name.rsplit(".", 1)[-1].startswith("term_")

    def propose(self, parent, scenarios, residuals):  # not used by the rules
        raise NotImplementedError

    def parameter(self, variable: str) -> Parameter:
        raise NotImplementedError


class Proposed:
    """A proposal as a search returns it: the terms to fit and every term it offers, best first."""

    def __init__(self, ranked: Sequence[tuple[str, float]], count: int):
        self.ranked = tuple(ranked)
        self.terms = dict(self.ranked[:count])
        self.shapes: Mapping[str, float] = {}
        self.inclusion: Mapping[str, float] = {}

    @property
    def empty(self) -> bool:
        return not self.terms

    def readable(self) -> list[str]:
        return list(self.terms)


def candidate(ids, held_out, sse, values=None, se=0.001) -> Candidate:
    values = {"m.mass": 2.0, **(values or {})}
    names = list(values)
    fit = FitResult(
        "+".join(ids) or "none", names, values, sse, 1000, 5, True, {n: se for n in names}, [], {}
    )
    return Candidate(tuple(ids), fit, held_out={f"run{k}": v for k, v in enumerate(held_out)})


def proofs(*candidates, worse=1.0):
    """Each candidate's proof as discovery builds it, its folds' held-out errors scaled by ``worse``."""
    out = {}
    for c in candidates:
        proof = discovery.proof_of(c, [], Terms())
        proof.held_out = {run: e * worse for run, e in proof.held_out.items()}
        out[c.label] = proof
    return out


def test_found_terms_must_pay_like_an_effect():
    """Accepted only when they cut held-out error by min_gain and BIC by the extended margin against the
    library's answer and every fitted part, every term two standard errors from zero, and their proof (the
    terms each fold chose for itself) bears them out against the same effects without the terms."""
    search = Terms()
    none = candidate((), [1.0, 1.0], 400.0)
    lag = candidate(("lag",), [0.3, 0.3], 100.0, {"m.lag": 0.4})
    term = {"m.term_a": -0.12}
    good = candidate(("lag", "discovered"), [0.05, 0.05], 10.0, {"m.lag": 0.0, **term})
    alone = candidate(("discovered",), [0.04, 0.04], 9.0, term)
    everything = [none, lag, good, alone]
    accept = discovery.accept
    assert accept(search, [good, alone], lag, everything, proofs(good, alone), 0.05, 10.0) is alone  # a tie
    # the folds' own choices predicted no better than the library's lag alone: the terms are not proven
    assert accept(search, [good], lag, everything, proofs(good, worse=6.0), 0.05, 10.0) is None
    assert discovery.proof_of(good, [], search).error == pytest.approx(good.cross_validated)
    small = candidate(("discovered",), [0.29, 0.29], 99.0, term)
    assert accept(search, [small], lag, [none, lag, small], proofs(small), 0.05, 10.0) is None  # < 5 % better
    vague = candidate(("discovered",), [0.04, 0.04], 9.0, term, se=0.1)
    assert accept(search, [vague], lag, [none, lag, vague], proofs(vague), 0.05, 10.0) is None  # within 2 se
    # the search is charged: a BIC gain that pays a library effect's margin does not pay ten terms' search
    costly = candidate(("discovered",), [0.04, 0.04], 100.0 * np.exp(-12.0 / 1000), term)
    assert accept(search, [costly], lag, [none, lag, costly], proofs(costly), 0.05, 10.0) is None
    named = Terms()
    named.offered = 1  # one term named beforehand: no search to charge for
    assert accept(named, [costly], lag, [none, lag, costly], proofs(costly), 0.05, 10.0) is costly


def test_pruned_slots_go_to_the_next_proposed_terms():
    """A term the proposal ranked high but the fit put near zero frees its slot for the next term the
    proposal ranked, never one already tried; the kept terms restart at zero."""
    ranked = (("a", 0.3), ("b", 0.2), ("c", 0.1), ("d", -0.1), ("e", 0.01))
    proposal = Proposed(ranked, 3)
    kept = {"c": 0.15}
    assert discovery.refilled(kept, proposal, set(proposal.terms), 3) == {"c": 0.0, "d": -0.1, "e": 0.01}
    assert discovery.refilled(kept, proposal, {v for v, _ in ranked}, 3) == {"c": 0.0}


def test_terms_are_told_by_the_search_and_stand_by_their_errors():
    search = Terms()
    fit = candidate(("discovered",), [0.1], 1.0, {"m.term_a": 0.5, "m.term_b": 0.001}).full
    fit.standard_error.update({"m.term_a": 0.01, "m.term_b": 0.01})
    assert search.terms_of(fit) == {"term_a": 0.5, "term_b": 0.001}
    assert search.standing(fit) == {"term_a": 0.5}  # term_b is a tenth of its standard error from zero


def test_resemblance_in_words_and_cosine():
    change = np.array([1.0, 2.0, 0.0, -1.0])
    similarity = discovery.similarity
    assert similarity(change, change[:, None] * 0.1, np.array([0.0]), np.array([10.0])) == pytest.approx(1.0)
    assert similarity(change, -change[:, None], np.array([0.0]), np.array([10.0])) == 0.0  # wrong sign only
    other = np.array([[2.0], [-1.0], [0.0], [0.0]])
    assert similarity(change, other, np.array([-5.0]), np.array([5.0])) == pytest.approx(0.0, abs=1e-12)
    assert discovery.resemblance_words([("slip", 0.96)]) == "resembles `slip` (0.96)"
    assert discovery.resemblance_words([("lag", 0.72)]) == "is partly like `lag` (0.72)"
    assert discovery.resemblance_words([("offset", 0.2)]).startswith("is unlike any library effect")
