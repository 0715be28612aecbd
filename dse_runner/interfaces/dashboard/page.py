"""The dashboard's page: one browser tab's Bokeh document, refilled from the shared feed (feed.py).

The counts come first and at once, from the status file; the figures follow as a worker thread reads
and reduces the rows, so a large study's page opens without waiting for them. For a closed-loop search
the page also shows a line of its figures, best so far against simulations, and, with two or more
Pareto objectives, the front as it grew (charts.BestSoFarChart, ParetoGrowthChart). The best point's
track is simulated on demand from the sweep's own spec and recordings.
"""

from __future__ import annotations

import html
import math
import threading
import time
from dataclasses import dataclass
from functools import partial
from typing import Any

import pandas as pd

from ...errors import DseError
from ...sweeps.rank import (
    format_point,
    plain,
)
from ...sweeps.status import SweepReport
from .. import charts
from .feed import REFRESH_SECONDS, Feed, Snapshot, search_summary

STALE_SECONDS = 30.0  # a running sweep whose status is older than this has probably lost its client
TOP = 15  # rows of the best-so-far ranking shown
STUDY_SECONDS = 10.0  # how often a running sweep's sensitivity or uncertainty figures are redrawn


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return "–"
    seconds = round(seconds)
    hours, rest = divmod(seconds, 3600)
    return (
        f"{hours}h {rest // 60:02d}m"
        if hours
        else f"{rest // 60}m {rest % 60:02d}s"
        if rest >= 60
        else f"{rest}s"
    )


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
    cells = [
        ("done", f"{snap.done}" + (f" of {total}" if total is not None else "")),
        ("failed", str(snap.failed)),
        ("remaining", "–" if remaining is None else str(remaining)),
        ("rate", f"{status.rate:.1f} simulations/s" if status else "–"),
        ("eta", _duration(status.eta_seconds) if status and status.state == "running" else "–"),
        ("state", state),
    ]
    items = "".join(
        f'<div class="cell"><div class="label">{name}</div>'
        f'<div class="value" id="dse-{name}">{html.escape(value)}</div></div>'
        for name, value in cells
    )
    return (
        f'<div class="bar"><div class="fill" style="width:{share:.1f}%"></div></div>'
        f'<div class="cells">{items}</div>'
    )


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
    return (
        f'<span id="dse-best">best so far: {html.escape(values)}; {html.escape(ranked_by)} '
        f"{top['ranked']:.4f} over {int(top[unit])} of {total or '?'} {unit}</span>"
    )


def search_html(cells: list[tuple[str, str]]) -> str:
    """The search line: ``tpe · 23 of 30 points · best rmse 0.0092 · ...``, one span with id dse-search."""
    parts = [
        value
        if name == "strategy"
        else f"{value} points"
        if name == "points"
        else f"{name} {value}"
        if name.startswith("best") or name in ("utilisation", "stopped")
        else f"{value} {name}"
        for name, value in cells
    ]
    return (
        f'<div style="font-family:sans-serif;font-size:15px;margin:6px 0">search: '
        f'<span id="dse-search">{html.escape(" · ".join(parts))}</span></div>'
    )


def title_html(feed: Feed, status: SweepReport | None) -> str:
    dask = status.dashboard if status else None
    link = f' · <a href="{html.escape(dask)}" target="_blank">Dask dashboard</a>' if dask else ""
    return (
        f"<h2 style='font-family:sans-serif;margin:0'>{html.escape(feed.sweep)}</h2>"
        f"<div style='font-family:sans-serif'>results in {html.escape(str(feed.output))}{link}</div>"
    )


def ranking_html(top: pd.DataFrame, objective: str, ranked_by: str, uncertain: bool = False) -> str:
    """The best-so-far table; its last column, headed by what it is, is the
    figure the points are ranked by."""
    mean = f"mean of {ranked_by.split(' of ', 1)[-1]}" if uncertain else f"mean {objective}"
    heading = f"ranked by: {ranked_by}"
    table = top.drop(columns="mean") if mean == ranked_by else top  # ranked by that mean: shown once
    table = table.rename(columns={"mean": mean, "ranked": heading})
    table.insert(0, "#", range(1, len(table) + 1))

    def four(value: float) -> str:
        return "–" if pd.isna(value) else f"{value:.4f}"

    return charts.html_table(table, "dse-ranking", {mean: four, heading: four})


def workers_html(status: SweepReport) -> str:
    table = pd.DataFrame(
        [
            {
                "worker": w.name,
                "threads": w.threads,
                "running": w.executing,
                "CPU %": round(w.cpu),
                "memory [MB]": round(w.memory / 2**20),
            }
            for w in status.activity
        ],
        columns=["worker", "threads", "running", "CPU %", "memory [MB]"],
    )
    return charts.html_table(table, "dse-workers")


STYLE = """<style>
.bar {height: 14px; background: #e8e8e8; border-radius: 7px; overflow: hidden; width: 760px}
.fill {height: 100%; background: #1f77b4; transition: width .5s}
.cells {display: flex; gap: 28px; margin-top: 8px; font-family: sans-serif}
.label {font-size: 11px; color: #666; text-transform: uppercase}
.value {font-size: 17px}
</style>"""


# Bokeh's page (which Bokeh extends with this) with the counts first in its body, and BokehJS's scripts after
# them rather than in the head, where they would hold the counts back until loaded
FIRST_COUNTS = """{% block js_resources %}{% endblock %}
{% block contents %}<div id="dse-first" style="padding:0 0 0 5px">{{ first }}</div>
{{ bokeh_js if bokeh_js }}
{{ super() }}{% endblock %}"""


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
        self.threads: list[
            threading.Thread
        ] = []  # those started, so that a stopping server can wait for them
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
        self.farewell.js_on_change(
            "text", CustomJS(code=f"const config = cb_obj.document.config; if (config) {quiet}")
        )
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
        search = (
            []
            if not searching
            else [
                heading(
                    f"Search: best {objective} against simulations"
                    + (", and the Pareto front as it grew" if self.front_chart else "")
                ),
                row(*(c.figure for c in (self.search_chart, self.front_chart) if c is not None)),
            ]
        )
        doc.add_root(
            column(
                self.farewell,
                self.title,
                self.progress,
                *([self.search] if self.search else []),
                self.best,
                row(
                    column(heading(f"Best so far, ranked by {html.escape(feed.ranked_by)}"), self.ranking),
                    column(heading("Workers"), self.workers),
                ),
                *([self.studies] if self.studies is not None else []),
                *search,
                heading(
                    f"{objective} against each parameter" + ("" if sampled else ", the mean over the others")
                ),
                self.fig5.layout,
                heading(
                    f"{objective} per scenario group at each parameter point, points sorted by {', '.join(p)}"
                ),
                self.fig6.layout,
                heading("Best candidate on the chosen scenario, over its recording if it has one"),
                self.select,
                self.track_note,
                self.track.figure,
            )
        )
        first = snap or feed.provisional()
        self._counts(first)
        # the counts in the page's HTML as well, shown before BokehJS has loaded, pulled and drawn the
        # document (a second or two); gone once it has, where the progress Div shows the same
        doc.template = FIRST_COUNTS
        doc.template_variables["first"] = self.progress.text
        doc.js_on_event("document_ready", CustomJS(code="document.getElementById('dse-first')?.remove()"))
        self.best.text = '<span id="dse-best">reading the results…</span>'
        self.update()
        doc.add_periodic_callback(self.update, int(REFRESH_SECONDS * 1000))

    def finish(self, note: str, said: threading.Event) -> None:
        """The server is about to stop: the final state and figures from the store as it is now, and ``note``
        on top (whose arrival tells the browser the connection's end is meant)."""
        try:
            snap = self.feed.snapshot(fresh=True)
            self._show(snap, self._view(snap), self._studies_due(snap, final=True))
            self.farewell.text = (
                f"<div id='dse-farewell' style='font-family:sans-serif;background:#fff4d6;"
                f"border:1px solid #e0c060;padding:8px 12px'>{html.escape(note)}</div>"
            )
        finally:
            said.set()

    def update(self) -> None:
        """On the server's loop, every REFRESH_SECONDS: the counts now; the figures, and apart from them the
        study sections (a large design's bootstrap), from worker threads."""
        snap = self.feed.latest() or self.feed.provisional()
        self._counts(snap)
        if not self.busy:
            self.busy = True
            self._start(self._prepare, "dse-runner-page")
        # from the first update: the counts are in the page's HTML already, and a large design's
        # bootstrap takes longest of all
        if not self.studying and self._studies_due(snap) is not None:
            self.studying = True
            self._start(self._prepare_studies, "dse-runner-studies")

    def _start(self, work, name: str) -> None:
        """``work`` on a thread of its own, kept until it ends."""
        self.threads = [t for t in self.threads if t.is_alive()]
        thread = threading.Thread(target=work, name=name, daemon=True)
        self.threads.append(thread)
        thread.start()

    def join(self, timeout: float) -> None:
        """Wait, at most ``timeout`` seconds in all, for the threads preparing this page's views: one may be
        reading the store or simulating the best track, which must not outlive the server."""
        deadline = time.monotonic() + timeout
        for thread in list(self.threads):
            thread.join(max(0.0, deadline - time.monotonic()))

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
        return View(
            best_html(snap, feed.parameters, feed.ranked_by, feed.counted(len(self.scenarios))),
            charts.TABLE_STYLE
            + ranking_html(
                snap.standings.head(TOP), feed.objective, feed.ranked_by, feed.uncertain is not None
            ),
            self.fig5.prepare(snap.ok),
            self.fig6.prepare(snap.ok),
            self._best_track(snap),
        )

    def _studies_due(self, snap: Snapshot, final: bool = False) -> str | None:
        """Whether the sensitivity or uncertainty figures are due again, when rows or the sweep's state
        changed: at most every STUDY_SECONDS while the sweep runs (the bootstrap takes a while on a
        large design), and once more when it has stopped, whenever the last rows came. None when they
        stand; else, ``final`` (the server stops), their HTML now, or "" (a worker thread draws them)."""
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
        self.track_note.text = (
            f"<span id='dse-track'>{html.escape(caption) if comparison else caption}</span>"
        )
        if comparison is not None:
            self.track.update(comparison, caption)

    def _search(self, snap: Snapshot) -> None:
        feed, history = self.feed, snap.history
        self.search.text = search_html(
            search_summary(
                snap.status.search if snap.status else None,
                history,
                feed.objective,
                feed.goal,
                feed.max_points,
                feed.strategy,
            )
        )
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
