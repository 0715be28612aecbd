"""Show: the diagnosis as a Markdown report with figures and a JSON twin.

<out>/report/report.md        locate, explain, model, show (held-out Table 1)
<out>/report/diagnosis.json   what ``dse-runner diagnose --json`` prints
<out>/report/figures/*.png    residual signatures, tracks, held-out errors
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ... import strict_json
from ...analysis.diagnose import explain, report_html
from ...analysis.diagnose.explain import Candidate
from ...analysis.diagnose.findings import DiscoveredCorrection
from ...analysis.diagnose.validation import record_of
from ...sweeps.rank import format_point
from ...sweeps.spec import Space
from .. import fielddata
from . import correction, discover, locate, lookalike
from .hypotheses import LIBRARY
from .noise import AT_REST, CLOSE_FIXES, MAX_SPACING

if TYPE_CHECKING:
    from .outcome import Diagnosis


def _table(frame: pd.DataFrame, digits: int = 3) -> str:
    """A DataFrame as a Markdown table (pandas' to_markdown needs tabulate, which we do not ship)."""

    def cell(v: Any) -> str:
        if isinstance(v, float):
            return (
                "inf"
                if math.isinf(v)
                else f"{v:.{digits}g}"
                if abs(v) < 1e-3 and v != 0
                else f"{v:.{digits}f}"
            )
        return str(v)

    head = "| " + " | ".join(map(str, frame.columns)) + " |"
    rule = "|" + "---|" * len(frame.columns)
    rows = ["| " + " | ".join(cell(v) for v in row) + " |" for row in frame.itertuples(index=False)]
    return "\n".join([head, rule, *rows])


def _candidates(diagnosis: Diagnosis) -> pd.DataFrame:
    base = diagnosis.baseline
    rows = []
    for c in diagnosis.candidates:
        effect = {
            k.split(".", 1)[1]: v
            for k, v in c.full.values.items()
            if k.split(".", 1)[1]
            in {p for hid in discover.library_ids(c.ids) for p in LIBRARY[hid].variables}
            or correction.is_correction(k)
        }
        validated = c.validated and math.isfinite(c.cross_validated)
        rows.append(
            {
                "candidate": c.label,
                "held-out error [m]": c.cross_validated if validated else "not cross-validated",
                "vs none": f"{(c.cross_validated / base.cross_validated - 1) * 100:+.1f} %"
                if validated
                else "-",
                "ΔBIC vs none": c.bic - base.bic,
                "effect parameters": ", ".join(f"{k} = {v:.4g}" for k, v in effect.items()) or "-",
                "chosen": "yes" if c is diagnosis.chosen else "",
            }
        )
    return pd.DataFrame(rows)


def held_out_table(baseline: Candidate, chosen: Candidate, space: Space) -> pd.DataFrame:
    """The paper's Table 1 style, on runs each fit did not see: before and after per scenario."""
    groups = {s.name: s.group for s in space.scenarios}
    group = {s: groups[record_of(s)] for s in baseline.held_out}  # a time block: its run's
    rows = [
        {
            "scenario": s,
            "group": group[s],
            "before [m]": baseline.held_out[s],
            "after [m]": chosen.held_out[s],
            "change": f"{(chosen.held_out[s] / baseline.held_out[s] - 1) * 100:+.1f} %",
        }
        for s in sorted(baseline.held_out, key=lambda n: (group[n], n))
    ]
    return pd.DataFrame(rows)


def signature(frames: dict[str, pd.DataFrame]) -> dict[str, Any]:
    """What changed between the calibrated model's residuals and the chosen model's."""
    before, after = (locate.by_segment(frames[k]).set_index("segment") for k in ("before", "after"))
    columns = ["along_rms", "cross_rms", "along_growth_rms", "cross_growth_rms"]
    drop = (before[columns] - after[columns].reindex(before.index)).stack()
    (segment, component), amount = drop.idxmax(), float(drop.max())
    return {
        "segment": segment,
        "component": component,
        "before": float(before.loc[segment, component]),
        "after": float(before.loc[segment, component] - amount),
        "correlations": locate.strongest(locate.correlations(frames["before"])),
    }


def _figures(
    folder: Path,
    space: Space,
    frames: dict[str, pd.DataFrame],
    tracks: dict[str, dict[str, pd.DataFrame]],
    x: str,
    y: str,
    held_out: pd.DataFrame,
    chosen_label: str,
) -> dict[str, Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    names = [s.name for s in space.scenarios]
    files = {}

    fig, axes = plt.subplots(len(names), 2, figsize=(11, 1.9 * len(names)), sharex="row", squeeze=False)
    for row, name in enumerate(names):
        for col, component in enumerate(["along", "cross"]):
            ax = axes[row][col]
            for key, colour in (("before", "tab:red"), ("after", "tab:blue")):
                part = frames[key][frames[key]["scenario"] == name]
                label = "calibrated baseline" if key == "before" else chosen_label
                ax.plot(part["time"], part[component], color=colour, lw=1, label=label)
            ax.axhline(0, color="0.6", lw=0.5)
            ax.set_ylabel(f"{name}\n{component} [m]", fontsize=8)
    axes[0][0].set_title("along-track residual (recorded ahead of model > 0)", fontsize=9)
    axes[0][1].set_title("cross-track residual (recorded left of model > 0)", fontsize=9)
    axes[0][1].legend(fontsize=7, loc="upper left")
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    fig.tight_layout()
    files["residuals"] = folder / "residuals.png"
    fig.savefig(files["residuals"], dpi=80)
    plt.close(fig)

    cols = 4
    rows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.2 * rows), squeeze=False)
    for ax, scenario in zip(axes.flat, space.scenarios):
        gps = fielddata.gps(scenario)
        ax.plot(gps.x, gps.y, ".", color="k", ms=1.5, label="GPS")
        for key, colour in (("before", "tab:red"), ("after", "tab:blue")):
            frame = tracks[key][scenario.name]
            ax.plot(
                frame[x],
                frame[y],
                color=colour,
                lw=1,
                label="calibrated baseline" if key == "before" else chosen_label,
            )
        ax.set_title(scenario.name, fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(names) :]:
        ax.axis("off")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    files["tracks"] = folder / "tracks.png"
    fig.savefig(files["tracks"], dpi=80)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(max(6, 0.6 * len(names)), 3.2))
    index = np.arange(len(held_out))
    ax.bar(index - 0.2, held_out["before [m]"], 0.4, color="tab:red", label="calibrated baseline")
    ax.bar(index + 0.2, held_out["after [m]"], 0.4, color="tab:blue", label=chosen_label)
    ax.set_xticks(index, held_out["scenario"], rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("held-out cross-track error [m]")
    ax.legend(fontsize=8)
    fig.tight_layout()
    files["held_out"] = folder / "held_out.png"
    fig.savefig(files["held_out"], dpi=80)
    plt.close(fig)
    return files


def write(
    diagnosis: Diagnosis,
    space: Space,
    frames: dict[str, pd.DataFrame],
    before: dict[str, pd.DataFrame],
    after: dict[str, pd.DataFrame],
) -> dict[str, Path]:
    folder = diagnosis.out / "report"
    vehicle = diagnosis.calibration["vehicle"]
    held_out = held_out_table(diagnosis.baseline, diagnosis.chosen, space)
    chosen_label = (
        "with " + diagnosis.chosen.label if diagnosis.chosen.ids else "calibrated baseline (no effect)"
    )
    figures = _figures(
        folder / "figures",
        space,
        frames,
        {"before": before, "after": after},
        f"{vehicle}.gps_x",
        f"{vehicle}.gps_y",
        held_out,
        chosen_label,
    )
    sig = signature(frames)
    located = {
        "by_group": locate.by_group(frames["before"]),
        "by_segment": locate.by_segment(frames["before"]),
        "by_scenario": locate.by_scenario(frames["before"]),
        "correlations": locate.correlations(frames["before"]),
    }
    diagnosis.located = {k: json.loads(v.to_json(orient="split")) for k, v in located.items()}
    diagnosis.located["signature"] = sig
    text = _markdown(
        diagnosis, located, sig, held_out, {k: p.relative_to(folder) for k, p in figures.items()}
    )
    report = folder / "report.md"
    report.write_text(text)
    page = report_html.write(report, f"Diagnosis of {diagnosis.calibration['sweep']}")
    files = {"report": report, "html": page, **{f"figure_{k}": p for k, p in figures.items()}}
    diagnosis.files.update(files)
    summary = folder / "diagnosis.json"
    summary.write_text(strict_json.dumps(diagnosis.to_json()))
    return {**files, "json": summary}


def _markdown(
    diagnosis: Diagnosis,
    located: dict[str, pd.DataFrame],
    sig: dict[str, Any],
    held_out: pd.DataFrame,
    figures: dict[str, Path],
) -> str:
    cal = diagnosis.calibration
    chosen = diagnosis.chosen
    lines = [
        f"# Discrepancy diagnosis: {cal['sweep']}",
        "",
        f"Runs: {len(held_out)} in {held_out['group'].nunique()} groups; cross-validation folds: "
        + "; ".join(", ".join(f) for f in cal["folds"])
        + ".",
        "",
    ]
    if chosen.ids:
        lines += [
            "**Finding:** "
            + "; ".join(
                f"`{f.id}` ({f.name}): "
                + (
                    ", ".join(t["text"] for t in f.terms)
                    if isinstance(f, DiscoveredCorrection)
                    else f.described()
                )
                for f in diagnosis.findings
            )
            + f". Held-out mean cross-track error {diagnosis.cross_track_before:.3f} m → "
            f"{diagnosis.cross_track_after:.3f} m.",
            "",
        ]
    else:
        lines += [
            (
                "**Finding:** `none`: no hypothesis of the library passes the "
                "test against the calibrated model (held-out mean cross-track "
                f"error {diagnosis.cross_track_before:.3f} m). Nothing is added."
            ),
            "",
        ]
    lines += [verdict_text(diagnosis), ""]
    lines += [
        line
        for look in diagnosis.lookalikes
        if look.decision != lookalike.DECIDED_BY_FIT
        for line in (twins_sentence(look), "")
    ]

    lines += [
        "## 1. Locate",
        "",
        (
            f"Calibration grid best point: {format_point(cal['grid_best'], 5)}; parameters "
            f"at a bound of the design space: {', '.join(cal['grid_at_bound']) or 'none'}."
        ),
        (
            f"Refined by least squares within the design space: {format_point(cal['refined'], 5)}; "
            f"at a bound: {', '.join(cal['refined_at_bound']) or 'none'}."
        ),
        (
            "Parameters no run responds to (any value fits equally well): "
            f"{', '.join(cal['no_effect']) or 'none'}."
        ),
        (
            "Runs no tuned parameter can improve (every grid point within 5 % of the calibrated error): "
            f"{', '.join(cal['insensitive_scenarios']) or 'none'}."
        ),
        "",
        "Residuals of the calibrated model, by scenario group:",
        "",
        _table(located["by_group"]),
        "",
        "By segment of the motion:",
        "",
        _table(located["by_segment"]),
        "",
        "Correlation of the residuals and of their growth rates with the motion:",
        "",
        _table(located["correlations"].reset_index().rename(columns={"index": "residual"}), 2),
        "",
        "Strongest: " + "; ".join(f"{c} with {f} (r = {r:+.2f})" for c, f, r in sig["correlations"]) + ".",
        "",
        f"![residual signatures]({figures['residuals']})",
        "",
        "## 2. Explain",
        "",
        (
            "Every hypothesis of the library fitted jointly with the calibrated parameters; held-out "
            "error is the mean Equation 1 error of each run predicted by the fit on the other folds. A "
            "candidate is chosen only if it lowers the held-out error by at least "
            f"{diagnosis.settings.min_gain:.0%} and the BIC by at least {diagnosis.settings.bic_margin:g} "
            "against `none` and against every fitted part of it (each member has to pay its way); of "
            f"those, the lowest held-out error wins, and one within {diagnosis.settings.min_gain:.0%} of "
            "it with fewer effects wins over it. Combinations fitted on every run but not "
            f"cross-validated failed the BIC gate: their BIC was not {diagnosis.settings.bic_margin:g} "
            "below the best single answer's and each fitted part's, so they could not be chosen."
        ),
        "",
        _table(_candidates(diagnosis)),
        "",
    ]
    lines += ["### Screen of combinations", "", screen_text(diagnosis), ""]
    if diagnosis.screened:
        lines += [_table(_screened(diagnosis)), ""]
    lines += ["### Noise floor", "", noise_text(diagnosis), ""]
    lines += ["### Discovery beyond the library", "", discovery_text(diagnosis), ""]
    up = diagnosis.runner_up
    lines += [
        "### Runner-up",
        "",
        runner_up_text(up, diagnosis.chosen.label, diagnosis.settings)
        if up
        else "No other candidate was fitted that is not part of the chosen one.",
        "",
    ]
    if diagnosis.lookalikes:
        lines += ["### Look-alikes", "", LOOKALIKE_INTRO, ""]
        for look in diagnosis.lookalikes:
            lines += [lookalike_text(look), "", _table(_by_segment(look), 2), ""]
            if look.response:
                lines += [response_text(look), "", _table(_responses(look)), ""]
    for e in diagnosis.effects:
        if e["id"] not in LIBRARY:
            continue
        h = LIBRARY[e["id"]]
        lines += [f"### `{h.id}`: {h.name}", "", h.explanation, "", f"Expected signature: {h.signature}.", ""]
    if chosen.ids:
        lines += [
            (
                f"Observed: the residual fell most in {sig['component']} on {sig['segment']} segments, "
                f"from {sig['before']:.3f} to {sig['after']:.3f} (rms)."
            ),
            "",
            "## 3. Model",
            "",
            "The chosen effect is part of the vehicle's effects variant "
            "(`bundled:fmus/robotti_vehicle_effects`: the checkout's top-level `fmus/`, "
            f"shipped inside the package). Written: `{diagnosis.files['multimodel'].name}` "
            f"and `{diagnosis.files['space'].name}` (the calibration with the effect's "
            "parameters added); `dse-runner submit space.yaml` re-calibrates with it."
            + (
                " The discovered terms are coefficients `corr_*` of the same variant's correction block, "
                "written over their ~95 % intervals like the effects' parameters."
                if diagnosis.discovered
                else ""
            ),
            "",
        ]
    lines += [
        "## 4. Show: held-out runs before and after",
        "",
        _table(held_out),
        "",
        f"![held-out errors]({figures['held_out']})",
        "",
        f"![tracks]({figures['tracks']})",
        "",
    ]
    return "\n".join(lines)


def _screened(diagnosis: Diagnosis, rows: int = 12) -> pd.DataFrame:
    """The best screened sets, and every shortlisted one: predicted against simulated SSE."""
    shown = [x for k, x in enumerate(diagnosis.screened) if k < rows or x.label in diagnosis.shortlisted]
    return pd.DataFrame(
        [
            {
                "set": x.label,
                "linearised at": "+".join(x.anchor) or "none",
                "predicted SSE [m²]": x.predicted_sse,
                "simulated SSE [m²]": x.sse,
                "BIC": x.bic,
                "fitted": "yes" if x.label in diagnosis.shortlisted else "",
            }
            for x in shown
        ]
    )


def screen_text(diagnosis: Diagnosis) -> str:
    """What the screen did, or why it did not run."""
    settings = diagnosis.settings
    if not diagnosis.screened:
        return (
            "No combination was screened: a fit of none or of one effect already left at most "
            f"{settings.floor_stop:g}× the noise floor of error on the runs it was fitted to (nothing a "
            "combination could clearly add), or the settings allow one effect at a time."
        )
    pairs = sum(len(x.ids) == 2 for x in diagnosis.screened)
    triples = len(diagnosis.screened) - pairs
    return (
        f"{pairs} pairs and {triples} triples (those extending the best predicted pairs) were screened "
        "without fitting them: from the Jacobian of the fix residuals at `none` and at the two best "
        "single fits (taken whether or not they passed alone, as masked effects do not), the bounded "
        "linear least-squares step for each set, calibrated parameters free too, predicts its SSE; "
        "simulating that step and half of it gives the SSE it really reaches. Ranked by the BIC of that "
        f"SSE, the best {settings.pairs} pairs and {settings.triples} triples, and the sets in which a "
        f"member is swapped for its look-alike, were fitted for real (at most {settings.shortlist}; two "
        "more pairs when the best set's simulated SSE was over twice its prediction): "
        + ", ".join(f"`{label}`" for label in diagnosis.shortlisted)
        + "."
    )


def _ids(label: str) -> str:
    return " + ".join(f"`{h}`" for h in label.split("+"))


def verdict_text(diagnosis: Diagnosis) -> str:
    """The verdict in an engineer's words: the chosen model's held-out error against the noise floor."""
    verdict, floor = diagnosis.verdict, diagnosis.floor
    after = diagnosis.cross_track_after
    factor = diagnosis.settings.noise_factor
    chosen = _ids(diagnosis.chosen.label) if diagnosis.chosen.ids else ""
    if not floor.available:
        return (
            f"**Verdict: {verdict}.** The GPS noise could not be estimated from these recordings (no three "
            "consecutive close fixes and no stop), so the residual is not weighed against it: read the "
            "finding as the best of the library, not as proof that nothing else is missing."
        )
    level = f"{after:.3f} m, {diagnosis.floor_ratio:.1f}× the noise floor of {floor.cross_track:.3f} m"
    remains = after - floor.cross_track
    if diagnosis.discovered:
        return discovered_text(diagnosis)
    if verdict == explain.EXPLAINED:
        return (
            f"**Verdict: explained.** With {chosen} the held-out error is {level}; up to {factor:g}× counts "
            "as noise, so what remains is receiver noise or too close to it to tell apart."
        )
    if verdict == explain.PARTIAL:
        return (
            f"**Verdict: partial.** The runs support {chosen}, but it is not the whole story: after it the "
            f"held-out error is {level}, above the {factor:g}× that counts as noise. The library does not "
            f"explain the residual: about {remains:.3f} m of mean cross-track error remains above the noise. "
            "Read the effect as part of the cause, not as the cause."
        )
    if verdict == explain.UNEXPLAINED:
        return (
            "**Verdict: unexplained.** No hypothesis of the library explains the residual, and it is "
            f"not noise: the calibrated model's held-out error is {level}, above the {factor:g}× that "
            f"counts as noise; about {remains:.3f} m of mean cross-track error remains unexplained."
        )
    return (
        f"**Verdict: none.** Nothing is missing: the calibrated model's held-out error is {level}, within "
        f"the {factor:g}× that counts as noise."
    )


def _without(diagnosis: Diagnosis) -> str:
    library = diagnosis.library
    return f"with {_ids(library.label)}" if library.ids else "with the calibrated model alone"


def discovered_text(diagnosis: Diagnosis) -> str:
    """The verdict when a discovered correction passed: the library falls short, and by how much; the term;
    and, when the correction too leaves a residual above the noise (verdict partial), how much remains."""
    floor, library, chosen = diagnosis.floor, diagnosis.library, diagnosis.chosen
    entry = next(e for e in diagnosis.effects if e["id"] == discover.DISCOVERED)
    remains = library.cross_validated - floor.cross_track
    gain = 100.0 * (1.0 - chosen.cross_validated / library.cross_validated)
    named = [e for e in diagnosis.effects if e["id"] != discover.DISCOVERED]
    whole = diagnosis.verdict == explain.DISCOVERED
    part = (
        " Read " + ", ".join(f"`{e['id']}`" for e in named) + " as part of the cause, not as the cause."
        if named
        else ""
    )
    resembles = entry["resembles"]["text"] if entry["resembles"] else "was not compared with the library"
    left = (
        f" It is not the whole story either: about {chosen.cross_validated - floor.cross_track:.3f} "
        "m of mean cross-track error remains above the noise, which the correction block's terms "
        "do not express; read the correction as part of the cause."
        if not whole
        else ""
    )
    return (
        f"**Verdict: {diagnosis.verdict}.** The library does not explain the residual: "
        f"{_without(diagnosis)} the held-out error is {library.cross_validated:.3f} m, "
        f"{library.cross_validated / floor.cross_track:.1f}× the noise floor of "
        f"{floor.cross_track:.3f} m, so about {remains:.3f} m of mean cross-track error remains "
        f"above the noise. A data-driven correction explains {'most' if whole else 'part'} of it: "
        + "; ".join(f"`{t}`" for t in entry["readable"])
        + f". With it the held-out error is {chosen.cross_validated:.3f} m ({gain:.0f} % lower, "
        f"{chosen.cross_validated / floor.cross_track:.1f}× the floor), on runs the fits did not see, and it "
        f"passed the same rule as the library's effects. It {resembles}.{part}{left}"
    )


def discovery_text(diagnosis: Diagnosis) -> str:
    """What discovery did, or why it did not run."""
    found, settings = diagnosis.discovery, diagnosis.settings
    if found is None:
        why = (
            "it is switched off (`--no-discovery`)"
            if not settings.discovery
            else f"the library's answer is within {settings.noise_factor:g}× the noise floor (or no floor "
            "could be estimated), so there is nothing a correction could claim but noise"
        )
        return f"No correction was sought: {why}."
    intro = (
        "The library's best answer left held-out error well above the noise, so a sparse correction "
        "was sought among the terms of the effects variant's correction block: the equation error of "
        "the recorded speed and yaw rate (from the fixes alone) against the reference's quasi-static "
        "answer, regressed on the block's features at the reference's state by PySINDy's STLSQ, with "
        "the threshold chosen by leave-one-run-out error and each term kept only if a seeded bootstrap "
        f"over runs picks it in {discover.INCLUSION:.0%} of the resamples. The proposed terms were then "
        "fitted on positions with the calibrated parameters, pruned to those two standard errors from "
        "zero, re-proposed inside each fold on its training runs only, and judged by the library's "
        f"rule, the BIC margin raised to {found.margin:.1f} for the search (extended BIC)."
    )
    proposed = "; ".join(found.proposal.readable()) if found.proposal else ""
    lines = [intro, f" Proposed from every run: {('`' + proposed + '`') if proposed else 'nothing'}."]
    for c in found.candidates:
        lines.append(
            f" `{c.label}`: "
            + "; ".join(correction.readable(c.full.point))
            + f", held-out {c.cross_validated:.4f} m, ΔBIC {c.bic - found.reference.bic:+.1f} against "
            f"`{found.reference.label}` ({found.reference.cross_validated:.4f} m)."
        )
    if found.chosen is None:
        lines.append(f" Nothing was accepted: {found.reason}.")
    else:
        lines.append(f" Accepted: `{found.chosen.label}`; it {discover.resemblance_words(found.resembles)}.")
    proof = found.proof
    if proof is not None and proof.chosen:
        lines.append(
            f" Proof: {proof.agree} of {len(proof.chosen)} folds, choosing among {proof.offered} terms on "
            f"their training runs alone, chose these terms again; their own choices predicted the held-out "
            f"runs with {proof.error:.4f} m."
        )
    return "".join(lines)


def noise_text(diagnosis: Diagnosis) -> str:
    """How the floor was estimated, from the recordings alone."""
    floor = diagnosis.floor
    if not floor.available:
        return (
            "Not available: no run has three consecutive fixes at most "
            f"{MAX_SPACING:g} s apart, nor a stop with enough fixes."
        )
    parts = []
    close, rest = floor.estimates.get(CLOSE_FIXES), floor.estimates.get(AT_REST)
    if close:
        parts.append(
            f"σ = {close.sigma:.4f} m per axis from the second differences at {close.fixes} fixes whose "
            "neighbours are equally close with no dropout between them (robust median absolute deviation, "
            "pooled over x, y and runs; speed cancels, and acceleration adds at most millimetres)"
        )
    if rest:
        colour = (
            ""
            if floor.rho1 is None
            else f"; lag-1 autocorrelation {floor.rho1:.2f}, "
            + ("coloured noise, which second differences under-estimate" if floor.rho1 > 0.3 else "white")
        )
        parts.append(
            f"σ = {rest.sigma:.4f} m from the spread of {rest.fixes} fixes while the "
            "commanded speed was 0 and the vehicle stood still (or crept at a steady "
            f"speed: the spread is taken about a straight line in time){colour}"
        )
    per_run = list(floor.per_run.values())
    spread = f" Per run, σ lies between {min(per_run):.4f} and {max(per_run):.4f} m." if per_run else ""
    method = {CLOSE_FIXES: "close fixes", AT_REST: "fixes at rest"}.get(floor.method, floor.method)
    ratio = diagnosis.floor_ratio
    return (
        "The GPS noise, estimated from the recordings alone, never from a model: "
        + "; and ".join(parts)
        + ". "
        f"The larger, from {method}, sets the floor: a perfect model would still "
        f"show a mean cross-track error of σ·√(π/2) = {floor.cross_track:.3f} m."
        + spread
        + f" The chosen model's held-out error, {diagnosis.cross_track_after:.3f} m, is {ratio:.1f}× that "
        f"floor; above {diagnosis.settings.noise_factor:g}× (`--noise-factor`) a residual counts as more "
        "than noise (verdict partial, or unexplained when nothing was chosen)."
    )


def runner_up_text(up: explain.Evidence, chosen: str, settings: Any) -> str:
    """The best real alternative to the chosen candidate and the evidence between them."""
    if math.isfinite(up.delta_held_out) and abs(up.delta_held_out) <= explain.TIE:
        held = f"its held-out error, {up.other_held_out:.4f} m, is the chosen model's (within 0.1 mm)"
    elif math.isfinite(up.delta_held_out) and up.delta_held_out > 0:
        held = (
            f"its held-out error, {up.other_held_out:.4f} m, is {up.delta_held_out:.4f} m "
            f"({up.delta_held_out_percent:+.1f} %) above the chosen model's"
        )
    else:
        held = (
            f"its held-out error, {up.other_held_out:.4f} m, is {-up.delta_held_out:.4f} m lower, "
            f"yet it did not pass the rule (at least {settings.min_gain:.0%} lower held-out error and "
            f"{settings.bic_margin:g} lower BIC than the simpler model)"
        )
    tied = f" ({up.runs_tied} equal within 0.1 mm)" if up.runs_tied else ""
    return (
        f"{_ids(up.other)}: {held}; the chosen model (`{chosen}`) predicts {up.runs_better_text} held-out "
        f"runs better{tied}; ΔBIC = {up.delta_bic:+.1f} (positive favours the chosen model). ΔBIC treats "
        "every fix as independent, but successive fixes are strongly correlated, so it overstates the "
        "evidence: the held-out difference and the count of runs are the figures to weigh."
    )


# ---- look-alikes ----------------------------------------------------------------------------------

SEGMENT_WORDS = {
    "steer_step": "steering steps",
    "steer_ramp": "steering ramps and sines",
    "steer_hold": "held turns",
    "speed_step": "speed steps",
    "speed_ramp": "speed ramps",
    "cruise": "cruising straight",
    "rest": "standing",
    "unlabelled": "outside the command log",
}
LOOKALIKE_INTRO = (
    "Twin effects (a delay of every command and a steering lag; slip and a speed lag; a delay and "
    "a speed lag) leave nearly the same residual on ordinary manoeuvres. Both sets were fitted on "
    "every run, and their fix residuals compared segment by segment, the segments read from the "
    "command log alone: the log-likelihood ratio (LLR) is the difference of their squared "
    "residuals over 2σ² (σ the GPS noise floor), divided by the residuals' autocorrelation time "
    "in fixes, since successive fixes of a smooth residual are not independent evidence. Positive "
    "favours the first set. When held-out error and BIC cannot separate the two, |LLR| ≥ "
    f"{lookalike.DECISIVE:g} (about 150 to 1) decides; below it the diagnosis names both."
)


def _words(kind: str) -> str:
    return SEGMENT_WORDS.get(kind, kind)


def _strongest(look: lookalike.LookAlike) -> str:
    """The segment kind that carries most of the evidence, in words, with its share of the LLR."""
    by_kind = look.evidence.by_kind
    if not by_kind:
        return ""
    kind = max(by_kind, key=lambda k: abs(by_kind[k]))
    return f"mostly on {_words(kind)} ({by_kind[kind]:+.1f})"


def twins_sentence(look: lookalike.LookAlike) -> str:
    """The verdict between twins that held-out error and BIC could not separate, in one sentence."""
    a, b = look.pair
    llr = look.evidence.llr
    if look.decision == lookalike.DECIDED_BY_LLR:
        loser = b if look.favoured == a else a
        return (
            f"**Look-alikes:** {_ids(look.favoured)} rather than its look-alike "
            f"{_ids(loser)}: held-out error and BIC cannot separate them, but the "
            f"fixes can (LLR {abs(llr):.1f} in its favour, {_strongest(look)})."
        )
    missing = (
        ""
        if look.telling_fixes
        else (" these runs have no " + " and no ".join(_words(k) for k in look.telling.kinds) + ";")
    )
    return (
        f"**Look-alikes:** {_ids(a)} or its look-alike {_ids(b)}: cannot tell on these runs (LLR {llr:+.1f}, "
        f"below the {lookalike.DECISIVE:g} that decides);{missing} {look.telling.advice} would."
    )


def lookalike_text(look: lookalike.LookAlike) -> str:
    """The evidence between one pair of twins and how it was used."""
    a, b = look.pair
    e = look.evidence
    how = {
        lookalike.DECIDED_BY_FIT: "held-out error and BIC already separate them, and the LLR is reported "
        "as a check",
        lookalike.DECIDED_BY_LLR: f"held-out error and BIC do not separate them; the LLR does "
        f"(|LLR| ≥ {lookalike.DECISIVE:g})",
        lookalike.CANNOT_TELL: f"neither held-out error and BIC nor the LLR (below {lookalike.DECISIVE:g}) "
        "separates them: cannot tell on these runs",
    }[look.decision]
    return (
        f"{_ids(a)} against {_ids(b)} (swapping `{look.members[0]}` for `{look.members[1]}`): "
        f"LLR {e.llr:+.1f}, in favour of {_ids(look.favoured)}, {_strongest(look)}; {how}. σ "
        f"= {e.sigma:.4f} m, autocorrelation time {e.tau:.1f} fixes. What tells them apart "
        f"best: {', '.join(_words(k) for k in look.telling.kinds)} ({look.telling_fixes} "
        f"fixes here); {look.telling.advice} would add the most."
    )


def _by_segment(look: lookalike.LookAlike) -> pd.DataFrame:
    e = look.evidence
    return pd.DataFrame(
        [
            {"segment": _words(k), "fixes": e.samples[k], f"LLR ({look.pair[0]} over {look.pair[1]})": v}
            for k, v in e.by_kind.items()
        ]
    )


def response_text(look: lookalike.LookAlike) -> str:
    """What the response fits say, in a control engineer's terms."""
    channel = (
        "course (direction of travel)" if look.telling.channel == lookalike.COURSE else "speed over ground"
    )
    telling = [r for r in look.response if r.kind in look.telling.kinds] or look.response
    said = "; ".join(
        f"on {_words(r.kind)}, "
        + (
            {
                "delay": f"a delay of {r.delay:.2f} s fits best (lag {r.lag:.2f} s fits a little worse)",
                "lag": f"a first-order lag of {r.lag:.2f} s fits best (delay "
                f"{r.delay:.2f} s fits a little worse)",
                "gain": f"a gain of {r.gain:.3f} fits best: an attenuation, not a phase",
                "none": "the calibrated model's answer fits as it is",
            }[r.best]
        )
        for r in telling
    )
    shape = look.shape
    segment = _words(shape["segment"])
    if shape["favours"]:
        verdict = (
            f"On {segment} the shape alone favours `{shape['favours']}` (LLR {abs(shape['llr']):.1f} over "
            f"{shape['fixes']} fixes)."
        )
    elif shape["fixes"]:
        verdict = (
            f"On {segment} the shape alone cannot tell them apart (LLR {shape['llr']:+.1f} over "
            f"{shape['fixes']} fixes); more of them would."
        )
    else:
        verdict = (
            f"These runs have no {segment}, so the shape alone "
            f"cannot tell them apart: {look.telling.advice} would."
        )
    return (
        f"The recorded {channel}, estimated from the fixes by local polynomial fits (no "
        "interpolation across dropouts), against the calibrated model's without either effect, seen "
        "through the same window, fitted per segment as a pure delay, a first-order lag and a gain "
        f"(no simulation): {said}. A delay and a lag of the same size shift a slow answer alike; "
        f"only a step's shape, or a steady deficit while cruising, tells them apart. {verdict}"
    )


def _responses(look: lookalike.LookAlike) -> pd.DataFrame:
    return pd.DataFrame(
        [
            {
                "segment": _words(r.kind),
                "fixes": r.fixes,
                "SSE as modelled": r.sse,
                "delay [s]": r.delay,
                "SSE delay": r.delay_sse,
                "lag [s]": r.lag,
                "SSE lag": r.lag_sse,
                "gain": r.gain,
                "SSE gain": r.gain_sse,
                "best": r.best,
            }
            for r in look.response
        ]
    )
