"""The report every diagnosis is read on (analysis/diagnose/report.py): drawn from the answer's JSON alone, in
one order, with a library's own sections where it places them."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import ClassVar

import pytest

from dse_runner.analysis.diagnose import report
from dse_runner.analysis.diagnose.answer import Answer
from dse_runner.analysis.diagnose.report import Section


def bare() -> dict:
    """An answer with nothing optional: nothing named, no runner-up, nothing held out."""
    return {
        "library": "toy",
        "verdict": "none",
        "verdict_text": "nothing is missing: what is left is the noise",
        "held_out_before": 0.021,
        "held_out_after": 0.021,
        "held_out_unit": "m (mean error on held-out runs)",
        "noise_floor": {"held_out": None, "factor": 2.0, "ratio": None, "method": "unavailable"},
        "effects": [
            {"id": "none", "name": "nothing named", "parameters": {}, "interval": {}, "partial": False}
        ],
        "runner_up": None,
        "candidates": [{"id": "none", "held_out": 0.021, "bic": 50.0, "validated": True}],
        "calibrated": {"parameters": {"plant.k": 2.0}},
        "fitted": {"parameters": {"plant.k": 2.0}},
    }


def full() -> dict:
    """An answer with every optional part: two effects (one pinned at a bound), a runner-up, a member not
    claimed, a proof, time blocks held out, a failed fit."""
    return {
        **bare(),
        "space": "toy-plant",
        "verdict": "partial",
        "verdict_text": "the runs support slip + lag, but a residual remains",
        "held_out_before": 0.5,
        "held_out_after": 0.05,
        "noise_floor": {"held_out": 0.02, "factor": 2.0, "ratio": 2.5, "method": "close fixes"},
        "effects": [
            {
                "id": "slip",
                "name": "wheel slip",
                "parameters": {"ratio": 0.0437},
                "interval": {"ratio": [0.0401, 0.0473]},
                "partial": True,
            },
            {
                "id": "lag",
                "name": "an actuator lag",
                "parameters": {"tau": 0.812},
                "interval": {"tau": [0.5, None]},
                "partial": True,
                "at_bound": ["tau"],
                "readable": ["d(v)/dt += -0.31·v"],
            },
        ],
        "runner_up": {
            "id": "slip+offset",
            "held_out": 0.061,
            "delta_bic": 14.2,
            "delta_held_out": 0.011,
            "delta_held_out_percent": 22.0,
            "runs_better": "3/4",
            "runs_tied": 1,
        },
        "candidates": [
            {
                "id": "lag+slip",
                "held_out": 0.05,
                "bic": -400.0,
                "validated": True,
                "parameters": {"v.tau": 0.8},
            },
            {"id": "slip+offset", "held_out": 0.061, "bic": -385.8, "validated": True},
            {"id": "none", "held_out": 0.5, "bic": 100.0, "validated": True},
            {"id": "bump", "held_out": None, "bic": None, "validated": False, "error": "its FMU failed"},
        ],
        "dropped": [{"id": "offset", "worth": 0.3, "rule": "removal adds < 1 noise variance"}],
        "proof": {
            "terms": ["corr_v"],
            "offered": 120,
            "folds": [["corr_v"], ["corr_v"], ["corr_a"]],
            "agree": 2,
            "held_out": 0.052,
            "rule": "each fold chose its terms on its fitting scenarios alone",
        },
        "validation": {"by": "time blocks", "folds": 3, "record": "run1"},
        "screen": {
            "strategy": "mixed",
            "how": "mixtures of the single fits",
            "predicted": 6,
            "screened": [
                {
                    "id": "lag+slip",
                    "from": "none",
                    "predicted_sse": 1.2,
                    "sse": 1.5,
                    "bic": -390.0,
                    "shortlisted": True,
                },
                {
                    "id": "slip+offset",
                    "from": "none",
                    "predicted_sse": 2.0,
                    "sse": 2.5,
                    "bic": -380.0,
                    "shortlisted": False,
                },
            ],
            "fitted": ["lag+slip"],
        },
        "growth": [{"parent": "lag+slip", "tried": 3, "best": "lag+offset+slip", "bic": -401.0}],
        "held_out": [
            {"scenario": "run1~block3", "before": 0.6, "after": 0.06, "group": "sin"},
            {"scenario": "run1~block2", "before": 0.4, "after": 0.04, "group": "sin"},
        ],
        "calibrated": {"parameters": {"plant.k": 2.0}},
        "fitted": {
            "parameters": {"plant.k": 2.1, "v.tau": 0.812},
            "interval": {"plant.k": [2.0, 2.2], "v.tau": [0.5, None]},
            "at_bound": ["v.tau"],
        },
    }


def part(text: str, heading: str) -> str:
    """The text under ``## heading``, to the next heading of that level."""
    return text.split(f"## {heading}\n", 1)[1].split("\n## ", 1)[0]


def test_the_page_says_the_verdict_each_effect_with_its_interval_and_the_held_out_figures():
    text = report.markdown(Answer.model_validate(full()))
    assert text.startswith("# Diagnosis of toy-plant\n")
    assert "**Verdict: partial.** The runs support slip + lag, but a residual remains" in text
    assert "Held-out error: 0.5 before (the calibrated model), 0.05 after (-90.0 %); in m" in text
    assert "Validated by time blocks (3 folds of the record run1)." in text
    assert "Noise floor: 0.02 m (close fixes); the answer's error is 2.50× it; above 2× a residual" in text
    effects = part(text, "Named effects")
    assert "| slip | ratio | 0.0437 | 0.0401 to 0.0473 |" in effects
    assert "| lag | tau | 0.812 | 0.5 to – |" in effects  # an undetermined end is a dash, not a number
    assert "at a bound, not an estimate: tau" in effects and "d(v)/dt += -0.31·v" in effects
    evidence = part(text, "Evidence")
    assert "Runner-up: `slip` + `offset`" in evidence and "3/4 held-out runs better (1 equal" in evidence
    assert "overstates the evidence" in evidence
    assert "Not claimed (removal adds < 1 noise variance): offset." in evidence
    assert "Proof: 2 of 3 folds, choosing among 120 terms" in evidence
    candidates = part(text, "Candidates (best held-out first)")
    assert "| lag+slip | 0.05 | -90.0 % | -500 | v.tau = 0.8 | yes |" in candidates  # the answer, marked
    assert "| bump | not cross-validated |" in candidates and "bump (its FMU failed)" in candidates
    search = part(text, "How the combinations were searched")
    assert "Combinations (mixed screen: mixtures of the single fits): 6 predicted, 2 checked" in search
    assert (
        "1 fitted for real (`lag+slip`)" in search
        and "| lag+slip | none | 1.2 | 1.5 | -390 | yes |" in search
    )
    assert (
        "Grown from `lag+slip`: 3 sets with one more effect tried, the best by BIC `lag+offset+slip`"
        in search
    )
    assert search.rstrip().endswith(": not accepted.")
    runs = part(text, "Held-out runs, before and after")
    assert runs.index("run1~block2") < runs.index("run1~block3")
    assert "| run1~block2 | sin | 0.4 | 0.04 | -90.0 % |" in runs
    assert "| v.tau | – | 0.812 | 0.5 to – | yes |" in part(text, "Calibrated and fitted values")


def test_a_bare_answer_reads_without_its_optional_parts():
    text = report.markdown(Answer.model_validate(bare()))
    assert text.startswith("# Diagnosis of toy\n")  # no space named: the library
    assert "**Verdict: none.** Nothing is missing" in text
    assert "Noise floor: none could be estimated (unavailable)" in text
    assert "- `none`: nothing named." in part(text, "Named effects")
    assert "Runner-up: none" in part(text, "Evidence") and "Proof" not in text and "Validated" not in text
    assert part(text, "Held-out runs, before and after").strip() == "(none)"
    assert part(text, "Files").strip() == "(none)"
    assert part(text, "How the combinations were searched").strip() == "Only single effects were fitted."
    skipped = report.markdown(
        Answer.model_validate({**bare(), "screen": {"strategy": "mixed", "reason": "a fit is at the noise"}})
    )
    assert "No combination was screened: a fit is at the noise." in skipped


def test_a_library_section_is_placed_after_the_part_it_names_and_the_page_rebuilds_from_the_json(tmp_path):
    files = report.files_at(tmp_path / "report.md", tmp_path / "diagnosis.json")
    figure = tmp_path / "figures" / "tracks.png"
    answer = Answer.model_validate({**full(), "files": {**files, "figure_tracks": str(figure)}})
    sections = [
        Section("Where it misses", "By run: run1 most.\n\n" + report.figure(answer, figure, "tracks")),
        Section("Compared signals", "x against x_rec", after="verdict"),
        Section("", "**Look-alikes:** slip or speed_lag: cannot tell.", after="verdict"),
    ]
    written = report.write(answer, lambda saved: sections)
    text = written["report"].read_text()
    order = [
        "**Verdict: partial.**",
        "## Compared signals",  # sections after the same part: in the library's order
        "**Look-alikes:** slip or speed_lag",
        "## Named effects",
        "## Evidence",
        "## Where it misses",
        "## Candidates",
    ]
    assert [text.index(s) for s in order] == sorted(text.index(s) for s in order)
    assert "![tracks](figures/tracks.png)" in text  # relative to the report, where the page is read
    assert written["html"].read_text().count("<h2>") == text.count("\n## ")
    again = report.read(written["json"])
    assert again == answer and report.markdown(again, sections) == text


def test_a_library_without_sections_gets_the_skeleton_alone():
    from dse_runner.analysis.diagnose import HypothesisLibrary

    class Bare(HypothesisLibrary):
        name = "bare"

        def serves(self, space):
            return True

        def diagnose(self, space, request, say):
            raise NotImplementedError

    answer = Answer.model_validate(bare())
    assert Bare().sections(answer) == []
    assert report.markdown(answer, Bare().sections(answer)) == report.markdown(answer)


@pytest.mark.parametrize("value, shown", [(23208.4, "23208"), (0.04492, "0.04492"), (None, "–"), ("x", "x")])
def test_numbers_read_as_people_write_them(value, shown):
    assert report.number(value) == shown


def test_the_json_it_is_drawn_from_is_the_answer_itself(tmp_path):
    files = report.files_at(tmp_path / "r" / "report.md", tmp_path / "r" / "diagnosis.json")
    answer = Answer.model_validate({**bare(), "files": files})
    report.write(answer)
    assert json.loads((tmp_path / "r" / "diagnosis.json").read_text()) == answer.json_dict()
    assert (tmp_path / "r" / "diagnosis.html").read_text().startswith("<!DOCTYPE html>")


# ---- the parts a library places: look-alikes and discovery, the engine's drawing in its words ---------


def twins_entry(decision: str, llr: float) -> dict:
    """The engine's evidence between two twins, as lookalike.Twins writes it."""
    from dse_runner.analysis.diagnose.lookalike import SegmentEvidence, Twins

    evidence = SegmentEvidence(
        llr, {"step": 0.9 * llr, "rest": 0.1 * llr}, {"step": 40, "rest": 60}, 2.5, 0.01
    )
    return Twins(("late", "sluggish"), ("late", "sluggish"), evidence, decision, "late").to_json()


class Nested(report.LookalikeWords):
    """A library that keeps the engine's evidence under a key of its own and adds its words on each pair."""

    segments: ClassVar[Mapping[str, str]] = {"step": "steps of the input"}
    noise = "the sensor's noise"
    intro = "Sets that fit alike were fitted on every run."

    def twins(self, look):
        return look["evidence"]

    def about(self, look):
        return f"It also fits alike ({look['held_out']} held-out)."

    def more(self, look):
        return "Its own paragraph."


def test_look_alikes_are_drawn_from_the_engines_evidence_in_the_librarys_words():
    from dse_runner.analysis.diagnose.lookalike import CANNOT_TELL, DECIDED_BY_FIT, DECIDED_BY_LLR

    assert report.lookalikes_part(Answer.model_validate(full()), Nested()) == ""  # no twins: no part
    looks = [
        {"held_out": 0.06, "evidence": twins_entry(DECIDED_BY_LLR, 8.0)},
        {"held_out": 0.07, "evidence": None},  # could not be weighed: the library's words alone
    ]
    text = report.lookalikes_part(Answer.model_validate({**full(), "lookalikes": looks}), Nested())
    assert text.startswith("Sets that fit alike were fitted on every run. The log-likelihood ratio (LLR)")
    assert "(σ the sensor's noise), divided by the residuals' autocorrelation time in samples" in text
    assert "|LLR| ≥ 5 (about 150 to 1) decides" in text
    assert (
        "`late` against `sluggish` (swapping `late` for `sluggish`): LLR +8.0, in favour of `late`, mostly "
        "on steps of the input (+7.2); held-out error and BIC do not separate them; the LLR does "
        "(|LLR| ≥ 5). σ = 0.0100 m, autocorrelation time 2.5 samples. It also fits alike (0.06 held-out)."
        in text
    )
    assert "| segment | samples | LLR (late over sluggish) |" in text
    assert "| steps of the input | 40 | 7.2 |" in text and "| rest | 60 | 0.8 |" in text  # unnamed: as is
    assert text.count("Its own paragraph.") == 2 and "\nIt also fits alike (0.07 held-out).\n" in text
    cannot = report.twins_sentence(twins_entry(CANNOT_TELL, -1.5), report.LookalikeWords())
    assert cannot == (
        "**Look-alikes:** `late` or its look-alike `sluggish`: cannot tell on these runs (LLR -1.5, below "
        "the 5 that decides)."
    )
    assert report.twins_sentence(twins_entry(DECIDED_BY_FIT, 30.0), report.LookalikeWords()) == ""
    decided = report.twins_sentence(twins_entry(DECIDED_BY_LLR, -8.0), report.LookalikeWords())
    assert decided.startswith("**Look-alikes:** `sluggish` rather than its look-alike `late`: held-out")
    assert "but the samples can (LLR 8.0 in its favour, mostly on step (-7.2))." in decided


def found(chosen: str | None) -> dict:
    """What discovery.Discovery writes of a search beyond the library."""
    return {
        "reference": "lag",
        "held_out_reference": 0.05,
        "bic_reference": -400.0,
        "proposed_text": ["d(v)/dt += -0.31·v"],
        "bic_margin": 14.25,
        "chosen": chosen,
        "resembles": "resembles no effect of the library" if chosen else None,
        "tried": [{"id": "lag+discovered", "text": ["k = -0.31"], "held_out": 0.03, "bic": -430.0}],
        "proof": {
            "terms": ["k"],
            "offered": 12,
            "folds": [["k"], ["k"], ["j"]],
            "agree": 2,
            "held_out": 0.035,
            "rule": "each fold chose on its own",
        },
        "reason": "" if chosen else "no set with terms beat the reference by the rule",
    }


def test_discovery_is_drawn_after_the_librarys_description_of_its_search():
    answer = Answer.model_validate(full())
    assert (
        report.discovery_part(answer, None, "Searched.", "it is off")
        == "No correction was sought: it is off."
    )
    assert report.discovery_part(answer, None, "Searched.", "") == ""
    text = report.discovery_part(answer, found("lag+discovered"), "A search of mine.", "")
    assert text.startswith(
        "A search of mine. The proposed terms were then fitted with the calibrated parameters"
    )
    assert "pruned to those 2 standard errors from zero" in text and "the BIC margin raised to 14.2" in text
    assert "Proposed from every run: `d(v)/dt += -0.31·v`." in text
    assert "`lag+discovered`: k = -0.31, held-out 0.0300 m, ΔBIC -30.0 against `lag` (0.0500 m)." in text
    assert "Accepted: `lag+discovered`; it resembles no effect of the library." in text
    assert "Proof: 2 of 3 folds, choosing among 12 terms" in text and "with 0.035 m" in text
    rejected = report.discovery_part(answer, found(None), "A search of mine.", "")
    assert "Nothing was accepted: no set with terms beat the reference by the rule." in rejected
