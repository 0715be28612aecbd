"""The sweep report: one self-contained HTML file to send to a colleague.

It holds Table 1, the rankings, the Pareto front, the dashboard's figures (drawn by the
same chart classes, filled once), the best point's track on every scenario, and the spec
that produced them; for a closed-loop search also its progress (best so far against
simulations, the Pareto front as it grew) from the search's history. BokehJS is inlined (its
core only, 1.3 MB: the report has no widgets), so the file opens offline and from an e-mail.
"""

from __future__ import annotations

import html
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
import yaml
from jinja2 import Template

from ..errors import DseError
from ..simulation.comparison import Comparison
from ..sweeps import store
from ..sweeps.history import load_history
from ..sweeps.rank import (
    TABLE1_HEADINGS,
    Ranking,
    figure_label,
    format_point,
    load_sweep_spec,
    pick_sweep,
    plain,
    rank,
    table1_scope,
)
from ..sweeps.search import Search, strategy
from ..sweeps.spec import SpaceSpec
from ..sweeps.status import SweepReport, load_status
from . import charts
from .dashboard.feed import Feed, search_summary
from .study_figures import Section, section_html, sensitivity_sections, uncertainty_sections

TOP = 20  # points listed in the ranking

PAGE = Template("""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>dse-runner report: {{ sweep }}</title>
{{ bokeh_resources }}
{{ table_style }}
<style>
body { font-family: sans-serif; margin: 24px 40px; color: #222; max-width: 1300px }
h1 { margin-bottom: 4px } h2 { margin-top: 36px; border-bottom: 1px solid #ddd; padding-bottom: 4px }
.summary td { padding: 2px 16px 2px 0 } .note { color: #666; font-size: 13px }
pre { background: #f7f7f7; padding: 12px; font-size: 12px; overflow-x: auto }
</style>
</head>
<body>
<h1>Sweep {{ sweep }}</h1>
<div class="note">generated {{ generated }} by dse-runner from {{ output }}</div>
<table class="summary">
{% for name, value in summary %}<tr><td>{{ name }}</td><td id="summary-{{ loop.index }}">{{ value }}</td></tr>
{% endfor %}</table>

{% if search %}<h2>Search: best {{ objective }} against simulations</h2>
<p class="note">Each point the strategy was told about costs one simulation per scenario (infeasible points,
and points asked again after their first copy was told, cost none); the line is the best {{ objective }} so
far, the dots each point's.{% if front_growth %} The second chart has every point on the first two Pareto
objectives, coloured by the order the strategy was told them, and the front after a quarter, half, three
quarters and all of them.{% endif %}</p>
<table class="summary" id="search">
{% for name, value in search %}<tr><td>{{ name }}</td><td>{{ value }}</td></tr>
{% endfor %}</table>
{{ plots.search }}{% endif %}

<h2>Table 1: {{ objective }} per scenario ({{ table1_scope }})</h2>
<p class="note">{{ notes.table1 }}</p>
{{ table1 }}

<h2>Ranking by {{ ranked_label }}</h2>
<p class="note">The {{ top }} best of {{ points }} points, each objective {{ "summed" if over == "sum" else
"reduced by its " ~ over }} over the scenarios.</p>
{{ totals }}

{% for section in studies %}{{ section }}
{% endfor %}
{% if pareto %}<h2>Pareto front</h2>
<p class="note">{{ notes.pareto }}</p>
{{ plots.pareto }}
{{ pareto }}{% endif %}

{% if groups %}<h2>Best point per scenario group</h2>
{{ groups }}{% endif %}

{% if weighted %}<h2>Weighted ranking</h2>
{{ weighted }}{% endif %}

<h2>{{ objective }} against each parameter</h2>
<p class="note">{{ notes.by_parameter }}</p>
{{ plots.by_parameter }}

<h2>{{ objective }} per scenario group</h2>
<p class="note">{{ notes.by_group }}</p>
{{ plots.by_group }}

<h2>{{ tracks_heading }}</h2>
<p class="note">{{ tracks_note }}</p>
{% if plots.tracks %}{{ plots.tracks }}{% endif %}

<h2>The spec</h2>
<p class="note">{{ notes.spec }}</p>
<pre>{{ spec }}</pre>
{{ bokeh_script }}
</body>
</html>
""")


@dataclass
class Tracks:
    """The best point simulated on each scenario: the charts (None if they cannot be drawn), a heading that
    mentions recordings only if some scenario has one, and a note on what the charts show, or why none."""

    layout: object | None
    heading: str
    note: str


def _tracks(feed: Feed, ranking: Ranking, scenarios: list[str]) -> Tracks:
    """A track chart per scenario for the best point, the row filling the page; or none, and why not."""
    best = {p: plain(v) for p, v in ranking.best.items()}
    compared, panels = [], []
    for scenario in scenarios:
        try:
            comparison, value = feed.track(scenario, best)
        except DseError as e:
            return Tracks(None, "The best point on each scenario", f"No tracks: {e}")
        chart = charts.TrackChart(width=charts.WIDTH, height=charts.HEIGHT)
        chart.update(comparison, f"{scenario}: {ranking.objective} {value:.3f}")
        compared.append(comparison)
        panels.append(chart.figure)
    heading, note = tracks_caption(compared, ranking.objective, format_point(ranking.best))
    return Tracks(charts.fill_width(charts.grid(panels)) if panels else None, heading, note)


def tracks_caption(compared: list[Comparison], objective: str, best: str) -> tuple[str, str]:
    """The tracks' heading and note: what each chart plots, and a recording only where a scenario has one
    (a study of the experiment alone has none to show)."""
    recorded = sum(c.recorded is not None and len(c.recorded[0]) > 0 for c in compared)
    drawn = "; ".join(sorted({f"{c.y_label} against {c.x_label}" for c in compared})) or "nothing"
    heading = "The best point " + ("against each scenario's recording" if recorded else "on each scenario")
    over = (
        ""
        if not recorded
        else ", over its recording (grey dots)"
        if recorded == len(compared)
        else f", over its recording (grey dots) on the {recorded} of {len(compared)} scenarios that have one"
    )
    return heading, (
        f"The best point ({best}) simulated on each scenario: {drawn}{over}; each title gives "
        f"the scenario's {objective}."
    )


def figure_notes(
    objective: str, parameters: list[str], scattered: bool, binned: bool = False
) -> dict[str, str]:
    """What each figure and table shows, in the study's own objective and parameter names (``binned``: a
    sampled design too large for dots, charts.is_binned)."""
    named = ", ".join(parameters)
    band = f"{round(100 * charts.BAND[0])} % and {round(100 * charts.BAND[1])} %"
    if binned:
        by_parameter = (
            f"Each point the sweep simulated lies off any grid, and there are more than "
            f"{charts.MAX_DOTS}: per scenario, the mean {objective} in {charts.BINS} equal bins "
            f"of each parameter ({named}), drawn as a line over the band between its rows' "
            f"{band} quantiles, coloured by group."
        )
    elif scattered:
        by_parameter = (
            f"Every point the sweep simulated, at its value of each parameter ({named}): a "
            "dot per scenario, coloured by its group. Sampled or searched points lie off any "
            "grid, so there is no mean over the other parameters to join with lines."
        )
    elif len(parameters) > 1:
        by_parameter = (
            f"One panel per parameter: the mean {objective} at each of its values, over every "
            f"value of the others (for {parameters[0]}: over {', '.join(parameters[1:])}); a "
            "line per scenario, coloured by its group."
        )
    else:
        by_parameter = f"{objective} at each value of {named}; a line per scenario, coloured by its group."
    drawn = (
        "per scenario, the mean in bins of consecutive points inside its quantile band"
        if binned
        else "a dot per point and scenario"
        if scattered
        else "a line per scenario of the group"
    )
    by_group = (
        f"One panel per scenario group: {objective} at every parameter point, {drawn}. The points "
        f"are numbered in the order of their values of {named}."
    )
    table1 = (
        f'Per scenario: the min, max and average {objective} over the ranked points; "best" is the '
        f'best point\'s {objective} and "difference" best minus average.'
    )
    return {"table1": table1, "by_parameter": by_parameter, "by_group": by_group}


def pareto_note(goals: list[tuple[str, str]], reduced: str) -> str:
    """The Pareto chart's caption: its axes, and which objectives the front is over."""
    named = [f"{reduced} {name} ({'lower' if goal == 'min' else 'higher'} is better)" for name, goal in goals]
    over = (
        "both"
        if len(goals) == 2
        else f"all {len(goals)} Pareto objectives ({', '.join(name for name, _ in goals)})"
    )
    return (
        f"Every ranked point on {named[0]} against {named[1]}; the front, the points no other point "
        f"beats on {over}, in red, listed in the table below."
    )


SEARCH_SETTINGS = ("strategy", "max_points", "seed")  # what chose a search's or a design's points


def budgeted(spec: SpaceSpec) -> bool:
    """Whether a budget and a seed chose the sweep's points, as its strategy says (a grid and given points
    say not). A strategy whose plug-in is not installed here is taken to have spent one, as most do."""
    try:
        return strategy(spec.search.strategy).budgeted
    except DseError:
        return True


def shown_spec(spec: SpaceSpec) -> dict:
    """The spec the sweep ran, as it stored it, less every key left at its default and a grid's search
    settings: they would show a budget (``max_points: 100``) that played no part. A search's or a design's
    budget and seed chose its points even at their defaults, so they stay."""
    full = spec.model_dump(mode="json")
    given = spec.model_dump(mode="json", exclude_defaults=True)
    if budgeted(spec):
        given["search"] = {**{key: full["search"][key] for key in SEARCH_SETTINGS}, **given.get("search", {})}
    else:  # a grid's budget, seed and order, even given, chose nothing; its strategy's own options did
        common = set(Search.model_fields) - {"strategy"}
        given["search"] = {key: value for key, value in given.get("search", {}).items() if key not in common}
    return {key: given[key] for key in full if given.get(key) not in (None, {}, [])}


def spec_note(spec: SpaceSpec) -> str:
    """The spec's caption: what is left out of it, and what stays."""
    said = "As the sweep stored it, without the keys left at their defaults (docs/space.md lists them)"
    return said + (
        "; the search's strategy, max_points and seed stay, as they chose its points."
        if budgeted(spec)
        else "; a grid has no budget or seed to show."
    )


def _ranked_columns(ranking: Ranking) -> pd.DataFrame:
    """The ranking's points with a robust figure's column headed by what it is (``ranked by: q90 of total
    y``), not by its CSV name ``y_robust``."""
    if ranking.ranked_by == ranking.objective:
        return ranking.totals
    figure = figure_label(ranking.objective, ranking.reduced, ranking.uncertainty["ranked_by"])
    return ranking.totals.rename(columns={ranking.ranked_by: f"ranked by: {figure}"})


def submission_line(status: SweepReport) -> tuple[str, str]:
    """The summary's line on the submission that ran the sweep's tasks: a later one that found them all done
    leaves the status file as it was (sweep.submit), so the figures are the run that made the rows."""
    name = "last submission that ran tasks" if status.ran else "last submission"
    return (
        name,
        f"{status.state}: ran {status.ran} tasks in {status.seconds:.1f} s on {status.workers} workers",
    )


def build_report(output: store.Root, sweep: str | None = None) -> str:
    """The report of ``sweep`` in ``output`` as one HTML string."""
    sweep = pick_sweep(output, sweep)
    with ThreadPoolExecutor(1) as aside:  # a large design's bootstrap (numpy, GIL released) beside the rest
        studied = aside.submit(sensitivity_sections, output, sweep)
        ranking = rank(output, sweep)
        return _page(output, sweep, ranking, lambda: [*studied.result(), *uncertainty_sections(ranking)])


def _page(output: store.Root, sweep: str, ranking: Ranking, studied: Callable[[], list[Section]]) -> str:
    """The page around ``ranking``; ``studied`` gives the study sections, asked for last."""
    from bokeh.embed import components
    from bokeh.resources import Resources

    spec = load_sweep_spec(output, sweep)
    status = load_status(output, sweep)
    feed = Feed(output, sweep)
    snap = feed.snapshot()
    ok, scenarios = snap.ok, feed.scenarios(snap)
    parameters = ranking.parameters
    scattered = feed.sampled(snap)  # a search's or a design's points lie off any grid: dots, not lines

    figures: dict[str, object] = {}
    by_parameter = charts.ObjectiveByParameter(
        parameters, ranking.objective, sorted(set(scenarios.values())), scattered
    )
    by_parameter.update(ok)
    figures["by_parameter"] = charts.fill_width(by_parameter.layout)
    by_group = charts.ErrorByGroup(parameters, ranking.objective, scenarios, scattered)
    by_group.update(ok)
    figures["by_group"] = charts.fill_width(by_group.layout)
    goals = spec.ranking.pareto_goals()
    notes = {
        **figure_notes(ranking.objective, parameters, scattered, charts.is_binned(ok, scattered)),
        "spec": spec_note(spec),
    }
    if len(goals) >= 2 and not ranking.pareto.empty:
        pareto = charts.ParetoChart(goals[0][0], goals[1][0], parameters, ranking.reduced)
        pareto.update(ranking.totals, ranking.pareto)
        figures["pareto"] = charts.fill_width(pareto.figure)
        notes["pareto"] = pareto_note(goals, ranking.reduced)
    history = load_history(output, sweep)
    search: list[tuple[str, str]] = []
    if history is not None:
        search = search_summary(
            status.search if status else None,
            history,
            ranking.objective,
            ranking.goal,
            spec.search.max_points,
            spec.search.strategy,
        )
        best = charts.BestSoFarChart(ranking.objective, ranking.goal, len(scenarios))
        best.update(history)
        progress = [best.figure]
        if len(goals) >= 2:
            growth = charts.ParetoGrowthChart(goals, parameters)
            growth.update(history)
            progress.append(growth.figure)
        figures["search"] = charts.fill_width(charts.grid(progress))
    tracks = _tracks(feed, ranking, sorted(scenarios))
    if tracks.layout is not None:
        figures["tracks"] = tracks.layout
    script, divs = components(figures)

    studies = [section_html(section) for section in studied()]
    summary = [
        ("best point", format_point(ranking.best)),
        (ranking.ranked_label, f"{ranking.best_total:.4f}"),
        ("points ranked", str(len(ranking.totals))),
        ("incomplete points", str(ranking.incomplete_points)),
        ("failed tasks", str(ranking.failed_rows)),
        ("scenarios", str(len(scenarios))),
    ]
    if ranking.stopped_points:  # rank.py's rule: after the complete points
        summary.insert(3, ("ranked last: a run an FMU stopped early", str(ranking.stopped_points)))
    if status is not None:
        summary.append(submission_line(status))
    return PAGE.render(
        sweep=sweep,
        output=html.escape(str(output)),
        generated=time.strftime("%Y-%m-%d %H:%M %Z"),
        summary=[(name, html.escape(value)) for name, value in summary],
        objective=ranking.objective,
        top=TOP,
        points=len(ranking.totals),
        table1=charts.html_table(ranking.table1.rename(columns=TABLE1_HEADINGS)),
        table1_scope=html.escape(table1_scope(ranking)),
        totals=charts.html_table(_ranked_columns(ranking).head(TOP)),
        pareto=charts.html_table(ranking.pareto) if not ranking.pareto.empty else "",
        groups=charts.html_table(ranking.groups) if not ranking.groups.empty else "",
        weighted=charts.html_table(ranking.weighted.head(10)) if not ranking.weighted.empty else "",
        plots=divs,
        notes={name: html.escape(note) for name, note in notes.items()},
        studies=studies,
        tracks_heading=html.escape(tracks.heading),
        tracks_note=html.escape(tracks.note),
        front_growth=len(goals) >= 2,
        over=spec.ranking.over_scenarios,
        ranked_label=html.escape(ranking.ranked_label),
        search=[(name, html.escape(value)) for name, value in search],
        spec=html.escape(yaml.safe_dump(shown_spec(spec), sort_keys=False)),
        table_style=charts.TABLE_STYLE,
        bokeh_resources=Resources(mode="inline", components=["bokeh"]).render(),
        bokeh_script=script,
    )


def write_report(output: store.Root, path: Path, sweep: str | None = None) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(build_report(output, sweep))
    return path
