"""The report of any diagnosis: one Markdown page and its HTML twin, drawn from the answer's JSON alone.

Why: every library answers in one shape (answer.py), so the page a user reads is laid out once, here, in
one order: the verdict, the held-out error before and after against the noise floor, the named effects with
their intervals, the evidence (the runner-up, what was not claimed, the proof of searched terms), the
candidates, each held-out run, the values calibrated and fitted, the files. A library adds only what is its
own: :class:`Section` s, each placed after one of those parts (``HypothesisLibrary.sections``), and its
figures. Reading nothing but the JSON, the page can be drawn again from ``diagnosis.json``.

Two parts whose evidence is the engine's but which a library places among its sections are drawn here too,
in the library's words: the look-alikes (:func:`lookalikes_part`, lookalike.py's twins in a library's
:class:`LookalikeWords`) and the search beyond the library (:func:`discovery_part`, discovery.py's, after
the library's description of its search).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

from ... import strict_json
from . import report_html
from .answer import Answer, Effect, Evidence, Proof
from .explain import TIE
from .lookalike import CANNOT_TELL, DECIDED_BY_FIT, DECIDED_BY_LLR, DECISIVE
from .sparse_regression import PRUNE_SE

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


# ---- parts a library places among its sections: look-alikes, discovery -----------------------------


class LookalikeWords:
    """A library's words on its look-alikes (:func:`lookalikes_part`, :func:`twins_sentence`): what its
    segment kinds are called (a kind not named is shown as it is), what one sample is
    (lookalike.Twins.sample: the JSON's ``autocorrelation_<sample>`` and the count per segment), what σ is,
    and its opening (which twins it weighs and how it reads the segments). Optional hooks, each saying
    nothing by default, add what only the library knows of one pair (an entry of ``Answer.lookalikes``, as
    the library wrote it)."""

    segments: ClassVar[Mapping[str, str]] = {}
    sample: ClassVar[str] = "samples"
    noise: ClassVar[str] = "the noise floor"
    intro: ClassVar[str] = ""

    def segment(self, kind: str) -> str:
        return self.segments.get(kind, kind)

    def twins(self, look: Mapping[str, Any]) -> Mapping[str, Any] | None:
        """The engine's evidence in an entry (lookalike.Twins.to_json): the entry itself, unless the library
        keeps it under a key of its own; None where the pair could not be weighed."""
        return look

    def about(self, look: Mapping[str, Any]) -> str:
        """Its own sentences on a pair, after the engine's (what tells the two apart, in its terms)."""
        return ""

    def more(self, look: Mapping[str, Any]) -> str:
        """Its own paragraphs after a pair's table of evidence by segment (response fits, say)."""
        return ""

    def advice(self, look: Mapping[str, Any]) -> str:
        """What would tell apart twins that cannot be told apart on these runs, for :func:`twins_sentence`."""
        return ""


HOW_DECIDED = {  # lookalike.decision -> how the twins were told apart, in words
    DECIDED_BY_FIT: "held-out error and BIC already separate them, and the LLR is reported as a check",
    DECIDED_BY_LLR: f"held-out error and BIC do not separate them; the LLR does (|LLR| ≥ {DECISIVE:g})",
    CANNOT_TELL: f"neither held-out error and BIC nor the LLR (below {DECISIVE:g}) separates them: cannot "
    "tell on these runs",
}


def strongest(twins: Mapping[str, Any], words: LookalikeWords) -> str:
    """The segment kind that carries most of the evidence, in words, with its share of the LLR."""
    by_kind = twins["by_segment"]
    if not by_kind:
        return ""
    kind = max(by_kind, key=lambda k: abs(by_kind[k]["llr"]))
    return f"mostly on {words.segment(kind)} ({by_kind[kind]['llr']:+.1f})"


def twins_sentence(look: Mapping[str, Any], words: LookalikeWords) -> str:
    """The verdict between twins that held-out error and BIC could not separate, in one sentence, for a
    library to place under the verdict; empty where they could (or the pair was not weighed)."""
    twins = words.twins(look)
    if not twins or twins["decision"] == DECIDED_BY_FIT:
        return ""
    a, b = twins["pair"]
    llr = twins["llr"]
    if twins["decision"] == DECIDED_BY_LLR:
        loser = b if twins["favours"] == a else a
        return (
            f"**Look-alikes:** {ids(twins['favours'])} rather than its look-alike {ids(loser)}: held-out "
            f"error and BIC cannot separate them, but the {words.sample} can (LLR {abs(llr):.1f} in its "
            f"favour, {strongest(twins, words)})."
        )
    advice = words.advice(look)
    return (
        f"**Look-alikes:** {ids(a)} or its look-alike {ids(b)}: cannot tell on these runs (LLR {llr:+.1f}, "
        f"below the {DECISIVE:g} that decides)" + (f";{advice}" if advice else "") + "."
    )


def twins_text(twins: Mapping[str, Any], words: LookalikeWords, u: str) -> str:
    """The evidence between one pair of twins and how it was used."""
    a, b = twins["pair"]
    x, y = twins["effects"]
    tau = twins[f"autocorrelation_{words.sample}"]
    how = HOW_DECIDED.get(twins["decision"], twins["decision"])
    return (
        f"{ids(a)} against {ids(b)} (swapping `{x}` for `{y}`): LLR {twins['llr']:+.1f}, in favour of "
        f"{ids(twins['favours'])}, {strongest(twins, words)}; {how}. "
        f"σ = {twins['sigma']:.4f} {u}, autocorrelation time {tau:.1f} {words.sample}."
    )


def lookalikes_part(answer: Answer, words: LookalikeWords) -> str:
    """Each pair of twins (``answer.lookalikes``): the evidence between them, segment by segment, with the
    library's own words on it; empty when there are none."""
    if not answer.lookalikes:
        return ""
    s = words.sample
    lines = [
        (
            f"{words.intro} The log-likelihood ratio (LLR) is the difference of their squared residuals over "
            f"2σ² (σ {words.noise}), divided by the residuals' autocorrelation time in {s}, since successive "
            f"{s} of a smooth residual are not independent evidence. Positive favours the first set. When "
            f"held-out error and BIC cannot separate the two, |LLR| ≥ {DECISIVE:g} (about "
            f"{round(math.exp(DECISIVE), -1):g} to 1) decides; below it the diagnosis names both."
        ).strip(),
        "",
    ]
    for look in answer.lookalikes:
        twins = words.twins(look)
        said = [twins_text(twins, words, unit(answer))] if twins else []
        lines += [" ".join([*said, words.about(look)]).strip(), ""]
        if twins:
            a, b = twins["pair"]
            rows = [
                {"segment": words.segment(k), s: v[s], f"LLR ({a} over {b})": v["llr"]}
                for k, v in twins["by_segment"].items()
            ]
            lines += [table(rows, ["segment", s, f"LLR ({a} over {b})"]), ""]
        more = words.more(look)
        if more:
            lines += [more, ""]
    return "\n".join(lines)


RESPONSE = {  # a response fit's JSON key (response.ResponseFit.to_json) -> its column, after its samples
    "sse": "SSE as modelled",
    "delay": "delay [s]",
    "delay_sse": "SSE delay",
    "lag": "lag [s]",
    "lag_sse": "SSE lag",
    "gain": "gain",
    "gain_sse": "SSE gain",
    "best": "best",
}


def response_table(fits: Sequence[Mapping[str, Any]], words: LookalikeWords) -> str:
    """Response fits (response.py), one row per segment kind: the SSE as modelled, and the delay, lag and
    gain that fit best with theirs."""
    s = words.sample
    rows = [
        {"segment": words.segment(r["segment"]), s: r[s], **{RESPONSE[k]: r[k] for k in RESPONSE}}
        for r in fits
    ]
    return table(rows, ["segment", s, *RESPONSE.values()])


def discovery_part(answer: Answer, found: Mapping[str, Any] | None, search: str, skipped: str) -> str:
    """What the search beyond the library did (``found``: discovery.Discovery.to_json), after the library's
    description of its search (``search``); or, when nothing was sought, why (``skipped``)."""
    if found is None:
        return f"No correction was sought: {skipped}." if skipped else ""
    u, proposed = unit(answer), "; ".join(found["proposed_text"])
    lines = [
        (
            f"{search} The proposed terms were then fitted with the calibrated parameters, pruned to "
            f"those {PRUNE_SE:g} standard errors from zero, re-proposed inside each fold on its training "
            "runs only, and judged by the library's rule, the BIC margin raised to "
            f"{found['bic_margin']:.1f} for the search (extended BIC)."
        ).strip(),
        f" Proposed from every run: {('`' + proposed + '`') if proposed else 'nothing'}.",
    ]
    for c in found["tried"]:
        lines.append(
            f" `{c['id']}`: "
            + "; ".join(c["text"])
            + f", held-out {c['held_out']:.4f} {u}, ΔBIC {c['bic'] - found['bic_reference']:+.1f} against "
            f"`{found['reference']}` ({found['held_out_reference']:.4f} {u})."
        )
    if found["chosen"] is None:
        lines.append(f" Nothing was accepted: {found['reason']}.")
    else:
        lines.append(f" Accepted: `{found['chosen']}`; it {found['resembles']}.")
    if found.get("proof") and found["proof"]["folds"]:
        lines.append(" " + proof(Proof.model_validate(found["proof"]), u))
    return "".join(lines)


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
