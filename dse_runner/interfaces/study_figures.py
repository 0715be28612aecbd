"""The sensitivity and uncertainty figures of a sweep as HTML sections, inline PNGs, for the report and the
dashboard alike: a sweep sampled by a sensitivity design gets its index bars (Sobol') or mu*-sigma plane
(Morris) per objective; a sweep with uncertain parameters gets its best points' objective distributions."""

from __future__ import annotations

import base64
import html
import warnings
from dataclasses import dataclass

from ..errors import DseError
from ..sweeps import store
from ..sweeps.rank import Ranking, load_sweep_spec
from ..sweeps.search import strategy
from ..sweeps.strategies.designs import SensitivityDesign

PANELS = 6  # sensitivity panels per objective: all scenarios and the five least responsive groups


@dataclass
class Section:
    """One heading's worth: its title, a note on how to read it, and the figures (or why there are none)."""

    key: str  # "sensitivity" | "uncertainty": the element ids
    title: str
    note: str
    body: str  # HTML: images, or a note saying why there are none


def image(png: bytes, alt: str, ident: str) -> str:
    """An inline PNG as wide as the page (drawn at least as wide: sensitivity_figures.PAGE_INCHES), so it is
    read at the size of the charts around it."""
    data = base64.b64encode(png).decode()
    return (
        f'<img id="{html.escape(ident)}" alt="{html.escape(alt)}" style="width:100%;height:auto" '
        f'src="data:image/png;base64,{data}">'
    )


def is_sensitivity(output: store.Root, sweep: str) -> bool:
    """Whether the sweep was sampled by a sensitivity design (a plug-in strategy this process lacks: no)."""
    try:
        return issubclass(strategy(load_sweep_spec(output, sweep).search.strategy), SensitivityDesign)
    except DseError:
        return False


def sensitivity_section(output: store.Root, sweep: str) -> Section:
    """Each objective's indices with their intervals, overall and per group (analysis/sensitivity.py)."""
    from ..analysis.sensitivity import sensitivity
    from .sensitivity_figures import pngs

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            found = sensitivity(output, sweep)
    except DseError as e:
        return Section(
            "sensitivity",
            "Sensitivity",
            "",
            f'<p class="note" id="sensitivity-note">{html.escape(str(e))}</p>',
        )
    sobol = found.indices  # S1 and ST (Sobol' or eFAST), else Morris' mu*, sigma
    level = f"{100 * found.confidence:g} %"
    named = "eFAST" if found.method == "fast" else "Sobol'"
    note = (
        f"{named} first-order (S1) and total (ST) indices with {level} bootstrap intervals"
        if sobol
        else "Morris' mu* (how much) against sigma (how non-linearly or through interactions), "
        f"mu* with its {level} interval"
    ) + (
        f", over all scenarios ({found.reduced}) and per scenario group, least responsive first"
        f"; {found.design['blocks']} blocks of {found.design['block']} points."
    )
    figures = "".join(
        image(png, f"sensitivity of {name}", f"sensitivity-{name}")
        for name, png in pngs(found, PANELS).items()
    )
    warned = "".join(f"<li>{html.escape(w)}</li>" for w in found.warnings)
    body = figures + (f'<ul class="note" id="sensitivity-warnings">{warned}</ul>' if warned else "")
    return Section("sensitivity", "Sensitivity: which parameters move each objective", note, body)


def uncertainty_section(ranking: Ranking) -> Section:
    """The best points' ranking objective over the uncertain draws (uncertainty_figures.py)."""
    from .uncertainty_figures import distributions_png

    about = ranking.uncertainty
    described = "; ".join(f"{name}: {_described(d)}" for name, d in about["parameters"].items())
    note = (
        f"Each point ran on {about['samples']} draws ({about['sampling']}, seed "
        f"{about['seed']}) of {described}. Per draw the objective is reduced over the "
        f"scenarios; the points are ranked by its {about['ranked_by']} over the draws."
    )
    png = distributions_png(ranking)
    return Section(
        "uncertainty",
        f"Uncertainty: {ranking.objective} over the draws at the best points",
        note,
        image(png, f"{ranking.objective} over the draws", "uncertainty-distributions"),
    )


def _described(d: dict) -> str:
    """``normal(mean 1800, std 50)``: a distribution as the spec wrote it."""
    if "from_diagnosis" in d:
        return f"from diagnosis {d['from_diagnosis']}" + (f" effect {d['effect']}" if d.get("effect") else "")
    args = ", ".join(f"{k} {v:g}" for k, v in d.items() if k != "distribution")
    return f"{d['distribution']}({args})"


def sections(output: store.Root, sweep: str, ranking: Ranking | None) -> list[Section]:
    """What this sweep has of the two: none for a plain sweep."""
    return [*sensitivity_sections(output, sweep), *uncertainty_sections(ranking)]


def sensitivity_sections(output: store.Root, sweep: str) -> list[Section]:
    """The sensitivity section of a sweep sampled by a sensitivity design; none for another."""
    return [sensitivity_section(output, sweep)] if is_sensitivity(output, sweep) else []


def uncertainty_sections(ranking: Ranking | None) -> list[Section]:
    """The uncertainty section of a ranking over uncertain draws; none for another."""
    if ranking is not None and ranking.uncertainty is not None and ranking.draws is not None:
        return [uncertainty_section(ranking)]
    return []


def section_html(section: Section, heading: str = "h2") -> str:
    note = f'<p class="note">{html.escape(section.note)}</p>' if section.note else ""
    return (
        f'<{heading} id="{section.key}">{html.escape(section.title)}</{heading}>{note}'
        f'<div id="{section.key}-figures">{section.body}</div>'
    )
