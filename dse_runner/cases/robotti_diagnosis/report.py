"""The Robotti's own sections of its diagnosis report (its figures are figures.py's); the engine's report.py
lays out what every diagnosis has (verdict, effects, evidence, candidates, held-out runs, values, files).

<out>/report/report.md        the page: the engine's skeleton with these sections
<out>/report/diagnosis.html   the same page as one file, figures inside
<out>/report/diagnosis.json   what ``dse-runner diagnose --json`` prints, and all the page is drawn from
<out>/report/figures/*.png    residual signatures, tracks, held-out errors

Each section reads the answer's JSON alone (its ``case``, ``lookalikes``, ``noise_floor.details``), so the
page can be drawn again from ``diagnosis.json``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from ...analysis.diagnose import discovery, report
from ...analysis.diagnose.answer import Answer
from ...analysis.diagnose.lookalike import CANNOT_TELL, DECIDED_BY_FIT, DECIDED_BY_LLR, DECISIVE
from ...analysis.diagnose.report import Section, ids, table
from ...simulation.scenario import dropouts_line
from ...sweeps.rank import format_point
from ...sweeps.spec import Space
from . import discover, lookalike
from . import figures as robotti_figures
from .hypotheses import LIBRARY
from .noise import AT_REST, CLOSE_FIXES, MAX_SPACING

if TYPE_CHECKING:
    from .outcome import Diagnosis

FIGURES = {"residuals": "residual signatures", "held_out": "held-out errors", "tracks": "tracks"}


def write(
    diagnosis: Diagnosis,
    space: Space,
    frames: dict[str, pd.DataFrame],
    before: dict[str, pd.DataFrame],
    after: dict[str, pd.DataFrame],
) -> dict[str, Path]:
    """The figures, then the report (the engine's, with this library's sections), its page and the JSON."""
    folder = diagnosis.out / "report"
    vehicle = diagnosis.calibration["vehicle"]
    chosen_label = (
        "with " + diagnosis.chosen.label if diagnosis.chosen.ids else "calibrated baseline (no effect)"
    )
    figures = robotti_figures.draw(
        folder / "figures",
        space,
        frames,
        {"before": before, "after": after},
        (f"{vehicle}.gps_x", f"{vehicle}.gps_y"),
        diagnosis.held_out,
        chosen_label,
    )
    diagnosis.files.update({f"figure_{k}": p for k, p in figures.items()})
    diagnosis.files.update(
        {k: Path(p) for k, p in report.files_at(folder / "report.md", folder / "diagnosis.json").items()}
    )
    return {**report.write(diagnosis.answer(), sections), **{f"figure_{k}": p for k, p in figures.items()}}


# ---- the sections -----------------------------------------------------------------------------------


def sections(answer: Answer) -> list[Section]:
    """The Robotti's sections of its report, from the answer alone."""
    case, named = answer.case, answer.effects[0].id != "none"
    twins = [twins_sentence(x) for x in answer.lookalikes if x["decision"] != DECIDED_BY_FIT]
    found = [
        Section("", "\n\n".join(twins), after="verdict"),
        Section("The effects named", effects_text(answer), after="effects"),
        Section("GPS noise floor", noise_text(answer), after="evidence"),
        Section("Look-alikes", lookalikes_text(answer), after="evidence"),
        Section("How a candidate is chosen", rule_text(case["settings"]), after="candidates"),
        Section("Discovery beyond the library", discovery_text(answer), after="candidates"),
        Section("Where the calibrated model misses", located_text(answer), after="runs"),
        Section(
            "Held-out errors and tracks",
            "\n\n".join(
                report.figure(answer, answer.files[f"figure_{k}"], FIGURES[k]) for k in ("held_out", "tracks")
            )
            if "figure_tracks" in answer.files
            else "",
            after="runs",
        ),
        Section("Calibration", calibration_text(answer), after="values"),
        Section("The model with the effects", model_text(answer) if named else "", after="values"),
    ]
    return [s for s in found if s.body]


def _rows(split: dict[str, Any], index: str | None = None) -> list[dict[str, Any]]:
    """A pandas ``split`` table as rows (its index as the column ``index``, if named)."""
    return [
        {**({index: i} if index else {}), **dict(zip(split["columns"], row))}
        for i, row in zip(split["index"], split["data"])
    ]


def calibration_text(answer: Answer) -> str:
    """The runs and folds, the calibration grid's best point, its refinement, and what no run responds to."""
    cal, held = answer.case["calibration"], answer.held_out
    lines = [
        f"Runs held out: {len(held)} in {len({h.group for h in held})} groups; cross-validation folds: "
        + "; ".join(", ".join(f) for f in cal["folds"])
        + ".",
        "",
        (
            f"Calibration grid best point: {format_point(cal['grid_best'], 5)}; parameters at a bound of the "
            f"design space: {', '.join(cal['grid_at_bound']) or 'none'}."
        ),
        (
            f"Refined by least squares within the design space: {format_point(cal['refined'], 5)}; at a "
            f"bound: {', '.join(cal['refined_at_bound']) or 'none'}."
        ),
        (
            "Parameters no run responds to (any value fits equally well): "
            f"{', '.join(cal['no_effect']) or 'none'}."
        ),
        (
            "Runs no tuned parameter can improve (every grid point within 5 % of the calibrated error): "
            f"{', '.join(cal['insensitive_scenarios']) or 'none'}."
        ),
    ]
    dropouts = answer.case.get("dropouts") or {}
    return "\n".join([*lines, *(["", dropouts_line(dropouts).capitalize() + "."] if dropouts else [])])


def located_text(answer: Answer) -> str:
    """The calibrated model's residuals by group, by segment of the motion, and their correlations."""
    located = answer.case.get("located") or {}
    if not located:
        return ""
    magnitudes = [
        "fixes",
        "cross_track_error",
        "along_rms",
        "cross_rms",
        "along_growth_rms",
        "cross_growth_rms",
    ]
    strongest = located["signature"]["correlations"]
    lines = [
        "By scenario group:",
        "",
        table(_rows(located["by_group"]), ["group", *magnitudes]),
        "",
        "By segment of the motion:",
        "",
        table(_rows(located["by_segment"]), ["segment", *magnitudes]),
        "",
        "Correlation of the residuals and of their growth rates with the motion:",
        "",
        table(_rows(located["correlations"], "residual"), ["residual", *located["correlations"]["columns"]]),
        "",
        "Strongest: " + "; ".join(f"{c} with {f} (r = {r:+.2f})" for c, f, r in strongest) + ".",
    ]
    if "figure_residuals" in answer.files:
        lines += ["", report.figure(answer, answer.files["figure_residuals"], FIGURES["residuals"])]
    return "\n".join(lines)


def effects_text(answer: Answer) -> str:
    """Each named effect of the library as the physics it stands for, its expected signature, and what the
    residuals showed."""
    lines = []
    for e in answer.effects:
        if e.id in LIBRARY:
            h = LIBRARY[e.id]
            lines += [
                f"### `{h.id}`: {h.name}",
                "",
                h.explanation,
                "",
                f"Expected signature: {h.signature}.",
                "",
            ]
    sig = (answer.case.get("located") or {}).get("signature")
    if sig and answer.effects[0].id != "none":
        lines.append(
            f"Observed: the residual fell most in {sig['component']} on {sig['segment']} segments, from "
            f"{sig['before']:.3f} to {sig['after']:.3f} (rms)."
        )
    return "\n".join(lines)


def model_text(answer: Answer) -> str:
    """What was written with the effects, and how to calibrate again with them."""
    written = " and ".join(
        f"`{Path(answer.files[k]).name}`" for k in ("multimodel", "space") if k in answer.files
    )
    discovered = any(e.id == discovery.DISCOVERED for e in answer.effects)
    return (
        "The chosen effect is part of the vehicle's effects variant (`bundled:fmus/robotti_vehicle_effects`: "
        f"the checkout's top-level `fmus/`, shipped inside the package). Written: {written or 'nothing'} "
        "(the calibration with the effect's parameters added); `dse-runner submit space.yaml` re-calibrates "
        "with it."
        + (
            " The discovered terms are coefficients `corr_*` of the same variant's correction block, written "
            "over their ~95 % intervals like the effects' parameters."
            if discovered
            else ""
        )
    )


def rule_text(settings: dict[str, Any]) -> str:
    """The choice's rule, with the gain and BIC margin this diagnosis used."""
    gain, margin = settings["min_gain"], settings["bic_margin"]
    return (
        "Every hypothesis of the library fitted jointly with the calibrated parameters; held-out error is "
        "the mean Equation 1 error of each run predicted by the fit on the other folds. A candidate is "
        f"chosen only if it lowers the held-out error by at least {gain:.0%} and the BIC by at least "
        f"{margin:g} against `none` and against every fitted part of it (each member has to pay its way); "
        "of those, the "
        f"lowest held-out error wins, and one within {gain:.0%} of it with fewer effects wins over it. "
        "Combinations fitted on every run but not cross-validated failed the BIC gate: their BIC was not "
        f"{margin:g} below the best single answer's and each fitted part's, so they could not be chosen."
    )


def noise_text(answer: Answer) -> str:
    """How the GPS noise floor was estimated, from the recordings alone."""
    floor = answer.noise_floor
    details = floor.details
    if floor.held_out is None:
        return (
            f"Not available: no run has three consecutive fixes at most {MAX_SPACING:g} s apart, nor a stop "
            "with enough fixes."
        )
    estimates = details.get("estimates") or {}
    close, rest, rho1 = estimates.get(CLOSE_FIXES), estimates.get(AT_REST), details.get("rho1")
    parts = []
    if close:
        parts.append(
            f"σ = {close['sigma']:.4f} m per axis from the second differences at {close['fixes']} fixes "
            "whose neighbours are equally close with no dropout between them (robust median absolute "
            "deviation, pooled over x, y and runs; speed cancels, and acceleration adds at most millimetres)"
        )
    if rest:
        colour = (
            ""
            if rho1 is None
            else f"; lag-1 autocorrelation {rho1:.2f}, "
            + ("coloured noise, which second differences under-estimate" if rho1 > 0.3 else "white")
        )
        parts.append(
            f"σ = {rest['sigma']:.4f} m from the spread of {rest['fixes']} fixes while the commanded speed "
            "was 0 and the vehicle stood still (or crept at a steady speed: the spread is taken about a "
            f"straight line in time){colour}"
        )
    per_run = list((details.get("per_run") or {}).values())
    spread = f" Per run, σ lies between {min(per_run):.4f} and {max(per_run):.4f} m." if per_run else ""
    method = {CLOSE_FIXES: "close fixes", AT_REST: "fixes at rest"}.get(floor.method, floor.method)
    return (
        "The GPS noise, estimated from the recordings alone, never from a model: "
        + "; and ".join(parts)
        + f". The larger, from {method}, sets the floor: a perfect model would still show a mean cross-track "
        f"error of σ·√(π/2) = {floor.held_out:.3f} m."
        + spread
        + f" The chosen model's held-out error, {answer.held_out_after:.3f} m, is {floor.ratio:.1f}× that "
        f"floor; above {floor.factor:g}× (`--noise-factor`) a residual counts as more than noise (verdict "
        "partial, or unexplained when nothing was chosen)."
    )


def discovery_text(answer: Answer) -> str:
    """What discovery did, or why it did not run."""
    found, settings = answer.case.get("discovery"), answer.case["settings"]
    if found is None:
        why = (
            "it is switched off (`--no-discovery`)"
            if not settings["discovery"]
            else f"the library's answer is within {settings['noise_factor']:g}× the noise floor (or no floor "
            "could be estimated), so there is nothing a correction could claim but noise"
        )
        return f"No correction was sought: {why}."
    proposed = "; ".join(found["proposed_text"])
    lines = [
        (
            "The library's best answer left held-out error well above the noise, so a sparse correction was "
            "sought among the terms of the effects variant's correction block: the equation error of the "
            "recorded speed and yaw rate (from the fixes alone) against the reference's quasi-static answer, "
            "regressed on the block's features at the reference's state by PySINDy's STLSQ, with the "
            "threshold chosen by leave-one-run-out error and each term kept only if a seeded bootstrap over "
            f"runs picks it in {discover.INCLUSION:.0%} of the resamples. The proposed terms were then "
            "fitted on positions with the calibrated parameters, pruned to those two standard errors from "
            "zero, re-proposed inside each fold on its training runs only, and judged by the library's rule, "
            f"the BIC margin raised to {found['bic_margin']:.1f} for the search (extended BIC)."
        ),
        f" Proposed from every run: {('`' + proposed + '`') if proposed else 'nothing'}.",
    ]
    for c in found["tried"]:
        lines.append(
            f" `{c['id']}`: "
            + "; ".join(c["text"])
            + f", held-out {c['held_out']:.4f} m, ΔBIC {c['bic'] - found['bic_reference']:+.1f} against "
            f"`{found['reference']}` ({found['held_out_reference']:.4f} m)."
        )
    if found["chosen"] is None:
        lines.append(f" Nothing was accepted: {found['reason']}.")
    else:
        lines.append(f" Accepted: `{found['chosen']}`; it {found['resembles']}.")
    proof = found.get("proof")
    if proof and proof["folds"]:
        lines.append(
            f" Proof: {proof['agree']} of {len(proof['folds'])} folds, choosing among {proof['offered']} "
            "terms on their training runs alone, chose these terms again; their own choices predicted the "
            f"held-out runs with {proof['held_out']:.4f} m."
        )
    return "".join(lines)


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
    f"{DECISIVE:g} (about 150 to 1) decides; below it the diagnosis names both."
)


def _words(kind: str) -> str:
    return SEGMENT_WORDS.get(kind, kind)


def _strongest(look: dict[str, Any]) -> str:
    """The segment kind that carries most of the evidence, in words, with its share of the LLR."""
    by_kind = look["by_segment"]
    if not by_kind:
        return ""
    kind = max(by_kind, key=lambda k: abs(by_kind[k]["llr"]))
    return f"mostly on {_words(kind)} ({by_kind[kind]['llr']:+.1f})"


def twins_sentence(look: dict[str, Any]) -> str:
    """The verdict between twins (as the JSON holds them) that held-out error and BIC could not separate, in
    one sentence."""
    a, b = look["pair"]
    llr = look["llr"]
    if look["decision"] == DECIDED_BY_LLR:
        loser = b if look["favours"] == a else a
        return (
            f"**Look-alikes:** {ids(look['favours'])} rather than its look-alike {ids(loser)}: held-out "
            f"error and BIC cannot separate them, but the fixes can (LLR {abs(llr):.1f} in its favour, "
            f"{_strongest(look)})."
        )
    missing = (
        ""
        if look["telling_fixes"]
        else (" these runs have no " + " and no ".join(_words(k) for k in look["telling_segments"]) + ";")
    )
    return (
        f"**Look-alikes:** {ids(a)} or its look-alike {ids(b)}: cannot tell on these runs (LLR {llr:+.1f}, "
        f"below the {DECISIVE:g} that decides);{missing} {look['would_tell']} would."
    )


def lookalike_text(look: dict[str, Any]) -> str:
    """The evidence between one pair of twins and how it was used."""
    a, b = look["pair"]
    how = {
        DECIDED_BY_FIT: "held-out error and BIC already separate them, and the LLR is reported as a check",
        DECIDED_BY_LLR: f"held-out error and BIC do not separate them; the LLR does (|LLR| ≥ {DECISIVE:g})",
        CANNOT_TELL: f"neither held-out error and BIC nor the LLR (below {DECISIVE:g}) "
        "separates them: cannot tell on these runs",
    }[look["decision"]]
    members = look["effects"]
    return (
        f"{ids(a)} against {ids(b)} (swapping `{members[0]}` for `{members[1]}`): LLR {look['llr']:+.1f}, in "
        f"favour of {ids(look['favours'])}, {_strongest(look)}; {how}. σ = {look['sigma']:.4f} m, "
        f"autocorrelation time {look['autocorrelation_fixes']:.1f} fixes. What tells them apart best: "
        f"{', '.join(_words(k) for k in look['telling_segments'])} ({look['telling_fixes']} fixes here); "
        f"{look['would_tell']} would add the most."
    )


def response_text(look: dict[str, Any]) -> str:
    """What the response fits say, in a control engineer's terms."""
    responses = look["response_fit"]
    channel = (
        "course (direction of travel)" if responses[0]["channel"] == lookalike.COURSE else "speed over ground"
    )
    telling = [r for r in responses if r["segment"] in look["telling_segments"]] or responses
    said = "; ".join(
        f"on {_words(r['segment'])}, "
        + {
            "delay": f"a delay of {r['delay']:.2f} s fits best (lag {r['lag']:.2f} s fits a little worse)",
            "lag": f"a first-order lag of {r['lag']:.2f} s fits best (delay {r['delay']:.2f} s fits a little "
            "worse)",
            "gain": f"a gain of {r['gain']:.3f} fits best: an attenuation, not a phase",
            "none": "the calibrated model's answer fits as it is",
        }[r["best"]]
        for r in telling
    )
    shape = look["shape"]
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
            f"These runs have no {segment}, so the shape alone cannot tell them apart: "
            f"{look['would_tell']} would."
        )
    return (
        f"The recorded {channel}, estimated from the fixes by local polynomial fits (no interpolation across "
        "dropouts), against the calibrated model's without either effect, seen through the same window, "
        "fitted per segment as a pure delay, a first-order lag and a gain (no simulation): "
        f"{said}. A delay and a lag of the same size shift a slow answer alike; only a step's shape, or a "
        f"steady deficit while cruising, tells them apart. {verdict}"
    )


RESPONSE = {  # a response fit's JSON key -> its column
    "fixes": "fixes",
    "sse": "SSE as modelled",
    "delay": "delay [s]",
    "delay_sse": "SSE delay",
    "lag": "lag [s]",
    "lag_sse": "SSE lag",
    "gain": "gain",
    "gain_sse": "SSE gain",
    "best": "best",
}


def lookalikes_text(answer: Answer) -> str:
    """Each pair of twins: the evidence between them segment by segment, and the response fits."""
    if not answer.lookalikes:
        return ""
    lines = [LOOKALIKE_INTRO, ""]
    for look in answer.lookalikes:
        a, b = look["pair"]
        by_segment = [
            {"segment": _words(k), "fixes": v["fixes"], f"LLR ({a} over {b})": v["llr"]}
            for k, v in look["by_segment"].items()
        ]
        lines += [
            lookalike_text(look),
            "",
            table(by_segment, ["segment", "fixes", f"LLR ({a} over {b})"]),
            "",
        ]
        if look["response_fit"]:
            rows = [
                {"segment": _words(r["segment"]), **{RESPONSE[k]: r[k] for k in RESPONSE}}
                for r in look["response_fit"]
            ]
            lines += [response_text(look), "", table(rows, ["segment", *RESPONSE.values()]), ""]
    return "\n".join(lines)
