"""The signal library's own sections of the report (report.py lays out the rest), and the files it writes.

Why: the engine's page says what every diagnosis says; only this library compares signals with recordings
in units of their noise, screens pairs, grows sets one effect at a time, decides twins across the model's
skin and locates the misfit in windows of time. Each section reads the answer's ``case`` alone, so the page
can be drawn again from ``diagnosis.json``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ...simulation.values import write_values
from . import report
from .answer import Answer
from .lookalike import CANNOT_TELL, DECIDED_BY_FIT, DECIDED_BY_LLR, DECISIVE
from .report import Section, number, table

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


def lookalikes(answer: Answer) -> str:
    """Sets that fit about as well as the answer, and the windows of time that tell them apart."""
    lines = []
    for x in answer.lookalikes:
        where = "; ".join(
            f"{w['scenario']} {w['start']:.3g}-{w['stop']:.3g} s "
            f"({w['input']}, {w['delta_mean_square']:+.3g})"
            for w in x["telling_windows"][:3]
        )
        lines.append(
            f"- {x['id']} fits alike ({x['held_out']:.3g} held-out, {x['runs_better']} runs better for the "
            "chosen); "
            + _llr_words(x.get("segment_llr"))
            + (f"differs most in {where}" if where else "no window tells them apart by more than the noise")
        )
    return "\n".join(lines)


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
        found.append(Section("Look-alikes", lookalikes(answer), after="evidence"))
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


DECIDED_WORDS = {
    DECIDED_BY_FIT: "held-out error and BIC already separate them",
    DECIDED_BY_LLR: f"|LLR| ≥ {DECISIVE:g}: the LLR decides",
    CANNOT_TELL: f"below the {DECISIVE:g} that decides",
}


def _llr_words(llr: dict[str, Any] | None) -> str:
    """The engine's evidence between the twins in words: the LLR for the chosen set, corrected for the
    residuals' autocorrelation, and how it was used."""
    if not llr:
        return ""
    return (
        f"LLR {llr['llr']:+.1f} for the chosen (autocorrelation time {llr['autocorrelation_samples']:.1f} "
        f"samples; {DECIDED_WORDS.get(llr['decision'], llr['decision'])}); "
    )
