"""The live dashboard: a Bokeh server page over one sweep's store, beside Dask's own dashboard.

It reads only what any process can read: the result rows, the spec the sweep ran with
(``<sweep>.sweep.json``) and the status the submitting process saves every second
(``<sweep>.status.json``, see sweeps/status.py). So one page serves a sweep running in
this process (``submit`` starts it), one running elsewhere (``dse-runner dashboard
RESULTS``) and a finished one. The best point's track is simulated here, on demand, from
the sweep's own spec and recordings: one co-simulation takes tens of milliseconds.

For a closed-loop search the page also reads the search's history (``<sweep>.search.json``,
history.py) and shows a line of its figures, best so far against simulations, and, with two
or more Pareto objectives, the front as it grew (charts.BestSoFarChart, ParetoGrowthChart).

dask_link.py adds a "dse-runner" page to Dask's dashboard that redirects here.
"""

from __future__ import annotations

import asyncio
import html
import math
import socket
import threading
import time
import weakref
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any

import pandas as pd

from ..errors import DseError
from ..simulation.comparison import Comparison, compare
from ..sweeps import store, uncertainty
from ..sweeps.history import SearchHistory, load_history
from ..sweeps.rank import (
    current_model,
    current_rows,
    draw_standings,
    format_point,
    load_sweep_spec,
    plain,
    ranked_figure_label,
    scalar_objectives,
    standings,
    without_excluded,
)
from ..sweeps.search import strategy
from ..sweeps.spec import Space, load_space
from ..sweeps.status import SearchStatus, SweepReport, load_status
from ..sweeps.strategies.designs import SensitivityDesign
from . import charts
from .study_figures import is_sensitivity, section_html, sections

REFRESH_SECONDS = 1.0  # how often pages refresh, and how stale the shared snapshot may be
STALE_SECONDS = 30.0  # a running sweep whose status is older than this has probably lost its client
TOP = 15  # rows of the best-so-far ranking shown
STUDY_SECONDS = 10.0  # how often a running sweep's sensitivity or uncertainty figures are redrawn
STUDY_STYLE = "<style>.note {font-family: sans-serif; color: #666; font-size: 13px} h3 {font-family: sans-serif}</style>"


@dataclass
class Snapshot:
    """The sweep as read from the store at one moment."""

    status: SweepReport | None
    ok: pd.DataFrame  # ok rows of the current model: parameters, scenario, group, objective
    done: int  # tasks with a row (ok or failed)
    failed: int
    standings: pd.DataFrame  # best so far first (rank.standings or rank.draw_standings)
    history: SearchHistory | None = None  # a closed-loop search's (history.py); None for a grid
    taken: float = field(default_factory=time.monotonic)
    provisional: bool = False  # the status file's counts only, before the rows are read (Feed.provisional)


class Feed:
    """What every page of one sweep shows: read from the store at most once per REFRESH_SECONDS
    and shared by all open pages, plus the tracks they ask for."""

    def __init__(self, output: store.Root, sweep: str, space: Space | None = None):
        spec = space.spec if space is not None else load_sweep_spec(output, sweep)
        self.output, self.sweep = output, sweep
        self.parameters = list(spec.parameters)
        self.objective, self.goal = spec.ranking.objective, spec.ranking.goal
        self.settings = spec.ranking  # the best point is named as rank() names it: over_scenarios, robust, constraints
        # the objectives read: the ranked one, and every one when constraints may name others (as rank() reads them)
        every = spec.ranking.constraints
        self.objectives = scalar_objectives(spec, output, sweep) if every else [self.objective]
        self.ranked_by = ranked_figure_label(spec.ranking, spec.uncertain is not None)
        self.pareto_goals = spec.ranking.pareto_goals()
        self.uncertain = spec.uncertain  # each scenario ran once per draw: the pages show the draws' means
        self.max_points, self.strategy = spec.search.max_points, spec.search.strategy
        try:  # a closed-loop search writes a history the pages draw; a grid has none to look for
            kind = strategy(spec.search.strategy)
            self.closed_loop, self.designed = kind.closed_loop, issubclass(kind, SensitivityDesign)
        except DseError:  # a plug-in strategy this process does not have: look for its history anyway
            self.closed_loop, self.designed = True, False
        self._space, self._space_note = space, ""  # no space, and why not (once looked for)
        self._looked_for_space = space is not None
        self._lock = threading.Lock()
        self._snapshot: Snapshot | None = None
        self._version = ""  # the store's version the snapshot's rows are of
        self._studies_lock = threading.Lock()
        self._studies: tuple[tuple, str] = ((), "")  # ((store version, model), the study sections' HTML)
        self._tracks: dict[tuple, tuple] = {}
        self._track_lock = threading.Lock()
        self.pages: weakref.WeakSet[Page] = weakref.WeakSet()  # the open tabs, told when the server stops

    def latest(self) -> Snapshot | None:
        """The last snapshot taken, without waiting for one: what a page shows while the next is read."""
        return self._snapshot

    def provisional(self) -> Snapshot:
        """Before the first rows are read (a million take seconds): the counts the submitting process saved
        in its status file, which a page shows at once."""
        status = load_status(self.output, self.sweep)
        done = status.skipped + status.ran if status is not None else 0
        empty = pd.DataFrame(columns=[*self.parameters, "scenario", "group", self.objective])
        return Snapshot(status, empty, done, status.failed if status is not None else 0, empty.iloc[0:0], None,
                        provisional=True)

    def warm(self) -> None:
        """Read the first snapshot in the background, so the first page finds it ready or under way. (The
        study sections are not started here too: their bootstrap beside the page's first build delayed the
        page's first number by 2 s at a million rows, and brought the figures no sooner.)"""
        threading.Thread(target=self.snapshot, name="dse-runner-feed", daemon=True).start()

    def snapshot(self, fresh: bool = False) -> Snapshot:
        """What the store holds, looked at most every REFRESH_SECONDS (``fresh``: now); its rows are read and
        reduced once per version of the store (store.version), which a finished sweep keeps for good."""
        with self._lock:
            last = self._snapshot
            if fresh or last is None or time.monotonic() - last.taken >= REFRESH_SECONDS:
                # The status first: a sweep saves "finished" after its last rows, so rows read after it are at
                # least as new. Read the other way round, a sweep ending between the two reads showed "finished"
                # over the rows of before its last chunks until the next refresh.
                status = load_status(self.output, self.sweep)
                version = f"{store.version(self.output, self.sweep)} {current_model(self.output, self.sweep)}"
                if last is not None and version == self._version:
                    history = load_history(self.output, self.sweep) \
                        if self.closed_loop or last.history is not None else None
                    self._snapshot = replace(last, status=status, history=history, taken=time.monotonic())
                else:
                    self._snapshot, self._version = self._read(status), version
            return self._snapshot

    def _read(self, status: SweepReport | None) -> Snapshot:
        rows = current_rows(self.output, self.sweep, ["group", "status", *self.parameters, *self.objectives])
        ok = rows[rows["status"] == "ok"]
        last = self._snapshot
        if self.uncertain is not None:  # ranked over the draws; the charts get a row per point and scenario,
            drawn = uncertainty.with_draws(ok, self.uncertain.samples)  # its objective the mean over the draws
            ok = uncertainty.collapse(drawn, self.parameters, [self.objective])
            scenarios = _scenario_count(status, drawn, "base")
            table = draw_standings(drawn, self.parameters, self.objective, self.settings, scenarios)
            table = without_excluded(table, drawn, self.parameters, self.objectives, self.settings, scenarios,
                                     self.uncertain.samples)
        else:
            table = standings(ok, self.parameters, self.objective, self.goal, self.settings.over_scenarios)
            table = without_excluded(table, ok, self.parameters, self.objectives, self.settings,
                                     _scenario_count(status, rows))
        history = load_history(self.output, self.sweep) \
            if self.closed_loop or (last is not None and last.history is not None) else None
        return Snapshot(status, ok, len(rows), int((rows["status"] != "ok").sum()), table, history)

    def counted(self, scenarios: int) -> tuple[str, int]:
        """What the standings count per point and of how many: (``draws``, samples) with uncertain draws (a
        draw counts once finished on every scenario), else (``scenarios``, ``scenarios``)."""
        return ("draws", self.uncertain.samples) if self.uncertain is not None else ("scenarios", scenarios)

    def searching(self, snap: Snapshot | None) -> bool:
        """Whether the pages show a search's progress: its strategy asks for points, or it left a history."""
        return self.closed_loop or (snap is not None and snap.history is not None)

    def sampled(self, snap: Snapshot | None) -> bool:
        """Whether the points lie off any grid, each its own value (a search's, a sensitivity design's):
        Figures 5 and 6 then draw dots, or binned means, where a grid's lines of means would zigzag."""
        return self.searching(snap) or self.designed

    def scenarios(self, snap: Snapshot | None) -> dict[str, str] | None:
        """Scenario -> group: from the space if this process has it, else the status, else the rows (None
        before they are read); with uncertain draws, the scenarios themselves (each ran once per draw)."""
        status = snap.status if snap is not None else load_status(self.output, self.sweep)
        if self._space is not None:
            found = {s.name: s.group for s in self._space.scenarios}
        elif status is not None and status.scenarios:
            found = dict(status.scenarios)
        elif snap is None or snap.provisional:
            return None
        else:
            return dict(zip(snap.ok["scenario"], snap.ok["group"]))
        return {uncertainty.split_name(name)[0]: group for name, group in found.items()} \
            if self.uncertain is not None else found

    def space(self) -> tuple[Space | None, str]:
        """The sweep's space, to simulate tracks; or None and why not."""
        if not self._looked_for_space:
            self._space, self._space_note = self._load_space()
            self._looked_for_space = True
        return self._space, self._space_note

    def _load_space(self) -> tuple[Space | None, str]:
        status = load_status(self.output, self.sweep)
        if status is None or not status.spec:
            return None, "no status file names the sweep's spec, so its recordings are unknown"
        if not Path(status.spec).is_file():
            return None, f"the sweep's spec {status.spec} is not on this machine"
        try:
            space = load_space(status.spec)
        except DseError as e:
            return None, f"cannot load the sweep's spec: {e}"
        if space.model_key != current_model(self.output, self.sweep):
            return None, f"{status.spec} has changed since the sweep ran; its tracks would not be the sweep's"
        return space, ""

    def studied(self) -> bool:
        """Whether the pages show sensitivity or uncertainty figures."""
        return self.uncertain is not None or is_sensitivity(self.output, self.sweep)

    def studies_now(self) -> str:
        """studies_html for the store as it is, drawn once per version of it for every page."""
        with self._studies_lock:
            key = (store.version(self.output, self.sweep), current_model(self.output, self.sweep))
            if self._studies[0] != key:
                self._studies = (key, self.studies_html())
            return self._studies[1]

    def studies_html(self) -> str:
        """The sweep's sensitivity and uncertainty sections as they stand, or why they cannot be drawn yet."""
        from ..sweeps.rank import rank

        ranking = None
        try:
            ranking = rank(self.output, self.sweep) if self.uncertain is not None else None
        except DseError as e:
            note = f"<p id='uncertainty-note' class='note'>{html.escape(str(e))}</p>"
            return STUDY_STYLE + note + "".join(section_html(s, "h3") for s in sections(self.output, self.sweep, None))
        return STUDY_STYLE + "".join(section_html(s, "h3") for s in sections(self.output, self.sweep, ranking))

    def track(self, scenario: str, point: dict[str, Any]) -> tuple[Comparison, float]:
        """``point`` simulated on ``scenario`` next to its recording (comparison.py), and the objective. One
        simulation at a time: the pages' worker threads and the server's loop all ask, and a process's FMU
        instances are not for two threads at once."""
        from ..simulation.run import simulate

        key = (scenario, tuple(sorted(point.items())))
        with self._track_lock:
            if key not in self._tracks:
                space, note = self.space()
                if space is None:
                    raise DseError(note)
                names = {s.name: s for s in space.scenarios}  # a scenario of uncertain draws: its first draw's
                recording = names.get(scenario) or names[uncertainty.sample_name(scenario, 0)]
                objective = space.objectives[self.objective]
                result = simulate(space.plan, recording, point, objectives={self.objective: objective},
                                  timeout=space.spec.timeout, experiment=space.experiment)
                self._tracks[key] = (compare(result, objective), result.objectives[self.objective])
            return self._tracks[key]


def _scenario_count(status: SweepReport | None, rows: pd.DataFrame, column: str = "scenario") -> int:
    """How many scenarios each point (each uncertain draw: ``column`` "base" of with_draws' rows) runs on: the
    status's, a sampled scenario counted once, else those with rows so far (as rank() counts)."""
    if status is not None and status.scenarios:
        return len({uncertainty.split_name(name)[0] for name in status.scenarios})
    return int(rows[column].nunique())


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return "–"
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f"{hours}h {rest // 60:02d}m" if hours else f"{rest // 60}m {rest % 60:02d}s" if rest >= 60 else f"{rest}s"


def progress_html(snap: Snapshot, now: float) -> str:
    """The progress line: done, failed, remaining, rate and ETA, as HTML with ids the tests read."""
    status = snap.status
    total = status.total if status else None
    remaining = max(0, total - snap.done) if total is not None else None
    if status and status.search is not None and status.state != "running":
        remaining = 0  # a search's total is its budget, which points told from the store do not spend
    state = status.state if status else "unknown"
    if status and state == "running" and now - status.updated_at > STALE_SECONDS:
        state = f"no news for {_duration(now - status.updated_at)} (is the submitting process still running?)"
    elif status and status.waiting:
        state = status.waiting
    share = 100.0 * (total - remaining) / total if total and remaining is not None else 0.0
    cells = [("done", f"{snap.done}" + (f" of {total}" if total is not None else "")),
             ("failed", str(snap.failed)),
             ("remaining", "–" if remaining is None else str(remaining)),
             ("rate", f"{status.rate:.1f} simulations/s" if status else "–"),
             ("eta", _duration(status.eta_seconds) if status and status.state == "running" else "–"),
             ("state", state)]
    items = "".join(f'<div class="cell"><div class="label">{name}</div>'
                    f'<div class="value" id="dse-{name}">{html.escape(value)}</div></div>' for name, value in cells)
    return (f'<div class="bar"><div class="fill" style="width:{share:.1f}%"></div></div>'
            f'<div class="cells">{items}</div>')


def best_html(snap: Snapshot, parameters: list[str], ranked_by: str, counted: tuple[str, int]) -> str:
    """The best-so-far line: the standings' first point, by the figure the ranking ranks by."""
    unit, total = counted
    if snap.standings.empty:
        said = "no results yet" if snap.ok.empty else "no finished point meets the ranking's constraints yet"
        return f'<span id="dse-best">{said}</span>'
    top = snap.standings.iloc[0]
    if unit == "draws" and not top["draws"]:
        return '<span id="dse-best">no point has finished an uncertain draw on every scenario yet</span>'
    values = format_point({p: top[p] for p in parameters})
    return (f'<span id="dse-best">best so far: {html.escape(values)}; {html.escape(ranked_by)} '
            f'{top["ranked"]:.4f} over {int(top[unit])} of {total or "?"} {unit}</span>')


def search_summary(search: SearchStatus | None, history: SearchHistory | None, objective: str, goal: str,
                   max_points: int, strategy_name: str = "–") -> list[tuple[str, str]]:
    """A closed-loop search's figures as (name, text): from the status the submitting process saves
    (``search``) if it has them, else counted from the history."""
    if search is not None:
        best = search.best
        cells = [("strategy", search.strategy), ("points", f"{search.points} of {search.max_points}"),
                 (f"best {objective}", "–" if best is None else f"{best:.6g}"),
                 ("infeasible", str(search.infeasible)), ("failed", str(search.failed)),
                 ("utilisation", "–" if search.utilisation is None else f"{search.utilisation:.0%}")]
        if search.reused:
            cells.append(("reused", str(search.reused)))
        if search.stopped:
            cells.append(("stopped", search.stopped))
        return cells
    if history is None:
        return [("strategy", strategy_name), ("points", f"0 of {max_points}")]
    values = [p.values[objective] for p in history.points if p.state == "ok" and objective in p.values]
    best = (min if goal == "min" else max)(values) if values else None
    return [("strategy", history.strategy), ("points", f"{history.simulated()} of {max_points}"),
            (f"best {objective}", "–" if best is None else f"{best:.6g}"),
            ("infeasible", str(sum(p.state == "infeasible" for p in history.points))),
            ("failed", str(sum(p.state == "failed" for p in history.points))), ("utilisation", "–")]


def search_html(cells: list[tuple[str, str]]) -> str:
    """The search line: ``tpe · 23 of 30 points · best rmse 0.0092 · ...``, one span with id dse-search."""
    parts = [value if name == "strategy" else
             f"{value} points" if name == "points" else
             f"{name} {value}" if name.startswith("best") or name in ("utilisation", "stopped") else
             f"{value} {name}" for name, value in cells]
    return (f'<div style="font-family:sans-serif;font-size:15px;margin:6px 0">search: '
            f'<span id="dse-search">{html.escape(" · ".join(parts))}</span></div>')


def title_html(feed: Feed, status: SweepReport | None) -> str:
    dask = status.dashboard if status else None
    link = f' · <a href="{html.escape(dask)}" target="_blank">Dask dashboard</a>' if dask else ""
    return (f"<h2 style='font-family:sans-serif;margin:0'>{html.escape(feed.sweep)}</h2>"
            f"<div style='font-family:sans-serif'>results in {html.escape(str(feed.output))}{link}</div>")


def ranking_html(top: pd.DataFrame, objective: str, ranked_by: str, uncertain: bool = False) -> str:
    """The best-so-far table; its last column, headed by what it is, is the figure the points are ranked by."""
    mean = f"mean of {ranked_by.split(' of ', 1)[-1]}" if uncertain else f"mean {objective}"
    heading = f"ranked by: {ranked_by}"
    table = top.drop(columns="mean") if mean == ranked_by else top  # ranked by that mean: shown once
    table = table.rename(columns={"mean": mean, "ranked": heading})
    table.insert(0, "#", range(1, len(table) + 1))

    def four(value: float) -> str:
        return "–" if pd.isna(value) else f"{value:.4f}"
    return charts.html_table(table, "dse-ranking", {mean: four, heading: four})


def workers_html(status: SweepReport) -> str:
    table = pd.DataFrame([{"worker": w.name, "threads": w.threads, "running": w.executing, "CPU %": round(w.cpu),
                           "memory [MB]": round(w.memory / 2**20)} for w in status.activity],
                         columns=["worker", "threads", "running", "CPU %", "memory [MB]"])
    return charts.html_table(table, "dse-workers")


STYLE = """<style>
.bar {height: 14px; background: #e8e8e8; border-radius: 7px; overflow: hidden; width: 760px}
.fill {height: 100%; background: #1f77b4; transition: width .5s}
.cells {display: flex; gap: 28px; margin-top: 8px; font-family: sans-serif}
.label {font-size: 11px; color: #666; text-transform: uppercase}
.value {font-size: 17px}
</style>"""


@dataclass
class View:
    """What a page shows of one snapshot beyond its counts, computed off the server's event loop (a million
    rows take seconds to reduce and bin) and then handed to the Bokeh models at once."""

    best: str
    ranking: str
    by_parameter: Any  # charts.ObjectiveByParameter.prepare's
    by_group: Any  # charts.ErrorByGroup.prepare's
    track: tuple | None  # (Comparison, caption) or (None, note): the best point's, if it changed


class Page:
    """One browser tab: Bokeh models refilled from the shared feed every REFRESH_SECONDS. The counts come
    first, at once (the status file's before the rows are read); the figures follow as a worker thread
    reads and reduces the rows, so a large study's page opens without waiting for them."""

    def __init__(self, feed: Feed, doc):
        from bokeh.layouts import column, row
        from bokeh.models import CustomJS, Div, Select

        self.feed, self.doc = feed, doc
        self.shown = -1  # rows shown: they only ever grow, so a count tells news
        self.busy = False  # a worker thread is preparing the next view
        self.studying = False  # one is drawing the study sections
        feed.pages.add(self)
        snap = feed.latest()
        scenarios = feed.scenarios(snap)
        if scenarios is None:  # neither the space nor a status file names them: the rows must
            snap = feed.snapshot()
            scenarios = feed.scenarios(snap)
        self.farewell = Div(width=800)  # what the page says when its server stops (DashboardServer.stop)
        # once it has said so, the end of the connection is expected: no "connection was lost" banner (a Bokeh
        # 3.8+ setting, read in the browser; a change made on the server does not reach the browser's copy)
        quiet = "config.setv({notify_connection_status: false}, {sync: false})"
        self.farewell.js_on_change("text", CustomJS(
            code=f"const config = cb_obj.document.config; if (config) {quiet}"))
        self.scenarios = scenarios
        p, objective = feed.parameters, feed.objective
        self.title = Div(width=800)
        self.progress = Div(text=STYLE, width=800)
        self.best = Div(width=800)
        self.ranking = Div(width=2 * charts.WIDTH)
        self.workers = Div(width=charts.WIDTH)
        searching, sampled = feed.searching(snap), feed.sampled(snap)
        self.fig5 = charts.ObjectiveByParameter(p, objective, sorted(set(self.scenarios.values())), sampled)
        self.fig6 = charts.ErrorByGroup(p, objective, self.scenarios, sampled)
        names = sorted(self.scenarios)
        self.select = Select(title="scenario", value=names[0] if names else "", options=names)
        self.select.on_change("value", lambda attr, old, new: self._chosen())
        self.track = charts.TrackChart()
        self.track_note = Div(width=800)
        self.track_shown: tuple | None = None
        # a sensitivity design's indices, an uncertainty study's distributions (study_figures.py)
        self.studies = Div(width=2 * charts.WIDTH) if feed.studied() else None
        self.studies_at = -math.inf  # when they were last drawn (monotonic seconds)
        self.studies_drawn: tuple | None = None  # the (rows done, sweep state) they show
        self.search = self.search_chart = self.front_chart = None  # a closed-loop search's progress
        self.search_shown: tuple | None = None
        if searching:
            self.search = Div(width=800)
            self.search_chart = charts.BestSoFarChart(objective, feed.goal, len(self.scenarios))
            if len(feed.pareto_goals) >= 2:
                self.front_chart = charts.ParetoGrowthChart(feed.pareto_goals, p)

        def heading(text: str) -> Div:
            return Div(text=f"<h3 style='font-family:sans-serif;margin:12px 0 0'>{text}</h3>")

        doc.title = f"dse-runner: {feed.sweep}"
        if getattr(doc, "config", None) is not None:  # Bokeh 3.8+: a page reconnects to a new, empty session
            doc.config.reconnect_session = False  # and shows nothing of it; a lost connection is said once
        search = [] if not searching else [
            heading(f"Search: best {objective} against simulations"
                    + (", and the Pareto front as it grew" if self.front_chart else "")),
            row(*(c.figure for c in (self.search_chart, self.front_chart) if c is not None))]
        doc.add_root(column(
            self.farewell, self.title, self.progress, *([self.search] if self.search else []), self.best,
            row(column(heading(f"Best so far, ranked by {html.escape(feed.ranked_by)}"), self.ranking),
                column(heading("Workers"), self.workers)),
            *([self.studies] if self.studies is not None else []),
            *search,
            heading(f"{objective} against each parameter"
                    + ("" if sampled else ", the mean over the others")),
            self.fig5.layout,
            heading(f"{objective} per scenario group at each parameter point, points sorted by "
                    f"{', '.join(p)}"),
            self.fig6.layout,
            heading("Best candidate on the chosen scenario, over its recording if it has one"), self.select,
            self.track_note, self.track.figure))
        self._counts(snap or feed.provisional())
        self.best.text = '<span id="dse-best">reading the results…</span>'
        self.update()
        doc.add_periodic_callback(self.update, int(REFRESH_SECONDS * 1000))

    def finish(self, note: str, said: threading.Event) -> None:
        """The server is about to stop: the final state and figures from the store as it is now, and ``note``
        on top (whose arrival tells the browser the connection's end is meant)."""
        try:
            snap = self.feed.snapshot(fresh=True)
            self._show(snap, self._view(snap), self._studies_due(snap, final=True))
            self.farewell.text = (f"<div id='dse-farewell' style='font-family:sans-serif;background:#fff4d6;"
                                  f"border:1px solid #e0c060;padding:8px 12px'>{html.escape(note)}</div>")
        finally:
            said.set()

    def update(self) -> None:
        """On the server's loop, every REFRESH_SECONDS: the counts now; the figures, and apart from them the
        study sections (a large design's bootstrap), from worker threads."""
        snap = self.feed.latest() or self.feed.provisional()
        self._counts(snap)
        if not self.busy:
            self.busy = True
            threading.Thread(target=self._prepare, name="dse-runner-page", daemon=True).start()
        # after the first view: beside the page's first build the bootstrap delays the counts and figures
        if not self.studying and self.shown >= 0 and self._studies_due(snap) is not None:
            self.studying = True
            threading.Thread(target=self._prepare_studies, name="dse-runner-studies", daemon=True).start()

    def _counts(self, snap: Snapshot) -> None:
        """The title, the progress line and the workers: cheap, from any snapshot."""
        self.title.text = title_html(self.feed, snap.status)
        self.progress.text = STYLE + progress_html(snap, time.time())
        if snap.status:
            self.workers.text = charts.TABLE_STYLE + workers_html(snap.status)

    def _prepare(self) -> None:
        """Off the loop: read the snapshot, compute what changed, and hand it to the loop."""
        try:
            snap = self.feed.snapshot()
            view = self._view(snap) if snap.done != self.shown else None
        except Exception:
            self.busy = False
            raise
        self.doc.add_next_tick_callback(partial(self._show, snap, view, None))

    def _prepare_studies(self) -> None:
        """Off the loop: the study sections for the store as it is, handed to the loop."""
        try:
            found = self.feed.studies_now()
        finally:
            self.studying = False
        self.doc.add_next_tick_callback(partial(setattr, self.studies, "text", found))

    def _view(self, snap: Snapshot) -> View:
        feed = self.feed
        self.shown = snap.done
        return View(best_html(snap, feed.parameters, feed.ranked_by, feed.counted(len(self.scenarios))),
                    charts.TABLE_STYLE + ranking_html(snap.standings.head(TOP), feed.objective, feed.ranked_by,
                                                      feed.uncertain is not None),
                    self.fig5.prepare(snap.ok), self.fig6.prepare(snap.ok), self._best_track(snap))

    def _studies_due(self, snap: Snapshot, final: bool = False) -> str | None:
        """Whether the sensitivity or uncertainty figures are due again, when rows or the sweep's state changed:
        at most every STUDY_SECONDS while the sweep runs (the bootstrap takes a while on a large design), and
        once more when it has stopped, whenever the last rows came. None when they stand; else, ``final``
        (the server stops), their HTML now, or "" (a worker thread draws them)."""
        state = snap.status.state if snap.status is not None else None
        if self.studies is None or (snap.done, state) == self.studies_drawn:
            return None
        if not final and state == "running" and time.monotonic() - self.studies_at < STUDY_SECONDS:
            return None
        self.studies_at, self.studies_drawn = time.monotonic(), (snap.done, state)
        return self.feed.studies_now() if final else ""

    def _show(self, snap: Snapshot, view: View | None, studies: str | None) -> None:
        """On the loop: hand a prepared view to the Bokeh models."""
        self.busy = False
        self._counts(snap)
        if self.search is not None:
            self._search(snap)
        if studies is not None:
            self.studies.text = studies
        if view is None:
            return
        self.best.text, self.ranking.text = view.best, view.ranking
        self.fig5.show(view.by_parameter)
        self.fig6.show(view.by_group)
        self._show_track(view.track)

    def _show_track(self, found: tuple | None) -> None:
        if found is None:
            return
        comparison, caption = found
        self.track_note.text = f"<span id='dse-track'>{html.escape(caption) if comparison else caption}</span>"
        if comparison is not None:
            self.track.update(comparison, caption)

    def _search(self, snap: Snapshot) -> None:
        feed, history = self.feed, snap.history
        self.search.text = search_html(search_summary(snap.status.search if snap.status else None, history,
                                                      feed.objective, feed.goal, feed.max_points, feed.strategy))
        shown = None if history is None else (history.settings, history.tells, len(history.points))
        if history is None or shown == self.search_shown:
            return  # nothing told since the last refill
        self.search_shown = shown
        self.search_chart.update(history)
        if self.front_chart is not None:
            self.front_chart.update(history)

    def _best_track(self, snap: Snapshot, force: bool = False) -> tuple | None:
        """(Comparison, caption) of the best point on the chosen scenario, (None, note) when there is none to
        show, or None when the one shown stands."""
        if snap.standings.empty or not self.select.value:
            return None, "The best point's track appears with the first results."
        point = {p: plain(snap.standings.iloc[0][p]) for p in self.feed.parameters}
        key = (self.select.value, tuple(sorted(point.items())))
        if key == self.track_shown and not force:
            return None
        self.track_shown = key
        try:
            comparison, value = self.feed.track(self.select.value, point)
        except DseError as e:
            return None, f"No track: {html.escape(str(e))}"
        return comparison, f"{self.select.value}: best point so far, {self.feed.objective} {value:.4f}"

    def _chosen(self) -> None:
        """Another scenario chosen: its track, at once."""
        snap = self.feed.latest()
        self._show_track(self._best_track(snap, force=True) if snap is not None else None)


# --- serving -------------------------------------------------------------------------------------

def parse_address(text: str) -> tuple[str, int]:
    """``host:port`` (port 0 for any free one) -> (host, port)."""
    host, colon, port = text.rpartition(":")
    if not colon or not host or not port.isdigit():
        raise DseError(f"dashboard address {text!r}: expected host:port, e.g. 127.0.0.1:8790 (port 0 for any)")
    return host, int(port)


def _free_port(host: str) -> int:
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def _origins(host: str, port: int) -> list[str]:
    """Pages whose websocket Bokeh accepts: the names a browser may use for this address."""
    names = {host, "localhost", "127.0.0.1"}
    if host not in ("127.0.0.1", "localhost", "::1"):
        names |= {socket.gethostname(), socket.getfqdn()}
    return sorted(f"{name}:{port}" for name in names)


FAREWELL_SECONDS = 10.0  # at most this long for the open pages to take their last update
DELIVERY_SECONDS = 2.0  # then this long for it to leave the server (0.5 s lost it under a full machine)


@dataclass
class DashboardServer:
    """A dashboard served from a background thread; ``stop()`` ends it."""

    url: str
    _loop: Any
    _thread: threading.Thread
    feed: Feed | None = None

    def stop(self, farewell: str | None = None) -> None:
        """Stop serving. With ``farewell``, every open page first shows the sweep's final state and figures
        and the note, and is told the connection's end is meant: no lost-connection banner, no error."""
        if farewell is not None and self.feed is not None:
            told = []
            for page in list(self.feed.pages):
                said = threading.Event()
                page.doc.add_next_tick_callback(partial(page.finish, farewell, said))
                told.append(said)
            deadline = time.monotonic() + FAREWELL_SECONDS  # every page its chance, however slow one is
            if [said.wait(max(0.0, deadline - time.monotonic())) for said in told].count(True):
                time.sleep(DELIVERY_SECONDS)
        self._loop.add_callback(self._loop.stop)
        self._thread.join(timeout=10)


def serve(output: store.Root, sweep: str, address: str = "127.0.0.1:0", space: Space | None = None) -> DashboardServer:
    """Serve the dashboard of ``sweep`` in ``output`` at ``address`` (loopback by default: the page
    shows file paths and has no login) from a daemon thread."""
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server
    from tornado.ioloop import IOLoop

    host, port = parse_address(address)
    try:
        port = port or _free_port(host)
    except OSError as e:
        raise DseError(f"dashboard address {address}: {e.strerror}") from None
    feed = Feed(output, sweep, space)
    feed.warm()
    ready: dict[str, Any] = {}
    started = threading.Event()

    def run() -> None:
        asyncio.set_event_loop(asyncio.new_event_loop())
        loop = IOLoop.current()
        try:
            server = Server({"/": Application(FunctionHandler(partial(Page, feed)))}, io_loop=loop,
                            address=host, port=port, allow_websocket_origin=_origins(host, port))
            server.start()
        except OSError as e:
            ready["error"] = e
            started.set()
            return
        ready["loop"] = loop
        started.set()
        loop.start()
        server.stop()

    thread = threading.Thread(target=run, name="dse-runner-dashboard", daemon=True)
    thread.start()
    started.wait()
    if "error" in ready:
        raise DseError(f"cannot serve the dashboard at {host}:{port}: {ready['error'].strerror}")
    shown = f"[{host}]" if ":" in host else host
    return DashboardServer(f"http://{shown}:{port}/", ready["loop"], thread, feed)


def farewell(output: store.Root, how: str) -> str:
    """What a page says when its server stops: how, and how to see the results again."""
    return (f"{how} This page shows the final state, and no longer updates. To open the results again: "
            f"dse-runner dashboard {output}")
