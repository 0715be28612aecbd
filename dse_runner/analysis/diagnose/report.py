"""The report of any diagnosis: one Markdown page and its HTML twin, drawn from the answer's JSON alone.

Why: every library answers in one shape (answer.py), so the page a user reads is laid out once, here, in
one order: the verdict, the held-out error before and after against the noise floor, the named effects with
their intervals, the evidence (the runner-up, what was not claimed, the proof of searched terms), the
candidates, each held-out run, the values calibrated and fitted, the files. A library adds only what is its
own: :class:`Section` s, each placed after one of those parts (``HypothesisLibrary.sections``), and its
figures. Reading nothing but the JSON, the page can be drawn again from ``diagnosis.json``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from ... import strict_json
from . import report_html
from .answer import Answer, Effect, Evidence, Proof
from .explain import TIE

Part = Literal["verdict", "effects", "evidence", "candidates", "search", "runs", "values", "files"]
PARTS: tuple[Part, ...] = (
    "verdict",
    "effects",
    "evidence",
    "candidates",
    "search",
    "runs",
    "values",
    "files",
)


@dataclass(frozen=True)
class Section:
    """A library's own part of the page: ``body`` (Markdown) under ``heading`` (none: the body alone, as a
    paragraph), after the skeleton's part ``after``."""

    heading: str
    body: str
    after: Part = "evidence"


Sections = Callable[[Answer], Sequence[Section]]  # a library's sections of an answer (its ``sections``)


def number(value: Any) -> str:
    """A number to four significant figures (a large one whole); anything else as it is (None as a dash)."""
    if value is None:
        return "–"
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return str(value)
    return f"{value:.0f}" if 1e4 <= abs(value) < 1e12 else f"{value:.4g}"  # 23208, not 2.321e+04


def table(rows: Sequence[Mapping[str, Any]], columns: Sequence[str]) -> str:
    """A Markdown table of ``columns`` of ``rows``; numbers to four significant figures."""
    if not rows:
        return "(none)"
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(number(row.get(c, "")) for c in columns) + " |" for row in rows]
    return "\n".join(lines)


def figure(answer: Answer, path: str | Path, caption: str) -> str:
    """A figure's Markdown, its address relative to the report's folder (where the page is read)."""
    folder = Path(answer.files["report"]).parent if "report" in answer.files else Path.cwd()
    return f"![{caption}]({Path(os.path.relpath(path, folder)).as_posix()})"


def unit(answer: Answer) -> str:
    """The held-out error's unit in short (``m``, ``noise floors``), for sentences and column heads."""
    return answer.held_out_unit.split(" (")[0]


def _change(before: float | None, after: float | None) -> str:
    if before is None or after is None or not before > 0 or not math.isfinite(before * after):
        return "–"
    return f"{(after / before - 1) * 100:+.1f} %"


def ids(label: str) -> str:
    """A set's label (``a+b``) as its members in code type."""
    return " + ".join(f"`{h}`" for h in label.split("+"))


# ---- the parts, in the page's order ---------------------------------------------------------------


def verdict(answer: Answer) -> str:
    """The verdict in the library's words, the error before and after, how it was validated, the floor."""
    v, floor, u = answer.validation, answer.noise_floor, unit(answer)
    in_sample = v is not None and v.by == "in sample"
    judged = "Error on the samples fitted (nothing could be held out)" if in_sample else "Held-out error"
    words = answer.verdict_text.removeprefix(f"{answer.verdict}: ")  # a library's words may repeat it
    words += "" if words.endswith((".", "!", "?")) else "."
    lines = [
        f"**Verdict: {answer.verdict}.** {words[:1].upper()}{words[1:]}",
        "",
        (
            f"{judged}: {number(answer.held_out_before)} before (the calibrated model), "
            f"{number(answer.held_out_after)} after "
            f"({_change(answer.held_out_before, answer.held_out_after)}); in {answer.held_out_unit}."
        ),
    ]
    if v is not None:
        of = f" of the record {v.record}" if v.record else ""
        lines += ["", f"Validated by {v.by}" + (f" ({v.folds} folds{of})" if v.folds else "") + "."]
    if floor.held_out is None:
        said = (
            f"Noise floor: none could be estimated ({floor.method}); the residual is not weighed against it."
        )
    else:
        ratio = f"; the answer's error is {floor.ratio:.2f}× it" if floor.ratio is not None else ""
        said = (
            f"Noise floor: {number(floor.held_out)} {u} ({floor.method}){ratio}; above {floor.factor:g}× a "
            "residual counts as more than noise."
        )
    return "\n".join([*lines, "", said])


def _label(effect: Effect) -> str:
    if effect.term:
        return f"{effect.target} += {effect.term}"
    if effect.target:
        return f"{effect.id}({effect.target})" + (f" into {effect.into}" if effect.into else "")
    return effect.id


def _about(effect: Effect, u: str) -> str:
    """One effect in a line: its id and name, the law or terms it stands for, what it gained, and any
    parameter pinned at a bound."""
    said = [f"`{_label(effect)}`: {effect.name}" + (f" ({effect.law})" if effect.law else "")]
    said += effect.readable
    if effect.held_out_without is not None and effect.held_out_with is not None:
        said.append(
            f"held-out error {number(effect.held_out_without)} {u} without it, "
            f"{number(effect.held_out_with)} {u} with it"
        )
    if effect.resembles:
        said.append(f"it {effect.resembles.get('text') or 'resembles ' + str(effect.resembles.get('id'))}")
    if effect.at_bound:
        said.append(f"at a bound, not an estimate: {', '.join(effect.at_bound)}")
    if effect.partial:
        said.append("partial: part of the cause, not the whole of it")
    return "- " + "; ".join(said) + "."


def effects(answer: Answer) -> str:
    """Each named effect in words, then every fitted value of them with its ~95 % interval."""
    rows = [
        {
            "effect": _label(e),
            "parameter": kind,
            "value": value,
            "95 % interval": " to ".join(number(x) for x in e.interval.get(kind, [None, None])),
        }
        for e in answer.effects
        for kind, value in e.parameters.items()
    ]
    lines = [_about(e, unit(answer)) for e in answer.effects]
    if rows:
        lines += ["", table(rows, ["effect", "parameter", "value", "95 % interval"])]
    pinned = answer.fitted.at_bound
    if pinned:
        lines += [
            "",
            (
                "At a bound of its interval, not an estimate (the recordings push it further; widen the "
                f"interval or doubt the model): {', '.join(pinned)}."
            ),
        ]
    return "\n".join(lines)


def runner_up(up: Evidence | None, u: str) -> str:
    """The best real alternative to the answer and the evidence between them."""
    if up is None:
        return "Runner-up: none; no other candidate was fitted that is not part of the answer."
    delta, held = up.delta_held_out, number(up.held_out)
    if delta is None or not math.isfinite(delta):
        said = f"its held-out error, {held} {u}, could not be compared with the answer's"
    elif abs(delta) <= TIE:
        said = f"its held-out error, {held} {u}, is the answer's (within {TIE:g})"
    elif delta > 0:
        said = (
            f"its held-out error, {held} {u}, is {number(delta)} {u} "
            f"({up.delta_held_out_percent:+.1f} %) above the answer's"
        )
    else:
        said = (
            f"its held-out error, {held} {u}, is {number(-delta)} {u} lower, yet it did not pass the rule "
            "(a clearly lower held-out error and BIC than the simpler model)"
        )
    tied = f" ({up.runs_tied} equal within {TIE:g})" if up.runs_tied else ""
    bic = f"{up.delta_bic:+.1f}" if up.delta_bic is not None else "–"
    return (
        f"Runner-up: {ids(up.id)}: {said}; the answer predicts {up.runs_better} held-out runs better{tied}; "
        f"ΔBIC = {bic} (positive favours the answer). ΔBIC treats every sample as independent, but "
        "successive samples are correlated, so it overstates the evidence: the held-out difference and the "
        "count of runs are the figures to weigh."
    )


def proof(found: Proof, u: str) -> str:
    """Whether each fold, choosing on its own, chose the answer's searched terms again."""
    return (
        f"Proof: {found.agree} of {len(found.folds)} folds, choosing among {found.offered} terms on their "
        f"fitting runs alone, chose these terms again ({', '.join(f'`{t}`' for t in found.terms) or 'none'});"
        f" their own choices predicted the held-out runs with {number(found.held_out)} {u} ({found.rule})."
    )


def evidence(answer: Answer) -> str:
    """The runner-up, the members a rule took away, and the proof of terms found by searching."""
    lines = [runner_up(answer.runner_up, unit(answer))]
    by_rule: dict[str, list[str]] = {}
    for d in answer.dropped:
        by_rule.setdefault(d.rule, []).append(d.id)
    lines += [f"Not claimed ({rule}): {', '.join(ids)}." for rule, ids in by_rule.items()]
    if answer.proof is not None:
        lines.append(proof(answer.proof, unit(answer)))
    return "\n\n".join(lines)


def chosen_label(answer: Answer) -> set[str]:
    """The answer's members as the candidates name them."""
    return {e.hypothesis or e.id for e in answer.effects}


def candidates(answer: Answer) -> str:
    """Every set fitted, best held-out first: against the calibrated model (``none``), its own parameters."""
    u, calibrated = unit(answer), answer.calibrated.parameters
    none = next((c for c in answer.candidates if c.id == "none"), None)
    members = chosen_label(answer)
    rows = [
        {
            "candidate": c.id,
            f"held-out [{u}]": c.held_out if c.validated else "not cross-validated",
            "vs none": _change(none.held_out, c.held_out) if none is not None and c.validated else "–",
            "ΔBIC vs none": (c.bic - none.bic) if none is not None and None not in (c.bic, none.bic) else "–",
            "its parameters": ", ".join(
                f"{k} = {v:.4g}" for k, v in c.parameters.items() if k not in calibrated
            )
            or "–",
            "answer": "yes" if set(c.id.split("+")) == members else "",
        }
        for c in answer.candidates
    ]
    columns = ["candidate", f"held-out [{u}]", "vs none", "ΔBIC vs none", "its parameters", "answer"]
    lines = [table(rows, columns)]
    failed = [f"{c.id} ({c.error})" for c in answer.candidates if c.error]
    if failed:
        lines += ["", f"Rejected, their fits could not start: {'; '.join(failed)}."]
    return "\n".join(lines)


def search(answer: Answer, rows: int = 12) -> str:
    """How the sets beyond the singles were found: the combination screen (its way, what it predicted,
    checked and fitted, its best sets predicted against simulated; or why it did not run), then growth."""
    lines = []
    found = answer.screen
    if found is not None and found.screened:
        lines.append(
            f"Combinations ({found.strategy} screen: {found.how}): {found.predicted} predicted, "
            f"{len(found.screened)} checked by simulation, {len(found.fitted)} fitted for real "
            f"({', '.join(f'`{x}`' for x in found.fitted) or 'none'})."
        )
        shown = [
            {
                "set": x["id"],
                "predicted from": x["from"],
                "predicted SSE": x["predicted_sse"],
                "simulated SSE": x["sse"],
                "BIC": x["bic"],
                "fitted": "yes" if x["shortlisted"] else "",
            }
            for k, x in enumerate(found.screened)
            if k < rows or x["shortlisted"]
        ]
        lines.append(
            table(shown, ["set", "predicted from", "predicted SSE", "simulated SSE", "BIC", "fitted"])
        )
    elif found is not None:
        lines.append(f"No combination was screened: {found.reason or 'nothing to combine'}.")
    for step in answer.growth:
        lines.append(
            f"Grown from `{step.parent}`: {step.tried} sets with one more effect tried, the best by BIC "
            f"`{step.best}`"
            + (f", held-out {number(step.held_out)} {unit(answer)}" if step.held_out is not None else "")
            + (": accepted." if step.accepted else ": not accepted.")
        )
    return "\n\n".join(lines) or "Only single effects were fitted."


def runs(answer: Answer) -> str:
    """Each run (or block of time) held out: the calibrated model's error and the answer's."""
    u = unit(answer)
    grouped = any(h.group for h in answer.held_out)
    rows = [
        {
            "run": h.scenario,
            "group": h.group or "",
            f"before [{u}]": h.before,
            f"after [{u}]": h.after,
            "change": _change(h.before, h.after),
        }
        for h in sorted(answer.held_out, key=lambda h: (h.group or "", h.scenario))
    ]
    columns = ["run", *(["group"] if grouped else []), f"before [{u}]", f"after [{u}]", "change"]
    return table(rows, columns)


def values(answer: Answer) -> str:
    """Every parameter, calibrated alone and fitted with the answer's effects, with its interval."""
    before, after = answer.calibrated, answer.fitted
    rows = [
        {
            "parameter": name,
            "calibrated": before.parameters.get(name),
            "with the answer": after.parameters.get(name),
            "95 % interval": " to ".join(number(x) for x in after.interval.get(name, [None, None])),
            "at a bound": "yes" if name in after.at_bound else "",
        }
        for name in dict.fromkeys([*before.parameters, *after.parameters])
    ]
    return table(rows, ["parameter", "calibrated", "with the answer", "95 % interval", "at a bound"])


def files(answer: Answer) -> str:
    """What was written, as the JSON lists it (figures are shown on the page instead)."""
    listed = [f"- {name}: `{path}`" for name, path in answer.files.items() if isinstance(path, str)]
    return "\n".join(listed) or "(none)"


HEADINGS: dict[Part, str] = {
    "verdict": "",
    "effects": "Named effects",
    "evidence": "Evidence",
    "candidates": "Candidates (best held-out first)",
    "search": "How the combinations were searched",
    "runs": "Held-out runs, before and after",
    "values": "Calibrated and fitted values",
    "files": "Files",
}
DRAWN = {
    "verdict": verdict,
    "effects": effects,
    "evidence": evidence,
    "candidates": candidates,
    "search": search,
    "runs": runs,
    "values": values,
    "files": files,
}


def _block(heading: str, body: str) -> list[str]:
    return [*([f"## {heading}", ""] if heading else []), body.rstrip(), ""]


def markdown(answer: Answer, sections: Sequence[Section] = ()) -> str:
    """The page: the skeleton's parts in order, each followed by the library's sections placed after it."""
    lines = [f"# Diagnosis of {answer.space or answer.library}", ""]
    for part in PARTS:
        lines += _block(HEADINGS[part], DRAWN[part](answer))
        for s in sections:
            if s.after == part:
                lines += _block(s.heading, s.body)
    return "\n".join(lines)


def files_at(report: Path, summary: Path) -> dict[str, str]:
    """Where :func:`write` puts the report, its page (beside it) and the JSON: for the answer's ``files``,
    which must name them before the JSON is written."""
    return {"report": str(report), "html": str(report.with_name(report_html.PAGE)), "json": str(summary)}


def write(answer: Answer, sections: Sections = lambda answer: ()) -> dict[str, Path]:
    """The JSON, the report (the skeleton with the library's ``sections`` of the answer) and its page, where
    the answer's ``files`` say (:func:`files_at`); their paths. The page is drawn from the JSON as written (a
    number that is not finite is null there), so drawing it again from ``diagnosis.json`` gives this page."""
    written = {k: Path(answer.files[k]) for k in ("report", "html", "json")}
    written["report"].parent.mkdir(parents=True, exist_ok=True)
    written["json"].write_text(strict_json.dumps(answer.json_dict()))
    saved = read(written["json"])
    written["report"].write_text(markdown(saved, sections(saved)))
    report_html.write(written["report"], f"Diagnosis of {saved.space or saved.library}")
    return written


def read(summary: Path) -> Answer:
    """A diagnosis' answer from its ``diagnosis.json``: what the report is drawn from, again."""
    return Answer.model_validate(json.loads(summary.read_text()))
