"""The Robotti's own sections of its diagnosis report (its figures are figures.py's); the engine's report.py
lays out what every diagnosis has (verdict, effects, evidence, candidates, held-out runs, values, files) and
draws the look-alikes and the search beyond the library, here in the Robotti's words (:class:`Words`,
:data:`SEARCH`).

<out>/report/report.md        the page: the engine's skeleton with these sections
<out>/report/diagnosis.html   the same page as one file, figures inside
<out>/report/diagnosis.json   what ``dse-runner diagnose --json`` prints, and all the page is drawn from
<out>/report/figures/*.png    residual signatures, tracks, held-out errors

Each section reads the answer's JSON alone (its ``case``, ``lookalikes``, ``noise_floor.details``), so the
page can be drawn again from ``diagnosis.json``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import pandas as pd

from ...analysis.diagnose import discovery, report
from ...analysis.diagnose.answer import Answer
from ...analysis.diagnose.report import Section, table
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
    twins = [said for said in (report.twins_sentence(x, WORDS) for x in answer.lookalikes) if said]
    found = [
        Section("", "\n\n".join(twins), after="verdict"),
        Section("The effects named", effects_text(answer), after="effects"),
        Section("GPS noise floor", noise_text(answer), after="evidence"),
        Section("Look-alikes", report.lookalikes_part(answer, WORDS), after="evidence"),
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


SEARCH = (  # the discovery part's opening: the Robotti's search beyond its library (discover/)
    "The library's best answer left held-out error well above the noise, so a sparse correction was sought "
    "among the terms of the effects variant's correction block: the equation error of the recorded speed and "
    "yaw rate (from the fixes alone) against the reference's quasi-static answer, regressed on the block's "
    "features at the reference's state by PySINDy's STLSQ, with the threshold chosen by leave-one-run-out "
    "error and each term kept only if a seeded bootstrap over runs picks it in "
    f"{discover.INCLUSION:.0%} of the resamples."
)


def discovery_text(answer: Answer) -> str:
    """What discovery did (the engine's part after the Robotti's description of its search), or why it did
    not run."""
    settings = answer.case["settings"]
    skipped = (
        "it is switched off (`--no-discovery`)"
        if not settings["discovery"]
        else f"the library's answer is within {settings['noise_factor']:g}× the noise floor (or no floor "
        "could be estimated), so there is nothing a correction could claim but noise"
    )
    return report.discovery_part(answer, answer.case.get("discovery"), SEARCH, skipped)


# ---- look-alikes: the engine's part, in the Robotti's words -------------------------------------------


class Words(report.LookalikeWords):
    """The Robotti's words on its look-alikes: its segments of the command log, its fixes, the GPS noise, and
    what only it knows of a pair (the segments and manoeuvre that tell it apart; the response fits)."""

    segments: ClassVar[Mapping[str, str]] = {
        "steer_step": "steering steps",
        "steer_ramp": "steering ramps and sines",
        "steer_hold": "held turns",
        "speed_step": "speed steps",
        "speed_ramp": "speed ramps",
        "cruise": "cruising straight",
        "rest": "standing",
        "unlabelled": "outside the command log",
    }
    sample = lookalike.LookAlike.sample
    noise = "the GPS noise floor"
    intro = (
        "Twin effects (a delay of every command and a steering lag; slip and a speed lag; a delay and a "
        "speed lag) leave nearly the same residual on ordinary manoeuvres. Both sets were fitted on every "
        "run, and their fix residuals compared segment by segment, the segments read from the command log "
        "alone."
    )

    def about(self, look: Mapping[str, Any]) -> str:
        return (
            f"What tells them apart best: {', '.join(self.segment(k) for k in look['telling_segments'])} "
            f"({look['telling_fixes']} fixes here); {look['would_tell']} would add the most."
        )

    def more(self, look: Mapping[str, Any]) -> str:
        if not look["response_fit"]:
            return ""
        return response_text(look, self) + "\n\n" + report.response_table(look["response_fit"], self)

    def advice(self, look: Mapping[str, Any]) -> str:
        missing = (
            ""
            if look["telling_fixes"]
            else (
                " these runs have no "
                + " and no ".join(self.segment(k) for k in look["telling_segments"])
                + ";"
            )
        )
        return f"{missing} {look['would_tell']} would"


WORDS = Words()


def response_text(look: Mapping[str, Any], words: report.LookalikeWords) -> str:
    """What the response fits say, in a control engineer's terms."""
    responses = look["response_fit"]
    channel = (
        "course (direction of travel)" if responses[0]["channel"] == lookalike.COURSE else "speed over ground"
    )
    telling = [r for r in responses if r["segment"] in look["telling_segments"]] or responses
    said = "; ".join(
        f"on {words.segment(r['segment'])}, "
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
    segment = words.segment(shape["segment"])
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
