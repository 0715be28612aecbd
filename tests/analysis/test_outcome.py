"""What a diagnosis found (outcome.Outcome): a library that fills only the hooks answers in the one shape,
with the skeleton's figures computed once for every library."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pytest
from conftest import strict_loads

from dse_runner import strict_json
from dse_runner.analysis.diagnose import Outcome, answer
from dse_runner.analysis.diagnose.explain import Candidate
from dse_runner.analysis.diagnose.proof import Proof
from dse_runner.sweeps.fit import FitResult


def _candidate(ids: tuple[str, ...], held_out: list[float], sse: float) -> Candidate:
    names = ["m.k", *(f"m.{i}" for i in ids)]
    values = {n: 1.0 + k for k, n in enumerate(names)}
    fit = FitResult(
        "+".join(ids) or "none", names, values, sse, 100, 5, True, {n: 0.1 for n in names}, [], {}
    )
    return Candidate(ids, fit, held_out={f"run{k}": v for k, v in enumerate(held_out)})


@dataclass
class Found(Outcome):
    """A library's outcome that fills the required hooks and nothing more."""

    library_name = "tiny"
    held_out_unit = "units"

    verdict: str = "explained"
    verdict_text: str = "what remains is noise"
    proof: Proof | None = None

    def effect_entries(self) -> list[answer.Effect]:
        return [
            answer.Effect(id=i, name=i, parameters={}, interval={}, partial=False) for i in self.chosen.ids
        ]

    def noise_floor_entry(self) -> answer.NoiseFloor:
        return answer.NoiseFloor(held_out=0.1, factor=2.0, ratio=self.held_out_after / 0.1, method="given")

    def case_fields(self) -> dict[str, Any]:
        return {"own": True}


def _found(proof: Proof | None = None) -> Found:
    none = _candidate((), [1.0, 1.2], 400.0)
    term = _candidate(("term",), [0.10, 0.12], 20.0)
    rival = _candidate(("rival",), [0.3, 0.2], 60.0)
    return Found(
        baseline=none, chosen=term, candidates=[none, rival, term], proof=proof, files={"report": "r.md"}
    )


def test_a_library_filling_only_the_hooks_answers_in_the_one_shape():
    found = _found()
    saved = answer.Answer.model_validate(strict_loads(strict_json.dumps(found.to_json())))
    assert (saved.library, saved.verdict, saved.held_out_unit) == ("tiny", "explained", "units")
    assert [c.id for c in saved.candidates] == ["term", "rival", "none"]  # best held-out error first
    assert saved.runner_up is not None and saved.runner_up.id == "rival"
    assert (saved.held_out_before, saved.held_out_after) == (pytest.approx(1.1), pytest.approx(0.11))
    assert [(h.scenario, h.before, h.after) for h in saved.held_out] == [
        ("run0", 1.0, 0.10),
        ("run1", 1.2, 0.12),
    ]
    assert saved.fitted.parameters == {"m.k": 1.0, "m.term": 2.0} and set(saved.fitted.interval) == {
        "m.k",
        "m.term",
    }
    assert saved.calibrated.interval  # by default the model before is quoted with its intervals
    assert saved.files == {"report": "r.md"} and saved.case == {"own": True}
    assert found.files_told(["report", "html"]) == ["report: r.md"]


def test_searched_terms_claim_the_proofs_error_when_it_is_worse():
    """A choice made on all the data has seen the held-out runs: its folds' own choices say what it is
    worth, and the answer claims that (proof.honest), in the noise floor's ratio too."""
    proof = Proof(("term",), [("term",), ("rival",)], {"run0": 0.2, "run1": 0.4}, offered=5)
    saved = _found(proof).answer()
    assert saved.held_out_after == pytest.approx(0.3) and saved.noise_floor.ratio == pytest.approx(3.0)
    assert saved.proof is not None and saved.proof.agree == 1
    assert _found(
        Proof(("term",), [("term",)] * 2, {"run0": 0.01, "run1": 0.01})
    ).held_out_after == pytest.approx(0.11)


def test_an_outcome_that_leaves_a_hook_unfilled_is_refused_when_it_is_defined():
    """Refused at import, not after a whole diagnosis has run and before its JSON is written."""
    with pytest.raises(TypeError, match=r"Half subclasses Outcome but fills no held_out_unit, proof"):

        @dataclass
        class Half(Outcome):
            library_name = "half"
            verdict: str = "none"
            verdict_text: str = ""

            def effect_entries(self) -> list[answer.Effect]:
                return []

            def noise_floor_entry(self) -> answer.NoiseFloor:
                return answer.NoiseFloor(held_out=None, factor=2.0, ratio=None, method="none")

            def case_fields(self) -> dict[str, Any]:
                return {}
