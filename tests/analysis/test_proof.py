"""The proof of searched terms, one rule for every diagnosis (analysis/diagnose/proof.py)."""

import math

import pytest

from dse_runner.analysis.diagnose.proof import Proof, extended_margin, honest


def test_the_claim_is_the_worse_of_the_answers_folds_and_the_folds_own_choices():
    """A choice made on all the data has seen the held-out scenarios: what it claims is never better than
    the folds that chose for themselves."""
    proof = Proof(("x3",), [("x3",), ("x|x|",)], {"a": 2.0, "b": 4.0}, offered=11)
    assert proof.error == pytest.approx(3.0)
    assert proof.agree == 1
    assert honest(1.5, proof) == pytest.approx(3.0)
    assert honest(3.5, proof) == pytest.approx(3.5)
    assert honest(1.5, None) == pytest.approx(1.5)
    assert math.isinf(Proof(("x3",)).error)  # nothing held out proves nothing


def test_terms_are_borne_out_only_by_a_clear_gain_over_the_answer_without_them():
    proof = Proof(("x3",), [("x3",)], {"a": 0.9}, offered=11)
    assert proof.bears_out(1.0, min_gain=0.05)
    assert not proof.bears_out(0.93, min_gain=0.05)
    assert "0.9" in proof.failed(0.93, " m") and "0.93 m without them" in proof.failed(0.93, " m")
    data = proof.to_json()
    assert data["folds"] == [["x3"]] and data["agree"] == 1 and data["offered"] == 11


def test_the_search_among_terms_pays_the_extended_bic():
    """Choosing k of P terms pays 2·ln C(P, k) beyond the library's margin; choosing none or all pays none."""
    assert extended_margin(10.0, 38, 2) == pytest.approx(10.0 + 2 * math.log(math.comb(38, 2)))
    assert extended_margin(10.0, 38, 0) == pytest.approx(10.0)
    assert extended_margin(10.0, 2, 2) == pytest.approx(10.0)
    assert extended_margin(10.0, 38, 3) > extended_margin(10.0, 38, 2) > extended_margin(10.0, 11, 2)
