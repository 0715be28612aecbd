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
from pathlib import Path

import pandas as pd
import yaml
from jinja2 import Template

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
from ..errors import DseError
from ..sweeps import store
from ..sweeps.history import load_history
from ..sweeps.status import SweepReport, load_status
from . import charts
from .dashboard import Feed, search_summary
from .study_figures import section_html, sections

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
and points asked again after their first copy was told, cost none); the line is the best {{ objective }} so far, the dots each point's.{% if plots.front_growth %} The
second chart has every point on the first two Pareto objectives, coloured by the order the strategy was told
them, and the front after a quarter, half, three quarters and all of them.{% endif %}</p>
<table class="summary" id="search">
{% for name, value in search %}<tr><td>{{ name }}</td><td>{{ value }}</td></tr>
{% endfor %}</table>
<div style="display:flex;gap:24px;flex-wrap:wrap">{{ plots.best_so_far }}
{% if plots.front_growth %}{{ plots.front_growth }}{% endif %}</div>{% endif %}

<h2>Table 1: {{ objective }} per scenario ({{ table1_scope }})</h2>
<p class="note">Per scenario: min, max and average over the ranked points; "best" is the best point's value
and "difference" its distance from the average (the paper's Table 1).</p>
{{ table1 }}

<h2>Ranking by {{ ranked_label }}</h2>
<p class="note">The {{ top }} best of {{ points }} points, each objective {{ "summed" if over == "sum" else
"reduced by its " ~ over }} over the scenarios.</p>
{{ totals }}

{% for section in studies %}{{ section }}
{% endfor %}
{% if pareto %}<h2>Pareto front</h2>
{{ plots.pareto }}
{{ pareto }}{% endif %}

{% if groups %}<h2>Best point per scenario group</h2>
{{ groups }}{% endif %}

{% if weighted %}<h2>Weighted ranking</h2>
{{ weighted }}{% endif %}

<h2>{{ objective }} against each parameter</h2>
{% if scattered %}<p class="note">Each point the search simulated, a dot per scenario coloured by group (the paper's
Figure 5 joins a grid's means with lines; a search's points lie off any grid).</p>
{% else %}<p class="note">Mean over the other parameters, one line per scenario coloured by group (the paper's Figure 5).</p>
{% endif %}{{ plots.by_parameter }}

<h2>{{ objective }} per scenario group</h2>
<p class="note">At every parameter point, sorted by {{ parameters }} (the paper's Figure 6){% if scattered %}; a
dot per point and scenario{% endif %}.</p>
{{ plots.by_group }}

<h2>The best point against each scenario's recording</h2>
{% if plots.tracks %}{{ plots.tracks }}{% else %}<p class="note">{{ track_note }}</p>{% endif %}

<h2>The spec</h2>
<pre>{{ spec }}</pre>
{{ bokeh_script }}
</body>
</html>
""")


def _tracks(feed: Feed, ranking: Ranking, scenarios: list[str]) -> tuple[object | None, str]:
    """A small track chart per scenario for the best point; or None and why not."""
    best = {p: plain(v) for p, v in ranking.best.items()}
    panels = []
    for scenario in scenarios:
        try:
            comparison, value = feed.track(scenario, best)
        except DseError as e:
            return None, f"No tracks: {e}"
        chart = charts.TrackChart(width=charts.WIDTH, height=charts.HEIGHT)
        chart.update(comparison, f"{scenario}: {ranking.objective} {value:.3f}")
        panels.append(chart.figure)
    return charts.grid(panels), ""


def _ranked_columns(ranking: Ranking) -> pd.DataFrame:
    """The ranking's points with a robust figure's column headed by what it is (``ranked by: q90 of total y``),
    not by its CSV name ``y_robust``."""
    if ranking.ranked_by == ranking.objective:
        return ranking.totals
    figure = figure_label(ranking.objective, ranking.reduced, ranking.uncertainty["ranked_by"])
    return ranking.totals.rename(columns={ranking.ranked_by: f"ranked by: {figure}"})


def submission_line(status: SweepReport) -> tuple[str, str]:
    """The summary's line on the submission that ran the sweep's tasks: a later one that found them all done
    leaves the status file as it was (sweep.submit), so the figures are the run that made the rows."""
    name = "last submission that ran tasks" if status.ran else "last submission"
    return name, f"{status.state}: ran {status.ran} tasks in {status.seconds:.1f} s on {status.workers} workers"


def build_report(output: store.Root, sweep: str | None = None) -> str:
    """The report of ``sweep`` in ``output`` as one HTML string."""
    from bokeh.embed import components
    from bokeh.resources import Resources

    sweep = pick_sweep(output, sweep)
    ranking = rank(output, sweep)
    spec = load_sweep_spec(output, sweep)
    status = load_status(output, sweep)
    feed = Feed(output, sweep)
    snap = feed.snapshot()
    ok, scenarios = snap.ok, feed.scenarios(snap)
    parameters = ranking.parameters
    scattered = feed.searching(snap)  # a search's points lie off any grid: dots, not lines

    figures: dict[str, object] = {}
    by_parameter = charts.ObjectiveByParameter(parameters, ranking.objective, sorted(set(scenarios.values())),
                                               scattered)
    by_parameter.update(ok)
    figures["by_parameter"] = by_parameter.layout
    by_group = charts.ErrorByGroup(parameters, ranking.objective, scenarios, scattered)
    by_group.update(ok)
    figures["by_group"] = by_group.layout
    goals = spec.ranking.pareto_goals()
    if len(goals) >= 2 and not ranking.pareto.empty:
        pareto = charts.ParetoChart(goals[0][0], goals[1][0], parameters, ranking.reduced)
        pareto.update(ranking.totals, ranking.pareto)
        figures["pareto"] = pareto.figure
    history = load_history(output, sweep)
    search: list[tuple[str, str]] = []
    if history is not None:
        search = search_summary(status.search if status else None, history, ranking.objective, ranking.goal,
                                spec.search.max_points, spec.search.strategy)
        best = charts.BestSoFarChart(ranking.objective, ranking.goal, len(scenarios))
        best.update(history)
        figures["best_so_far"] = best.figure
        if len(goals) >= 2:
            growth = charts.ParetoGrowthChart(goals, parameters)
            growth.update(history)
            figures["front_growth"] = growth.figure
    tracks, track_note = _tracks(feed, ranking, sorted(scenarios))
    if tracks is not None:
        figures["tracks"] = tracks
    script, divs = components(figures)

    studies = [section_html(section) for section in sections(output, sweep, ranking)]
    summary = [("best point", format_point(ranking.best)), (ranking.ranked_label, f"{ranking.best_total:.4f}"),
               ("points ranked", str(len(ranking.totals))), ("incomplete points", str(ranking.incomplete_points)),
               ("failed tasks", str(ranking.failed_rows)), ("scenarios", str(len(scenarios)))]
    if status is not None:
        summary.append(submission_line(status))
    return PAGE.render(
        sweep=sweep, output=html.escape(str(output)), generated=time.strftime("%Y-%m-%d %H:%M %Z"),
        summary=[(name, html.escape(value)) for name, value in summary], objective=ranking.objective, top=TOP, points=len(ranking.totals),
        parameters=", ".join(parameters),
        table1=charts.html_table(ranking.table1.rename(columns=TABLE1_HEADINGS)),
        table1_scope=html.escape(table1_scope(ranking)), scattered=scattered,
        totals=charts.html_table(_ranked_columns(ranking).head(TOP)),
        pareto=charts.html_table(ranking.pareto) if not ranking.pareto.empty else "",
        groups=charts.html_table(ranking.groups) if not ranking.groups.empty else "",
        weighted=charts.html_table(ranking.weighted.head(10)) if not ranking.weighted.empty else "",
        plots=divs, track_note=track_note, studies=studies, over=spec.ranking.over_scenarios, reduced=ranking.reduced,
        ranked_label=html.escape(ranking.ranked_label),
        search=[(name, html.escape(value)) for name, value in search],
        spec=html.escape(yaml.safe_dump(spec.model_dump(mode="json"), sort_keys=False)),
        table_style=charts.TABLE_STYLE, bokeh_resources=Resources(mode="inline", components=["bokeh"]).render(), bokeh_script=script)


def write_report(output: store.Root, path: Path, sweep: str | None = None) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(build_report(output, sweep))
    return path
