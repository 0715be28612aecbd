"""The signal library's own sections of the report (report.py lays out the rest), and the files it writes.

Why: the engine's page says what every diagnosis says; only this library compares signals with recordings
in units of their noise, screens pairs, grows sets one effect at a time, decides twins across the model's
skin and locates the misfit in windows of time. Its look-alikes are the engine's part (report.lookalikes_part)
in its words (:class:`Words`). Each section reads the answer alone (its ``case``, ``lookalikes``), so the
page can be drawn again from ``diagnosis.json``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

from ...simulation.values import write_values
from . import report
from .answer import Answer
from .report import Section, ids, number, table
from .signal_locate import CHANGING, NO_INPUT, STEADY

REPORT, SUMMARY, VALUES = "diagnosis-report.md", "diagnosis.json", "diagnosed-values.yaml"


def files_in(folder: Path) -> dict[str, str]:
    """Where the report, its page, the JSON and the diagnosed model's values go in ``folder``."""
    return {**report.files_at(folder / REPORT, folder / SUMMARY), "values": str(folder / VALUES)}


def compared(case: dict[str, Any]) -> str:
    """Each signal compared with a recording, its noise and how it was estimated, and whether the answer's
    residuals are white."""
    lines = [table(case["compared"], ["objective", "signal", "recorded", "noise"])]
    for c in case["compared"]:
        estimate = c.get("noise_estimate") or {}
        if estimate:
            lines += [
                "",
                (
                    f"Noise of {c['recorded']}: σ {estimate['sigma']:.4g} by {estimate['method']}; it "
                    f"assumes {estimate['assumptions']}."
                ),
            ]
    for signal, w in (case.get("whiteness") or {}).items():
        lines += [
            "",
            f"Residuals of {signal} after: lag-1 autocorrelation {number(w['rho1'])}, Ljung-Box p "
            f"{number(w['p'])} over {w['lags']} lags: " + ("white." if w["white"] else "not white."),
        ]
    return "\n".join(lines)


def decided(case: dict[str, Any]) -> str:
    """Each member against its look-alike across the model's skin, fitted in the other's place."""
    lines = []
    for d in case.get("decided") or []:
        errors = d["held_out"]
        lines.append(
            f"Look-alike: {d['lookalike']} (held-out {errors[d['lookalike']]:.3g} noise floors) lost to "
            f"{d['winner']} ({errors[d['winner']]:.3g}); each fitted in the other's place with the rest of "
            "the answer."
        )
    return "\n\n".join(lines)


class Words(report.LookalikeWords):
    """The signal library's words on its look-alikes: the windows of its segments, its samples in units of
    their recording's noise; what it adds of a pair (each entry is signal_claims.FitsAlike.to_json, the
    engine's evidence under ``segment_llr``): how alike the two fit and the windows of time that tell them
    apart."""

    segments: ClassVar[Mapping[str, str]] = {
        CHANGING: "windows where an input changes",
        STEADY: "windows where the inputs hold",
        NO_INPUT: "runs without a driven input",
    }
    noise = "the recording's noise; each residual is in its units, so σ is 1"
    intro = (
        "Sets that fit about as well as the answer (neither's held-out error clearly lower) were fitted on "
        "every run, and their residuals compared segment by segment, each sample labelled by what the driven "
        "inputs do in its window."
    )

    def twins(self, look: Mapping[str, Any]) -> Mapping[str, Any] | None:
        return look.get("segment_llr")

    def about(self, look: Mapping[str, Any]) -> str:
        where = "; ".join(
            f"{w['scenario']} {w['start']:.3g}-{w['stop']:.3g} s "
            f"({w['input']}, {w['delta_mean_square']:+.3g})"
            for w in look["telling_windows"][:3]
        )
        return (
            f"{ids(look['id'])} fits alike ({look['held_out']:.3g} held-out, {look['runs_better']} runs "
            "better for the chosen); "
            + (f"differs most in {where}" if where else "no window tells them apart by more than the noise")
            + "."
        )


WORDS = Words()


def located(case: dict[str, Any]) -> str:
    """Where the model misses: by run, by what the inputs do, and the worst windows of time."""
    found = case["located"]
    return "\n".join(
        [
            found["method"][:1].upper() + found["method"][1:] + ".",
            "",
            "By run (noise floors):",
            "",
            table(found["by_scenario"], ["signal", "scenario", "samples", "floors_before", "floors_after"]),
            "",
            "By what the inputs do:",
            "",
            table(found["by_input"], ["signal", "input", "windows", "floors_before", "floors_after"]),
            "",
            "Worst windows before:",
            "",
            table(
                found["worst"],
                ["signal", "scenario", "start", "stop", "input", "floors_before", "floors_after"],
            ),
        ]
    )


def sections(answer: Answer) -> list[Section]:
    """The signal library's sections of its report, from the answer alone."""
    case = answer.case
    found = [Section("Compared signals", compared(case), after="verdict")]
    if case.get("decided"):
        found.append(Section("Look-alikes across the model's skin", decided(case), after="evidence"))
    if answer.lookalikes:
        found.append(Section("Look-alikes", report.lookalikes_part(answer, WORDS), after="evidence"))
    if case.get("located"):
        found.append(Section("Where the model misses", located(case), after="runs"))
    figures = answer.files.get("figures") or []
    if figures:
        shown = "\n\n".join(report.figure(answer, f, Path(f).stem) for f in figures)
        found.append(Section("Recorded against simulated", shown, after="runs"))
    return found


def write(answer: Answer) -> dict[str, Path]:
    """The report (the engine's, with this library's sections), its page, the JSON, and the diagnosed
    model's values, where the answer's ``files`` say (:func:`files_in`). The values file is the model the
    recordings support, ready to run again: ``dse-runner simulate MODEL --scenario … --values
    diagnosed-values.yaml``."""
    written = report.write(answer, sections)
    written["values"] = Path(answer.files["values"])
    write_values(
        written["values"],
        answer.fitted.parameters,
        f"The diagnosed model of {answer.space}: its calibrated parameters, and the effects and derivative\n"
        f"terms the recordings support ({answer.verdict}), as fitted together. Run it again with\n"
        f"dse-runner simulate SPACE.yaml --scenario NAME --values {VALUES}, or put it in a "
        "space's parameters.",
    )
    return written
