"""The figures the dashboard and the report share, as Bokeh models fed by ColumnDataSources.

Each chart is built once and refilled by ``update(...)``: the live dashboard refills
its charts every second from the store, the report fills them once. Bokeh draws; what
is drawn (which means, which lines) is computed here from result rows with pandas.

- :class:`ObjectiveByParameter`: the objective against each parameter, one line per
  scenario coloured by its group (the paper's Figure 5);
- :class:`ErrorByGroup`: for each scenario group, the objective at every parameter point,
  one line per scenario (the paper's Figure 6);
- :class:`TrackChart`: a simulated track over the recorded GPS fixes;
- :class:`ParetoChart`: the complete points on two objectives, the front joined;
- :func:`html_table`: a data frame as an HTML table (ranking, workers, Table 1).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd
from bokeh.layouts import column, row
from bokeh.models import ColumnDataSource, HoverTool
from bokeh.palettes import Category10
from bokeh.plotting import figure

PALETTE = Category10[10]
WIDTH, HEIGHT = 380, 300


def colours(names: Sequence[str]) -> dict[str, str]:
    """A fixed colour per name (sorted), so a group keeps its colour as results arrive."""
    return {name: PALETTE[i % len(PALETTE)] for i, name in enumerate(sorted(set(names)))}


def _figure(title: str, x_label: str, y_label: str, **options) -> figure:
    fig = figure(title=title, width=WIDTH, height=HEIGHT, x_axis_label=x_label, y_axis_label=y_label,
                 tools="pan,wheel_zoom,box_zoom,reset,save", toolbar_location="above", **options)
    fig.title.text_font_size = "11pt"
    return fig


def _empty_lines() -> dict[str, list]:
    return {"xs": [], "ys": [], "scenario": [], "group": [], "colour": []}


def lines(ok: pd.DataFrame, x: str, objective: str, colour_of: dict[str, str], by: str = "group") -> dict[str, list]:
    """One line per scenario: the mean ``objective`` at each value of column ``x``; coloured by
    ``colour_of[row[by]]``. Columns for a ``multi_line`` glyph."""
    data = _empty_lines()
    for scenario, rows in ok.groupby("scenario", sort=True):
        mean = rows.groupby(x)[objective].mean().sort_index()
        data["xs"].append(mean.index.to_numpy(float))
        data["ys"].append(mean.to_numpy(float))
        data["scenario"].append(scenario)
        data["group"].append(rows["group"].iloc[0])
        data["colour"].append(colour_of.get(rows[by].iloc[0], "grey"))
    return data


def _multi_line(fig: figure, source: ColumnDataSource, legend: str) -> None:
    glyph = fig.multi_line("xs", "ys", line_color="colour", line_width=1.6, line_alpha=0.85,
                           legend_field=legend, source=source)
    fig.add_tools(HoverTool(renderers=[glyph], tooltips=[("scenario", "@scenario"), ("group", "@group")]))
    fig.legend.location = "top_left"
    fig.legend.label_text_font_size = "8pt"
    fig.legend.background_fill_alpha = 0.6


class ObjectiveByParameter:
    """The paper's Figure 5: the objective against each parameter, other parameters averaged out."""

    def __init__(self, parameters: list[str], objective: str, groups: Sequence[str]):
        self.objective = objective
        self.colour_of = colours(groups)
        self.sources = {p: ColumnDataSource(_empty_lines()) for p in parameters}
        figures = []
        for name, source in self.sources.items():
            fig = _figure(f"{objective} against {name}", name, f"mean {objective}")
            _multi_line(fig, source, "group")
            figures.append(fig)
        self.layout = row(*figures)

    def update(self, ok: pd.DataFrame) -> None:
        for name, source in self.sources.items():
            source.data = lines(ok, name, self.objective, self.colour_of)


def point_index(ok: pd.DataFrame, parameters: list[str]) -> pd.Series:
    """Each row's parameter point as an integer: points sorted by their values, so the same point
    has the same x in every scenario's line."""
    if ok.empty:
        return pd.Series(dtype=float, index=ok.index)
    keys = pd.MultiIndex.from_frame(ok[parameters])
    order = keys.unique().sort_values()
    return pd.Series(order.get_indexer(keys), index=ok.index, dtype=float)


class ErrorByGroup:
    """The paper's Figure 6: one panel per scenario group, the objective at every parameter
    point, a line per scenario of the group."""

    def __init__(self, parameters: list[str], objective: str, scenarios: dict[str, str]):
        self.parameters, self.objective, self.scenarios = parameters, objective, scenarios
        self.colour_of = colours(scenarios)  # scenario -> colour; scenarios of a group differ
        self.sources = {g: ColumnDataSource(_empty_lines()) for g in sorted(set(scenarios.values()))}
        figures = []
        for group, source in self.sources.items():
            fig = _figure(f"group {group}", "parameter point #", objective)
            _multi_line(fig, source, "scenario")
            figures.append(fig)
        self.layout = row(*figures) if len(figures) <= 4 else column(
            *[row(*figures[i:i + 4]) for i in range(0, len(figures), 4)])

    def update(self, ok: pd.DataFrame) -> None:
        indexed = ok.assign(point=point_index(ok, self.parameters))
        for group, source in self.sources.items():
            source.data = lines(indexed[indexed["group"] == group], "point", self.objective, self.colour_of,
                                by="scenario")


class TrackChart:
    """A simulation over its recording (comparison.py): a track over GPS fixes, or a signal over time."""

    def __init__(self, title: str = "", width: int = 2 * WIDTH, height: int = int(1.6 * HEIGHT)):
        self.recorded = ColumnDataSource({"x": [], "y": []})
        self.simulated = ColumnDataSource({"x": [], "y": []})
        self.figure = figure(title=title, width=width, height=height, match_aspect=True,
                             tools="pan,wheel_zoom,box_zoom,reset,save", toolbar_location="above")
        self.figure.scatter("x", "y", source=self.recorded, size=3, color="#777777", legend_label="recorded")
        self.figure.line("x", "y", source=self.simulated, line_width=2, color=PALETTE[0], legend_label="simulated")
        self.figure.legend.location = "top_left"

    def update(self, comparison, title: str) -> None:
        recorded = comparison.recorded or (np.array([]), np.array([]))
        self.recorded.data = {"x": recorded[0], "y": recorded[1]}
        self.simulated.data = {"x": comparison.simulated[0], "y": comparison.simulated[1]}
        self.figure.xaxis.axis_label = comparison.x_label
        self.figure.yaxis.axis_label = comparison.y_label
        self.figure.match_aspect = comparison.equal_axes
        self.figure.title.text = title


class ParetoChart:
    """Every complete point on the first two Pareto objectives (totals), the front joined."""

    def __init__(self, x: str, y: str, parameters: list[str]):
        self.x, self.y, self.parameters = x, y, parameters
        self.points = ColumnDataSource({x: [], y: [], **{p: [] for p in parameters}})
        self.front = ColumnDataSource({x: [], y: []})
        self.figure = _figure("Pareto front", f"total {x}", f"total {y}")
        dots = self.figure.scatter(x, y, source=self.points, size=6, color="#9a9a9a", legend_label="points")
        self.figure.line(x, y, source=self.front, color=PALETTE[3], line_width=2, legend_label="front")
        self.figure.scatter(x, y, source=self.front, size=8, color=PALETTE[3])
        self.figure.add_tools(HoverTool(renderers=[dots], tooltips=[(p, f"@{{{p}}}") for p in parameters]))
        self.figure.legend.location = "top_right"

    def update(self, totals: pd.DataFrame, front: pd.DataFrame) -> None:
        self.points.data = {c: totals[c].to_numpy() for c in (self.x, self.y, *self.parameters)}
        ordered = front.sort_values(self.x)
        self.front.data = {self.x: ordered[self.x].to_numpy(), self.y: ordered[self.y].to_numpy()}


def html_table(frame: pd.DataFrame, table_id: str | None = None,
               formats: dict[str, Callable[[Any], str]] | None = None) -> str:
    """``frame`` as a plain HTML table (class ``frame``): what the report prints and the dashboard
    refreshes (Bokeh 3.9's DataTable does not redraw rows whose data were replaced)."""
    return frame.to_html(index=False, border=0, classes="frame", table_id=table_id, formatters=formats,
                         float_format=lambda v: f"{v:.6g}", na_rep="–")


TABLE_STYLE = """<style>
table.frame { border-collapse: collapse; font: 13px sans-serif; margin: 8px 0 }
table.frame th, table.frame td { padding: 3px 10px; text-align: right; border-bottom: 1px solid #eee }
table.frame th { background: #f4f4f4 }
</style>"""
