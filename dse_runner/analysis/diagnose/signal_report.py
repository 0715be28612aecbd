"""The report of a diagnosis of any model: one short Markdown page beside the JSON, in the out folder.

Why: the JSON is for scripts; a user reads what was named, how sure it is, what else fits alike and
where the model misses, in that order, without the field-data report's tracks and manoeuvres.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ... import strict_json
from ...simulation.values import write_values
from . import report_html
from .lookalike import CANNOT_TELL, DECIDED_BY_FIT, DECIDED_BY_LLR, DECISIVE

REPORT, SUMMARY, VALUES = "diagnosis-report.md", "diagnosis.json", "diagnosed-values.yaml"


def _number(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, (int, float)) and not isinstance(value, bool) else str(value)


def markdown_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[str]) -> list[str]:
    """A Markdown table of ``columns`` of ``rows``; numbers to four significant figures."""
    if not rows:
        return ["(none)"]
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(_number(row.get(c, "")) for c in columns) + " |" for row in rows]
    return lines


def effect_rows(effects: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """One row per fitted value: an effect's parameter, or a term's coefficient (and a friction's width)."""
    rows = []
    for e in effects:
        for kind, value in e["parameters"].items():
            low, high = e["interval"][kind]
            into = f" into {e['into']}" if e.get("into") else ""
            label = f"{e['target']} += {e['term']}" if e.get("term") else f"{e['id']}({e['target']}){into}"
            rows.append(
                {
                    "effect": label,
                    "parameter": kind,
                    "value": value,
                    "95 % interval": f"{_number(low)} to {_number(high)}",
                    "partial": e.get("partial", ""),
                }
            )
    return rows


def markdown(found: Mapping[str, Any], title: str) -> str:
    """The report's text from the diagnosis' JSON."""
    case = found.get("case") or {}  # the signal library's own fields
    located = case.get("located") or {}
    pairs = case.get("pairs") or {}
    lines = [
        f"# Diagnosis of {title}",
        "",
        f"**Verdict** {found.get('verdict_text') or found['verdict']}.",
        "",
        (
            "Error on the samples fitted (nothing could be held out) "
            if (found.get("validation") or {}).get("by") == "in sample"
            else "Held-out error "
        )
        + f"{found['held_out_before']:.3g} noise floors before (the calibrated model), "
        f"{found['held_out_after']:.3g} after; 1 is the recordings' own noise.",
        "",
        "## Compared signals",
        "",
    ]
    validation = found.get("validation") or {}
    if validation:
        lines[-2:-2] = [
            f"Validated by {validation['by']}"
            + (
                f" ({validation['folds']} folds"
                + (f" of the record {validation['record']}" if validation.get("record") else "")
                + ")"
                if validation.get("folds")
                else ""
            )
            + ".",
            "",
        ]
    lines += markdown_table(case["compared"], ["objective", "signal", "recorded", "noise"])
    for c in case["compared"]:
        estimate = c.get("noise_estimate") or {}
        if estimate:
            lines += [
                "",
                (
                    f"Noise of {c['recorded']}: σ {estimate['sigma']:.4g} by {estimate['method']}; "
                    f"it assumes {estimate['assumptions']}."
                ),
            ]
    for signal, w in (case.get("whiteness") or {}).items():
        lines += [
            "",
            f"Residuals of {signal} after: lag-1 autocorrelation {_number(w['rho1'])}, Ljung-Box p "
            f"{_number(w['p'])} over {w['lags']} lags: " + ("white." if w["white"] else "not white."),
        ]
    lines += ["", "## Named effects", ""] + markdown_table(
        effect_rows(found["effects"]), ["effect", "parameter", "value", "95 % interval", "partial"]
    )
    terms = [line for e in found["effects"] for line in e.get("readable") or []]
    if terms:
        lines += ["", "Inside the model:", ""] + [f"- {t}" for t in terms]
    pinned = (found.get("fitted") or {}).get("at_bound") or []
    if pinned:
        lines += [
            "",
            (
                "At a bound of its interval, not an estimate (the recordings push it further; widen the "
                f"interval or doubt the model): {', '.join(pinned)}."
            ),
        ]
    for d in case.get("decided") or []:
        errors = d["held_out"]
        lines += [
            "",
            (
                f"Look-alike: {d['lookalike']} (held-out {errors[d['lookalike']]:.3g} noise floors) lost to "
                f"{d['winner']} ({errors[d['winner']]:.3g}); each fitted in the other's place with the rest "
                "of the answer."
            ),
        ]
    by_rule: dict[str, list[str]] = {}
    for d in found.get("dropped") or []:
        by_rule.setdefault(d["rule"], []).append(d["id"])
    for rule, ids in by_rule.items():
        lines += ["", f"Not claimed ({rule}): {', '.join(ids)}."]
    lines += ["", "## Candidates (best held-out first)", ""]
    lines += markdown_table(found["candidates"][:8], ["id", "held_out", "bic"])
    failed = [c for c in found["candidates"] if c.get("error")]
    rejected = {c["id"]: c["error"] for c in failed}
    if rejected:
        lines += [
            "",
            "Rejected, their fits could not start: "
            + "; ".join(f"{k} ({v})" for k, v in rejected.items())
            + ".",
        ]
    lines += ["", f"Runner-up: {(found.get('runner_up') or {}).get('id') or 'none'}.", ""]
    for step in case.get("growth") or []:
        lines += [
            f"Grown from {step['from']}: {step['tried']} sets with one more effect tried, the best "
            f"{step['best']}"
            + (f", held-out {step['held_out']:.3g}" if "held_out" in step else "")
            + (": accepted." if step.get("accepted") else ": not accepted."),
            "",
        ]
    if pairs.get("screened"):
        lines += [
            (
                f"Pairs: {pairs['predicted']} predicted from the single fits, "
                f"{len(pairs['screened'])} checked by simulation, {len(pairs['fitted'])} "
                f"fitted for real ({', '.join(pairs['fitted']) or 'none'})."
            ),
            "",
        ]
    elif pairs:
        lines += [f"Pairs: not screened ({pairs.get('reason', '')}).", ""]
    looks = found.get("lookalikes") or []
    if looks:
        lines += ["## Look-alikes", ""]
        for x in looks:
            where = "; ".join(
                f"{w['scenario']} {w['start']:.3g}-{w['stop']:.3g} s ({w['input']}, "
                f"{w['delta_mean_square']:+.3g})"
                for w in x["telling_windows"][:3]
            )
            lines.append(
                f"- {x['id']} fits alike ({x['held_out']:.3g} held-out, {x['runs_better']} runs better "
                f"for the chosen); "
                + _llr_words(x.get("segment_llr"))
                + (
                    f"differs most in {where}"
                    if where
                    else "no window tells them apart by more than the noise"
                )
            )
        lines.append("")
    if located:
        lines += [
            "## Where the model misses",
            "",
            located["method"][:1].upper() + located["method"][1:] + ".",
            "",
            "By run (noise floors):",
            "",
        ]
        lines += markdown_table(
            located["by_scenario"], ["signal", "scenario", "samples", "floors_before", "floors_after"]
        )
        lines += ["", "By what the inputs do:", ""]
        lines += markdown_table(
            located["by_input"], ["signal", "input", "windows", "floors_before", "floors_after"]
        )
        lines += ["", "Worst windows before:", ""]
        lines += markdown_table(
            located["worst"],
            ["signal", "scenario", "start", "stop", "input", "floors_before", "floors_after"],
        )
    return "\n".join(lines) + "\n"


def write(
    found: Mapping[str, Any], folder: Path, title: str, figures: Sequence[Path] = ()
) -> dict[str, Path]:
    """Write the report, the strict JSON summary and the diagnosed model's values into ``folder``; their
    paths. The values file is the model the recordings support, ready to run again:
    ``dse-runner simulate MODEL --scenario … --values diagnosed-values.yaml``. ``figures`` (inside ``folder``)
    are shown in the report and listed in the JSON."""
    folder.mkdir(parents=True, exist_ok=True)
    files = {
        "report": folder / REPORT,
        "html": folder / report_html.PAGE,
        "json": folder / SUMMARY,
        "values": folder / VALUES,
    }
    found = {
        **found,
        "files": {
            **{k: str(v) for k, v in files.items()},  # the file says where its siblings are
            "figures": [str(f) for f in figures],
        },
    }
    text = markdown(found, title)
    if figures:
        text += "\n## Recorded against simulated\n\n" + "".join(
            f"![{f.stem}]({f.relative_to(folder).as_posix()})\n\n" for f in figures
        )
    files["report"].write_text(text)
    files["html"] = report_html.write(files["report"], f"Diagnosis of {title}")
    files["json"].write_text(strict_json.dumps(found))
    write_values(
        files["values"],
        found["fitted"]["parameters"],
        f"The diagnosed model of {title}: its calibrated parameters, and the effects and derivative\n"
        f"terms the recordings support ({found['verdict']}), as fitted together. Run it again with\n"
        f"dse-runner simulate SPACE.yaml --scenario NAME --values {VALUES}, or put it in a "
        "space's parameters.",
    )
    return files


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
