"""The engine's look-alike evidence: the autocorrelation time of coloured noise, the segment LLR between two
twins' residuals, the rule by which held-out error, BIC and the LLR decide between them, and which sets are
twins by a library's declared look-alikes."""

from __future__ import annotations

import numpy as np
import pytest

from dse_runner.analysis.diagnose import lookalike
from dse_runner.analysis.diagnose.explain import Candidate
from dse_runner.sweeps.fit import FitResult


def ar1(rho: float, n: int, seed: int) -> np.ndarray:
    """AR(1) noise x_k = ρ x_{k−1} + e_k of white e."""
    e = np.random.default_rng(seed).normal(0, 1, n)
    x = np.empty(n)
    x[0] = e[0]
    for k in range(1, n):
        x[k] = rho * x[k - 1] + e[k]
    return x


def test_white_noise_is_one_sample_per_sample_and_ar1_its_known_autocorrelation_time():
    white = np.random.default_rng(4).normal(0, 1, 20000)
    assert lookalike.autocorrelation_time([white]) == pytest.approx(1.0, abs=0.1)
    for rho in (0.5, 0.8):
        known = 1 + 2 * rho / (1 - rho)
        assert lookalike.autocorrelation_time([ar1(rho, 20000, 5)]) == pytest.approx(known, rel=0.15)
    pooled = lookalike.autocorrelation_time([ar1(0.5, 10000, 6), ar1(0.5, 10000, 7)])
    assert pooled == pytest.approx(3.0, rel=0.15)  # series pooled, never joined end to end


KINDS = np.array(["steady"] * 200 + ["changing"] * 50 + ["steady"] * 150, dtype=object)


def twins(seed: int = 2, sigma: float = 0.02) -> tuple[list, list]:
    """Two components per sample (as a fix's x and y): the right set's residual is noise, the wrong one's
    carries a bump where the inputs change."""
    rng = np.random.default_rng(seed)
    bump = np.where(KINDS == "changing", 0.03 * np.sin(np.linspace(0, np.pi, KINDS.size)) + 0.02, 0.0)
    noise = rng.normal(0, sigma, (2, 2, KINDS.size))
    right = [(noise[0], KINDS), (noise[1], KINDS)]
    wrong = [(noise[0] + np.stack([bump, 0 * bump]), KINDS), (noise[1] + np.stack([bump, bump]), KINDS)]
    return right, wrong


def test_the_llr_favours_the_set_whose_residual_is_noise_and_says_where():
    right, wrong = twins()
    e = lookalike.segment_evidence(right, wrong, 0.02, ("changing", "steady"))
    assert e.llr >= lookalike.DECISIVE and e.tau == pytest.approx(1.0, abs=0.3)
    assert list(e.by_kind) == ["changing", "steady"] and e.samples == {"changing": 100, "steady": 700}
    assert abs(e.by_kind["changing"]) > 0.9 * abs(e.llr)  # where they differ
    assert lookalike.segment_evidence(wrong, right, 0.02).llr == pytest.approx(-e.llr)
    same = lookalike.segment_evidence(right, [(r + 0.0, k) for r, k in right], 0.02)
    assert same.llr == 0.0


def test_the_llr_scales_as_one_over_sigma_squared_and_over_the_autocorrelation_time():
    right, wrong = twins()
    e = lookalike.segment_evidence(right, wrong, 0.02)
    assert lookalike.segment_evidence(right, wrong, 0.04).llr == pytest.approx(e.llr / 4)
    labels = np.full(4000, "steady", dtype=object)
    noise = 0.02 * ar1(0.8, labels.size, 8)[None, :]  # the right set's residual: coloured noise
    coloured = lookalike.segment_evidence([(noise, labels)], [(noise + 0.01, labels)], 0.02)
    assert coloured.tau == pytest.approx(9.0, rel=0.2)  # 1 + 2ρ/(1 − ρ) at ρ = 0.8
    counted = float(np.sum((noise + 0.01) ** 2 - noise**2)) / (2 * 0.02**2)  # every sample independent
    assert coloured.llr == pytest.approx(counted / coloured.tau)


def candidate(
    ids: tuple[str, ...], held_out: float, sse: float, residual: np.ndarray | None = None
) -> Candidate:
    fit = FitResult("+".join(ids) or "none", ["k"], {"k": 1.0}, sse, 800, 5, True, {"k": 0.01}, [], {})
    fit.residuals = [] if residual is None else [residual]
    return Candidate(ids, fit, held_out={f"run{k}": held_out for k in range(4)})


def test_the_fits_decide_first_and_the_llr_only_where_they_cannot():
    none = candidate((), 1.0, 400.0)
    late = candidate(("late",), 0.12, 20.0)
    sluggish = candidate(("sluggish",), 0.121, 20.5)  # held-out and BIC cannot separate them
    assert lookalike.decision(late, none, 0.0) == lookalike.DECIDED_BY_FIT
    assert lookalike.decision(late, sluggish, 6.0) == lookalike.DECIDED_BY_LLR
    assert lookalike.decision(late, sluggish, -6.0) == lookalike.DECIDED_BY_LLR
    assert lookalike.decision(late, sluggish, 4.9) == lookalike.CANNOT_TELL


def one_run(candidate: Candidate) -> list[lookalike.Piece] | None:
    """A library's layout: one run, its residual a sample's two components one after the other."""
    if len(candidate.full.residuals) != 1:
        return None
    return [(candidate.full.residuals[0].reshape(2, -1), KINDS)]


def test_weighing_answers_with_the_twin_the_llr_favours_if_it_could_be_chosen():
    (right, _), (wrong, _) = [pieces[0] for pieces in twins()]
    none = candidate((), 1.0, 400.0, 3 * wrong.ravel())
    chosen = candidate(("late",), 0.12, 20.0, wrong.ravel())
    twin = candidate(("sluggish",), 0.121, 20.5, right.ravel())
    segments = lookalike.Segments(one_run, ("changing", "steady"))
    answer, looks = lookalike.weigh(chosen, [(chosen, twin)], [none, chosen, twin], none, segments, 0.02)
    assert answer is twin and looks[0].decision == lookalike.DECIDED_BY_LLR
    saved = looks[0].to_json()
    assert saved["favours"] == saved["chosen"] == "sluggish" and saved["effects"] == ["late", "sluggish"]
    assert saved["llr"] <= -lookalike.DECISIVE and saved["by_segment"]["changing"]["samples"] == 50
    assert saved["autocorrelation_samples"] == pytest.approx(1.0, abs=0.3)

    unvalidated = candidate(("sluggish",), 0.121, 20.5, right.ravel())
    unvalidated.held_out = {}  # fitted on every run only: it could never be the answer
    answer, looks = lookalike.weigh(chosen, [(chosen, unvalidated)], [none, chosen], none, segments, 0.02)
    assert answer is chosen and looks[0].chosen == "late" and looks[0].favoured == "sluggish"

    elsewhere = candidate(("sluggish",), 0.121, 20.5)  # fitted on other runs: nothing to weigh
    assert lookalike.weigh(chosen, [(chosen, elsewhere)], [none, chosen], none, segments, 0.02) == (
        chosen,
        [],
    )


# a library's declared look-alikes (id -> its twins)
TWINS = {"late": ("sluggish",), "sluggish": ("late",), "slip": ("sluggish",)}


def test_the_twins_of_a_set_are_each_member_swapped_for_each_of_its_declared_look_alikes():
    """What the screen shortlists beside a set it chose: one member replaced at a time, by each of its
    declared look-alikes (declared one way only, and none already in the set), in the set's order."""
    assert list(lookalike.swaps(("slip", "late"), TWINS).items()) == [
        (frozenset({"sluggish", "late"}), ("slip", "sluggish")),
        (frozenset({"slip", "sluggish"}), ("late", "sluggish")),
    ]
    assert lookalike.swaps(("late", "sluggish"), TWINS) == {}  # each one's twin is already in the set
    assert lookalike.swaps(("grip",), TWINS) == {}  # nothing declared


def test_twins_are_a_swap_of_one_member_for_a_declared_look_alike():
    assert lookalike.swapped(("grip", "late"), ("grip", "sluggish"), TWINS) == ("late", "sluggish")
    assert lookalike.swapped(("slip",), ("sluggish",), TWINS) == ("slip", "sluggish")
    assert lookalike.swapped(("sluggish",), ("slip",), TWINS) is None  # declared one way only
    assert lookalike.swapped(("grip", "late"), ("grip", "slip"), TWINS) is None  # not a look-alike
    assert lookalike.swapped(("late", "slip"), ("sluggish", "grip"), TWINS) is None  # two swapped
    assert lookalike.swapped(("late",), ("late", "sluggish"), TWINS) is None  # one added, none swapped
    assert lookalike.swapped(("late",), ("sluggish",), {}) is None  # nothing declared, no twins


def test_the_pairs_to_weigh_are_the_chosen_set_and_its_fitted_twins_or_the_two_best_if_twins():
    residual = np.zeros(4)
    chosen = candidate(("grip", "late"), 0.12, 20.0, residual)
    twin = candidate(("grip", "sluggish"), 0.13, 21.0, residual)
    unfitted = candidate(("grip", "sluggish"), 0.13, 21.0)  # no residuals: fitted on other runs
    other = candidate(("grip", "slip"), 0.125, 20.5, residual)
    pairs = lookalike.twin_pairs(chosen, [chosen, twin, unfitted, other], TWINS)
    assert [(a.label, b.label) for a, b in pairs] == [("grip+late", "grip+sluggish")]
    assert pairs[0][1] is twin

    nothing = candidate((), 1.0, 400.0, residual)
    late, sluggish = candidate(("late",), 0.5, 90.0, residual), candidate(("sluggish",), 0.4, 80.0, residual)
    pairs = lookalike.twin_pairs(nothing, [nothing, late, sluggish], TWINS)
    assert [(a.label, b.label) for a, b in pairs] == [("sluggish", "late")]  # best first
    grip = candidate(("grip",), 0.3, 70.0, residual)  # now the two best are grip and sluggish: no twins
    assert lookalike.twin_pairs(nothing, [nothing, late, sluggish, grip], TWINS) == []
