"""The figures the dashboard and the report share, as Bokeh models fed by ColumnDataSources.

Each chart is built once and refilled by ``update(...)``: the live dashboard refills
its charts every second from the store, the report fills them once. Bokeh draws; what
is drawn (which means, which lines) is computed here from result rows with pandas.

- :class:`ObjectiveByParameter`: the objective against each parameter, one line per
  scenario coloured by its group (the paper's Figure 5);
- :class:`ErrorByGroup`: for each scenario group, the objective at every parameter point,
  one line per scenario (the paper's Figure 6); both draw a search's points as dots
  (``scattered``): they lie off any grid, each its own x, and a line through them zigzags;
- :class:`TrackChart`: a simulated track over the recorded GPS fixes;
- :class:`ParetoChart`: the complete points on two objectives, the front joined;
- :class:`BestSoFarChart`: a closed-loop search's best value against simulations run
  (:func:`best_so_far`);
- :class:`ParetoGrowthChart`: a search's points on two objectives coloured by tell order, with
  the front as it stood at a few stages (:func:`pareto_stages`);
- :func:`html_table`: a data frame as an HTML table (ranking, workers, Table 1).

Charts stand in rows of at most three (:func:`grid`), toolbars at the right, titles sized to fit
(:func:`title_size`), legends below the plot where they hide no point (:func:`_legend_below`), an entry
only for a glyph with something drawn (:func:`legend_follows_data`): the dashboard fits a 1400 px window,
and the report stretches its figures to its page's width (:func:`fill_width`).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from bokeh.layouts import gridplot
from bokeh.models import ColorBar, ColumnDataSource, HoverTool, LegendItem, LinearColorMapper
from bokeh.palettes import Category10, Viridis256
from bokeh.plotting import figure

from ..sweeps.history import Asked, SearchHistory
from ..sweeps.rank import pareto_mask

PALETTE = Category10[10]
WIDTH, HEIGHT = 380, 300
PER_ROW = 3  # charts side by side: 3 * WIDTH and their toolbar fit the dashboard on a 1400 px page
NARROWEST_PAGE = 1200  # px: the report's body in a 1280 px window (less its margins), which its figures fill
TALLER = {1: 1.5, 2: 1.2}  # a report's row of one or two charts, stretched wider, is made this much taller
PAD = 0.15  # Pareto charts' ranges beyond their points: a marker at the edge is drawn whole
LEGEND_PT, LEGEND_CHAR, LEGEND_ITEM = 8, 6.0, 40  # legend font, a label character's px, a glyph's px
LEGEND_ROW = 22  # px a row of a legend below the plot takes
TITLE_PT = 11.0  # a chart title's font size, unless it must shrink to fit
SMALLEST_TITLE_PT = 7.0
TITLE_EM = (
    0.62  # a title character's mean advance in ems, with a margin (our titles measure 0.57 in Chromium)
)
AXIS_ROOM = 80  # px left of the plot frame, where a title starts: the y axis, its tick labels and its label


def colours(names: Sequence[str]) -> dict[str, str]:
    """A fixed colour per name (sorted), so a group keeps its colour as results arrive."""
    return {name: PALETTE[i % len(PALETTE)] for i, name in enumerate(sorted(set(names)))}


def _figure(title: str, x_label: str, y_label: str, **options) -> figure:
    """A chart with its toolbar on the right, where it takes no room from the title."""
    fig = figure(
        title=title,
        width=WIDTH,
        height=HEIGHT,
        x_axis_label=x_label,
        y_axis_label=y_label,
        tools="pan,wheel_zoom,box_zoom,reset,save",
        toolbar_location="right",
        **options,
    )
    fig.title.text_font_size = title_size([title], fig.width)
    return fig


def title_size(titles: Sequence[str], width: int) -> str:
    """The font size at which the longest of ``titles`` fits a chart ``width`` px wide: Bokeh draws a title
    on its canvas and cuts off what runs past the edge (a long parameter or scenario name)."""
    longest = max((len(t) for t in titles), default=0)
    room = width - AXIS_ROOM  # px; a point is 4/3 px
    fits = 0.75 * room / (TITLE_EM * longest) if longest else TITLE_PT
    return f"{max(SMALLEST_TITLE_PT, min(TITLE_PT, fits)):.1f}pt"


def grid(figures: Sequence[figure]):
    """Charts in rows of at most PER_ROW, one toolbar for them all on the right: a row fits a 1400 px page,
    and no title shares its line with a toolbar. Titles get one size, the one the longest fits."""
    size = title_size([f.title.text for f in figures], WIDTH)
    for fig in figures:
        fig.title.text_font_size = size
    return gridplot(list(figures), ncols=PER_ROW, toolbar_location="right")


def legend_columns(labels: Sequence[str], width: int = WIDTH) -> int:
    """How many of ``labels``' legend entries fit side by side under a plot ``width`` px wide."""
    widest = max((len(label) for label in labels), default=0)
    return max(1, min(len(labels), int((width - AXIS_ROOM) // (LEGEND_ITEM + LEGEND_CHAR * widest))))


def legend_room(label_sets: Sequence[Sequence[str]]) -> tuple[int, int]:
    """(columns, rows) for the legends of one grid's panels, each holding one of ``label_sets``: the same for
    every panel, so that the panels' plots stand as tall as each other."""
    columns = legend_columns([label for labels in label_sets for label in labels])
    return columns, max((-(-len(labels) // columns) for labels in label_sets), default=1)


def _legend_below(fig: figure, room: tuple[int, int] | None = None) -> None:
    """The legend in rows under the plot, where it hides no point: ``room`` (columns, rows) as
    :func:`legend_room` gives it, else room for its own entries, each a ``legend_label``."""
    legend = fig.legend[0]
    columns, lines = room or legend_room([[item.label.value for item in legend.items]])
    legend.orientation, legend.label_text_font_size, legend.ncols = "horizontal", f"{LEGEND_PT}pt", columns
    legend.margin, legend.padding, legend.spacing, legend.location = 4, 4, 6, "center"
    fig.add_layout(legend, "below")
    fig.height += LEGEND_ROW * max(1, lines) + 8


def source_rows(source: ColumnDataSource) -> int:
    """How many rows a data source holds (its longest column)."""
    return max((len(column) for column in source.data.values()), default=0)


def legend_follows_data(fig: figure) -> None:
    """Show a legend entry only while its glyph has something to draw: a study without recordings has no
    "recorded" entry, nor a search without an ok point a "best so far"; a legend with no entry is hidden."""
    for legend in fig.legend:
        for item in legend.items:
            item.visible = any(source_rows(renderer.data_source) > 0 for renderer in item.renderers)
        legend.visible = any(item.visible for item in legend.items)


def fill_width(layout):
    """``layout`` (a chart or :func:`grid`'s charts) stretched to the width of the page that holds it: the
    report's figures fill its body whatever the window, a row of one or two charts shares the width and
    stands taller. Titles are sized for the narrowest page the report is made for."""
    from bokeh.models import GridPlot

    placed = list(layout.children) if isinstance(layout, GridPlot) else [(layout, 0, 0)]
    columns = 1 + max(column for _, _, column in placed)
    size = title_size([fig.title.text for fig, _, _ in placed], NARROWEST_PAGE // columns - 30)
    for fig, _, _ in placed:
        fig.sizing_mode = "stretch_width"
        fig.height = int(fig.height * TALLER.get(columns, 1.0))
        fig.title.text_font_size = size
    layout.sizing_mode = "stretch_width"
    return layout


def _empty_lines() -> dict[str, list]:
    return {"xs": [], "ys": [], "scenario": [], "group": [], "colour": []}


def lines(
    ok: pd.DataFrame, x: str, objective: str, colour_of: dict[str, str], by: str = "group"
) -> dict[str, list]:
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


def _empty_dots() -> dict[str, list]:
    return {"x": [], "y": [], "scenario": [], "group": [], "colour": [], "legend": []}


def dots(
    ok: pd.DataFrame, x: str, objective: str, colour_of: dict[str, str], by: str = "group"
) -> dict[str, Any]:
    """Every row a dot at its ``x`` and ``objective``, coloured by ``colour_of[row[by]]``: a search's points,
    each its own x, have no mean over the other parameters to join. Columns for a ``scatter`` glyph."""
    return {
        "x": ok[x].to_numpy(float),
        "y": ok[objective].to_numpy(float),
        "scenario": ok["scenario"].to_numpy(),
        "group": ok["group"].to_numpy(),
        "colour": [colour_of.get(v, "grey") for v in ok[by]],
        "legend": ok[by].to_numpy(),
    }


MAX_DOTS = 5000  # rows of a sampled design drawn as dots; above, a binned mean and band (megabytes, a blot)
BINS = 30  # bins of a parameter's range in the binned view
BAND = (0.1, 0.9)  # the quantiles the band spans


def _empty_bands() -> dict[str, list]:
    return {"xs": [], "ys": [], "colour": []}


def binned(
    ok: pd.DataFrame, x: str, objective: str, colour_of: dict[str, str], by: str = "group", bins: int = BINS
) -> tuple[dict[str, list], dict[str, list]]:
    """Per scenario, over ``bins`` equal bins of column ``x``: the mean ``objective`` (a line, as ``lines``
    makes them) and the band between its ``BAND`` quantiles (a patch). What a sampled design of 10^5 rows
    shows of its objective against a parameter, in a few kilobytes."""
    means, bands = _empty_lines(), _empty_bands()
    for scenario, rows in ok.groupby("scenario", sort=True):
        values = rows[x].to_numpy(float)
        edges = np.linspace(values.min(), values.max(), bins + 1)
        where = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, bins - 1)
        per_bin = rows[objective].groupby(where)
        mean = per_bin.mean()
        low, high = per_bin.quantile(BAND[0]).to_numpy(float), per_bin.quantile(BAND[1]).to_numpy(float)
        centres = ((edges[:-1] + edges[1:]) / 2)[mean.index.to_numpy()]
        colour = colour_of.get(rows[by].iloc[0], "grey")
        means["xs"].append(centres)
        means["ys"].append(mean.to_numpy(float))
        means["scenario"].append(scenario)
        means["group"].append(rows["group"].iloc[0])
        means["colour"].append(colour)
        bands["xs"].append(np.concatenate([centres, centres[::-1]]))
        bands["ys"].append(np.concatenate([low, high[::-1]]))
        bands["colour"].append(colour)
    return means, bands


@dataclass
class _Sources:
    """What one panel draws: lines (a grid's means, or a large design's binned means), a large design's
    quantile bands, and dots (a search's or a smaller design's points)."""

    lines: ColumnDataSource
    bands: ColumnDataSource
    dots: ColumnDataSource

    @classmethod
    def empty(cls) -> _Sources:
        return cls(
            ColumnDataSource(_empty_lines()),
            ColumnDataSource(_empty_bands()),
            ColumnDataSource(_empty_dots()),
        )

    def fill(
        self, ok: pd.DataFrame, x: str, objective: str, colour_of: dict[str, str], by: str, scattered: bool
    ) -> None:
        self.show(contents(ok, x, objective, colour_of, by, scattered))

    def show(self, drawn: Contents) -> None:
        """Hand what :func:`contents` computed to the browser."""
        self.lines.data, self.bands.data, self.dots.data = drawn


Contents = tuple[dict[str, Any], dict[str, Any], dict[str, Any]]  # a panel's lines, bands and dots


def contents(
    ok: pd.DataFrame, x: str, objective: str, colour_of: dict[str, str], by: str, scattered: bool
) -> Contents:
    """What one panel draws: a grid's lines; a sampled design's dots up to MAX_DOTS rows, its binned means
    and bands above. Computed apart from the Bokeh models, so a server can do it off its event loop."""
    if not scattered:
        return lines(ok, x, objective, colour_of, by), _empty_bands(), _empty_dots()
    if not is_binned(ok, scattered):
        return _empty_lines(), _empty_bands(), dots(ok, x, objective, colour_of, by)
    return (*binned(ok, x, objective, colour_of, by), _empty_dots())


def is_binned(ok: pd.DataFrame, scattered: bool) -> bool:
    """Whether a sampled design's rows are too many for dots: its binned means and bands are drawn."""
    return scattered and len(ok) > MAX_DOTS


def _draw(fig: figure, sources: _Sources, legend: str, room: tuple[int, int]) -> None:
    """Lines (a grid's means, or a large design's binned means over their quantile bands), and dots (a
    search's points); the legend below, in ``room``, showing only what has data."""
    line = fig.multi_line(
        "xs",
        "ys",
        line_color="colour",
        line_width=1.6,
        line_alpha=0.85,
        legend_field=legend,
        source=sources.lines,
    )
    # its own legend column: Bokeh merges entries of one field name across glyphs, and their sources differ
    dot = fig.scatter(
        "x", "y", color="colour", size=6, alpha=0.75, legend_field="legend", source=sources.dots
    )
    fig.patches(
        "xs",
        "ys",
        fill_color="colour",
        fill_alpha=0.15,
        line_alpha=0.0,
        source=sources.bands,
        level="underlay",
    )
    fig.add_tools(HoverTool(renderers=[line, dot], tooltips=[("scenario", "@scenario"), ("group", "@group")]))
    _legend_below(fig, room)


class ObjectiveByParameter:
    """The paper's Figure 5: the objective against each parameter, other parameters averaged out; for a
    search (``scattered``), each point's objective as a dot."""

    def __init__(self, parameters: list[str], objective: str, groups: Sequence[str], scattered: bool = False):
        self.objective, self.scattered = objective, scattered
        self.colour_of = colours(groups)
        self.sources = {p: _Sources.empty() for p in parameters}
        room = legend_room([list(self.colour_of)])  # every panel has a line per group
        self.figures = []
        for name, sources in self.sources.items():
            fig = _figure(
                name, name, objective if scattered else f"mean {objective}", name=f"dse-by-parameter-{name}"
            )
            _draw(fig, sources, "group", room)
            self.figures.append(fig)
        self.layout = grid(self.figures)

    def update(self, ok: pd.DataFrame) -> None:
        self.show(self.prepare(ok))

    def prepare(self, ok: pd.DataFrame) -> tuple[list[Contents], bool]:
        """Each panel's contents, and whether they are binned: all the work of an update, none of it on
        Bokeh's models."""
        return (
            [
                contents(ok, name, self.objective, self.colour_of, "group", self.scattered)
                for name in self.sources
            ],
            is_binned(ok, self.scattered),
        )

    def show(self, prepared: tuple[list[Contents], bool]) -> None:
        drawn, binned_ = prepared
        for (name, sources), fig, panel in zip(self.sources.items(), self.figures, drawn):
            sources.show(panel)
            if self.scattered:  # dots, or above MAX_DOTS rows the binned mean with its band
                fig.yaxis.axis_label = (
                    self.objective
                    if not binned_
                    else (f"mean {self.objective}, {round(100 * BAND[0])}-{round(100 * BAND[1])} % band")
                )
            legend_follows_data(fig)


def point_index(ok: pd.DataFrame, parameters: list[str]) -> pd.Series:
    """Each row's parameter point as an integer: points sorted by their values, so the same point
    has the same x in every scenario's line."""
    if ok.empty:
        return pd.Series(dtype=float, index=ok.index)
    columns = [ok[p].to_numpy() for p in parameters]
    if not all(np.issubdtype(c.dtype, np.number) for c in columns):  # text values: pandas orders them
        keys = pd.MultiIndex.from_frame(ok[parameters])
        return pd.Series(keys.unique().sort_values().get_indexer(keys), index=ok.index, dtype=float)
    order = np.lexsort(columns[::-1])  # numpy sorts without the GIL: a million rows beside a live page
    ordered = np.stack([c[order] for c in columns])
    new = np.concatenate([[True], (ordered[:, 1:] != ordered[:, :-1]).any(axis=0)])
    index = np.empty(len(order))
    index[order] = np.cumsum(new) - 1
    return pd.Series(index, index=ok.index)


class ErrorByGroup:
    """The paper's Figure 6: one panel per scenario group, the objective at every parameter
    point, a line per scenario of the group; for a search (``scattered``), dots."""

    def __init__(
        self, parameters: list[str], objective: str, scenarios: dict[str, str], scattered: bool = False
    ):
        self.parameters, self.objective, self.scenarios, self.scattered = (
            parameters,
            objective,
            scenarios,
            scattered,
        )
        self.colour_of = colours(scenarios)  # scenario -> colour; scenarios of a group differ
        self.sources = {g: _Sources.empty() for g in sorted(set(scenarios.values()))}
        room = legend_room([[s for s, of in scenarios.items() if of == g] for g in self.sources])
        self.figures = []
        for group, sources in self.sources.items():
            fig = _figure(f"group {group}", "parameter point #", objective, name=f"dse-by-group-{group}")
            _draw(fig, sources, "scenario", room)
            self.figures.append(fig)
        self.layout = grid(self.figures)

    def update(self, ok: pd.DataFrame) -> None:
        self.show(self.prepare(ok))

    def prepare(self, ok: pd.DataFrame) -> list[Contents]:
        """Each panel's contents (see ObjectiveByParameter.prepare)."""
        indexed = ok.assign(point=point_index(ok, self.parameters))
        return [
            contents(
                indexed[indexed["group"] == group],
                "point",
                self.objective,
                self.colour_of,
                "scenario",
                self.scattered,
            )
            for group in self.sources
        ]

    def show(self, prepared: list[Contents]) -> None:
        for sources, fig, panel in zip(self.sources.values(), self.figures, prepared):
            sources.show(panel)
            legend_follows_data(fig)


class TrackChart:
    """A simulation over its recording (comparison.py): a track over GPS fixes, or a signal over time."""

    def __init__(self, title: str = "", width: int = 2 * WIDTH, height: int = int(1.6 * HEIGHT)):
        self.recorded = ColumnDataSource({"x": [], "y": []})
        self.simulated = ColumnDataSource({"x": [], "y": []})
        self.figure = figure(
            title=title,
            width=width,
            height=height,
            match_aspect=True,
            tools="pan,wheel_zoom,box_zoom,reset,save",
            toolbar_location="right",
        )
        self.figure.scatter("x", "y", source=self.recorded, size=3, color="#777777", legend_label="recorded")
        self.figure.line(
            "x", "y", source=self.simulated, line_width=2, color=PALETTE[0], legend_label="simulated"
        )
        _legend_below(self.figure)

    def update(self, comparison, title: str) -> None:
        recorded = comparison.recorded or (np.array([]), np.array([]))
        self.recorded.data = {"x": recorded[0], "y": recorded[1]}
        self.simulated.data = {"x": comparison.simulated[0], "y": comparison.simulated[1]}
        self.figure.xaxis.axis_label = comparison.x_label
        self.figure.yaxis.axis_label = comparison.y_label
        self.figure.match_aspect = comparison.equal_axes
        self.figure.title.text = title
        self.figure.title.text_font_size = title_size([title], self.figure.width)
        legend_follows_data(self.figure)


class ParetoChart:
    """Every complete point on the first two Pareto objectives (totals), the front joined."""

    def __init__(self, x: str, y: str, parameters: list[str], reduced: str = "total"):
        self.x, self.y, self.parameters = x, y, parameters
        self.points = ColumnDataSource({x: [], y: [], **{p: [] for p in parameters}})
        self.front = ColumnDataSource({x: [], y: []})
        self.figure = _figure("Pareto front", f"{reduced} {x}", f"{reduced} {y}", name="dse-pareto")
        self.figure.x_range.range_padding = self.figure.y_range.range_padding = PAD
        dots = self.figure.scatter(x, y, source=self.points, size=6, color="#9a9a9a", legend_label="points")
        front_line = self.figure.line(x, y, source=self.front, color=PALETTE[3], line_width=2)
        front_dots = self.figure.scatter(x, y, source=self.front, size=8, color=PALETTE[3])
        self.figure.legend.items.append(LegendItem(label="front", renderers=[front_line, front_dots]))
        self.figure.add_tools(HoverTool(renderers=[dots], tooltips=[(p, f"@{{{p}}}") for p in parameters]))
        _legend_below(self.figure)

    def update(self, totals: pd.DataFrame, front: pd.DataFrame) -> None:
        shown = totals if len(totals) <= MAX_DOTS else totals.sample(MAX_DOTS, random_state=0)  # front: whole
        self.figure.title.text = (
            "Pareto front"
            if shown is totals
            else (f"Pareto front; {MAX_DOTS} of the {len(totals)} points, drawn at random")
        )
        self.points.data = {c: shown[c].to_numpy() for c in (self.x, self.y, *self.parameters)}
        ordered = front.sort_values(self.x)
        self.front.data = {self.x: ordered[self.x].to_numpy(), self.y: ordered[self.y].to_numpy()}
        legend_follows_data(self.figure)


# --- a closed-loop search's history (sweeps/history.py) ------------------------------------------


def told_in_order(history: SearchHistory) -> list[Asked]:
    """The points the strategy has been told about, in the order it was told."""
    return sorted((p for p in history.points if p.told is not None), key=lambda p: p.told)


def _key(point: dict[str, Any]) -> str:
    return json.dumps(point, sort_keys=True, default=str)


def best_so_far(history: SearchHistory, objective: str, goal: str, n_scenarios: int) -> pd.DataFrame:
    """The search's progress, one row per point told with a result (ok or failed), in tell order.

    Columns: ``told`` (place among the tells), ``number`` (ask order), ``state``, ``simulated``
    (False for a point asked again after an earlier copy was told: the search took its result from
    the store), ``simulations`` (run up to and including this point: one per scenario for each
    simulated point; infeasible points cost none and have no row), ``value`` (the point's
    ``objective`` reduced over scenarios; NaN unless ok) and ``best`` (the best ok value so far by
    ``goal``; NaN before the first ok point)."""
    told = told_in_order(history)
    first_told: dict[str, int] = {}
    for p in told:
        first_told.setdefault(_key(p.point), p.told)
    rows = [p for p in told if p.state in ("ok", "failed")]
    simulated = np.array([first_told[_key(p.point)] >= p.asked_after for p in rows], dtype=bool)
    value = np.array(
        [p.values.get(objective, np.nan) if p.state == "ok" else np.nan for p in rows], dtype=float
    )
    sign = 1.0 if goal == "min" else -1.0
    best = (
        sign * np.minimum.accumulate(np.where(np.isnan(value), np.inf, sign * value)) if rows else np.zeros(0)
    )
    return pd.DataFrame(
        {
            "told": np.array([p.told for p in rows], dtype=int),
            "number": np.array([p.number for p in rows], dtype=int),
            "state": [p.state for p in rows],
            "simulated": simulated,
            "simulations": np.cumsum(simulated) * max(1, n_scenarios),
            "value": value,
            "best": np.where(np.isinf(best), np.nan, best),
        }
    )


STAGES = (0.25, 0.5, 0.75, 1.0)  # shares of the told points after which the growing front is drawn
STAGE_COLOURS = ("#c6dbef", "#6baed6", "#2171b5", "#08306b")  # light (early) to dark (all points)


def search_points(history: SearchHistory, objectives: Sequence[str]) -> pd.DataFrame:
    """The told ok points with every one of ``objectives``, in tell order: ``order`` (0, 1, ...: their
    place among these points), ``told``, ``number``, the objectives and the point's parameters."""
    rows = [
        p
        for p in told_in_order(history)
        if p.state == "ok" and all(np.isfinite(p.values.get(o, np.nan)) for o in objectives)
    ]
    frame = pd.DataFrame(
        [
            {"told": p.told, "number": p.number, **{o: p.values[o] for o in objectives}, **p.point}
            for p in rows
        ],
        columns=None if rows else ["told", "number", *objectives],
    )
    frame.insert(0, "order", np.arange(len(frame), dtype=int))
    return frame


def pareto_stages(
    points: pd.DataFrame, goals: Sequence[tuple[str, str]], stages: Sequence[float] = STAGES
) -> list[tuple[int, pd.DataFrame]]:
    """The front as it grew: for each share in ``stages``, (n, the non-dominated rows among the first
    n of ``points``), n = ceil(share * len(points)); fronts sorted by the first objective. ``points``
    in tell order, as :func:`search_points` gives them; ``goals`` (objective, "min" | "max")."""
    names, directions = [n for n, _ in goals], [g for _, g in goals]
    fronts = []
    for share in stages:
        n = int(np.ceil(share * len(points) - 1e-9))
        first = points.iloc[:n]
        front = first[pareto_mask(first[names].to_numpy(float), directions)] if n else first
        fronts.append((n, front.sort_values(names[0], kind="stable").reset_index(drop=True)))
    return fronts


class BestSoFarChart:
    """A search's best ``objective`` so far against the simulations run, each point's value a faint dot."""

    def __init__(self, objective: str, goal: str, n_scenarios: int):
        self.objective, self.goal, self.n_scenarios = objective, goal, n_scenarios
        self.best = ColumnDataSource({"simulations": [], "best": []}, name="dse-best-so-far-line")
        self.points = ColumnDataSource(
            {"simulations": [], "value": [], "number": []}, name="dse-best-so-far-points"
        )
        self.figure = _figure(
            f"best {objective} so far", "simulations", f"{objective} ({goal})", name="dse-best-so-far"
        )
        self.figure.width = int(1.4 * WIDTH)
        dots = self.figure.scatter(
            "simulations",
            "value",
            source=self.points,
            size=5,
            color=PALETTE[0],
            alpha=0.3,
            legend_label="each point",
        )
        self.figure.step(
            "simulations",
            "best",
            source=self.best,
            mode="after",
            line_width=2,
            color=PALETTE[3],
            legend_label="best so far",
        )
        self.figure.add_tools(
            HoverTool(
                renderers=[dots],
                tooltips=[("point #", "@number"), ("simulations", "@simulations"), (objective, "@value")],
            )
        )
        _legend_below(self.figure)

    def update(self, history: SearchHistory) -> pd.DataFrame:
        progress = best_so_far(history, self.objective, self.goal, self.n_scenarios)
        ok = progress[progress["state"] == "ok"]
        self.points.data = {
            "simulations": ok["simulations"].to_numpy(),
            "value": ok["value"].to_numpy(),
            "number": ok["number"].to_numpy(),
        }
        shown = progress[progress["best"].notna()]
        self.best.data = {"simulations": shown["simulations"].to_numpy(), "best": shown["best"].to_numpy()}
        legend_follows_data(self.figure)
        return progress


class ParetoGrowthChart:
    """A search's points on its first two Pareto objectives, coloured by tell order, with the front
    after 25, 50, 75 and 100% of them drawn as steps: how the front grew."""

    def __init__(self, goals: Sequence[tuple[str, str]], parameters: list[str]):
        self.goals = list(goals[:2])
        (x, x_goal), (y, y_goal) = self.goals
        self.x, self.y, self.parameters = x, y, parameters
        self.points = ColumnDataSource(
            {"x": [], "y": [], "order": [], **{p: [] for p in parameters}}, name="dse-front-growth-points"
        )
        self.mapper = LinearColorMapper(palette=Viridis256, low=0, high=1)
        self.figure = _figure(
            "Pareto front as the search went", f"{x} ({x_goal})", f"{y} ({y_goal})", name="dse-front-growth"
        )
        self.figure.x_range.range_padding = self.figure.y_range.range_padding = PAD
        self.figure.width = int(1.4 * WIDTH)
        dots = self.figure.scatter(
            "x",
            "y",
            source=self.points,
            size=6,
            alpha=0.8,
            color={"field": "order", "transform": self.mapper},
        )
        self.figure.add_tools(
            HoverTool(
                renderers=[dots], tooltips=[("told #", "@order"), *((p, f"@{{{p}}}") for p in parameters)]
            )
        )
        # sorted by x, the front holds each y until the next point: rightwards if x is minimised
        mode = "after" if x_goal == "min" else "before"
        self.fronts = []
        for share, colour in zip(STAGES, STAGE_COLOURS):
            source = ColumnDataSource({"x": [], "y": []}, name=f"dse-front-growth-{share:.0%}".rstrip("%"))
            label = (
                f"front after {share:.0%}"
                if share == STAGES[0]
                else f"{share:.0%} of points"
                if share == 1
                else f"{share:.0%}"
            )
            self.figure.step(
                "x",
                "y",
                source=source,
                mode=mode,
                line_width=2 if share == 1 else 1.5,
                color=colour,
                legend_label=label,
            )
            self.fronts.append(source)
        self.figure.add_layout(ColorBar(color_mapper=self.mapper, title="tell order", width=8), "right")
        _legend_below(self.figure)

    def update(self, history: SearchHistory) -> list[tuple[int, pd.DataFrame]]:
        points = search_points(history, [self.x, self.y])
        self.points.data = {
            "x": points[self.x].to_numpy(float),
            "y": points[self.y].to_numpy(float),
            "order": points["order"].to_numpy(),
            **{
                p: points[p].to_numpy() if p in points else np.full(len(points), np.nan)
                for p in self.parameters
            },
        }
        self.mapper.high = max(1, len(points) - 1)
        stages = pareto_stages(points, self.goals)
        for source, (_, front) in zip(self.fronts, stages):
            source.data = {"x": front[self.x].to_numpy(float), "y": front[self.y].to_numpy(float)}
        legend_follows_data(self.figure)
        return stages


def html_table(
    frame: pd.DataFrame, table_id: str | None = None, formats: dict[str, Callable[[Any], str]] | None = None
) -> str:
    """``frame`` as a plain HTML table (class ``frame``): what the report prints and the dashboard
    refreshes (Bokeh 3.9's DataTable does not redraw rows whose data were replaced)."""
    return frame.to_html(
        index=False,
        border=0,
        classes="frame",
        table_id=table_id,
        formatters=formats,
        float_format=lambda v: f"{v:.6g}",
        na_rep="–",
    )


TABLE_STYLE = """<style>
table.frame { border-collapse: collapse; font: 13px sans-serif; margin: 8px 0 }
table.frame th, table.frame td { padding: 3px 10px; text-align: right; border-bottom: 1px solid #eee }
table.frame th { background: #f4f4f4 }
</style>"""
