"""The dashboard's feed: what every page of one sweep shows, read from the store once per version of it and
shared by all open pages (page.py), and the best points' tracks they ask for.

It reads only what any process can read: the result rows, the spec the sweep ran with
(``<sweep>.sweep.json``), the status the submitting process saves every second (``<sweep>.status.json``,
sweeps/status.py) and a closed-loop search's history (``<sweep>.search.json``, history.py). The report
(report.py) reads a search's figures through it too.
"""

from __future__ import annotations

import html
import threading
import time
import weakref
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import pandas as pd

from ...errors import DseError
from ...simulation.comparison import Comparison, compare
from ...sweeps import store, uncertainty
from ...sweeps.history import SearchHistory, load_history
from ...sweeps.rank import (
    current_model,
    current_rows,
    draw_standings,
    load_sweep_spec,
    ranked_figure_label,
    scalar_objectives,
    standings,
    without_excluded,
)
from ...sweeps.search import strategy
from ...sweeps.spec import Space, load_space
from ...sweeps.status import SearchStatus, SweepReport, load_status
from ...sweeps.strategies.designs import SensitivityDesign
from ..study_figures import is_sensitivity, section_html, sections

REFRESH_SECONDS = 1.0  # how often pages refresh, and how stale the shared snapshot may be
STUDY_STYLE = (
    "<style>.note {font-family: sans-serif; color: #666; "
    "font-size: 13px} h3 {font-family: sans-serif}</style>"
)


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
        self.settings = (
            spec.ranking
        )  # the best point is named as rank() names it: over_scenarios, robust, constraints
        # the objectives read: the ranked one, and every one when constraints may
        # name others (as rank() reads them)
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
        self.pages: weakref.WeakSet[Any] = (
            weakref.WeakSet()
        )  # the open tabs (page.Page), told when the server stops

    def latest(self) -> Snapshot | None:
        """The last snapshot taken, without waiting for one: what a page shows while the next is read."""
        return self._snapshot

    def provisional(self) -> Snapshot:
        """Before the first rows are read (a million take seconds): the counts the submitting process saved
        in its status file, which a page shows at once."""
        status = load_status(self.output, self.sweep)
        done = status.skipped + status.ran if status is not None else 0
        empty = pd.DataFrame(columns=[*self.parameters, "scenario", "group", self.objective])
        return Snapshot(
            status,
            empty,
            done,
            status.failed if status is not None else 0,
            empty.iloc[0:0],
            None,
            provisional=True,
        )

    def warm(self) -> None:
        """Read the first snapshot in the background, so the first page finds it ready or under way. (The
        study sections start with the first page instead: started here, at a million rows, they delayed the
        page's HTML by 0.8 s and all its figures by 2-4 s, measured with benchmarks/scale.py's browser.)"""
        threading.Thread(target=self.snapshot, name="dse-runner-feed", daemon=True).start()

    def snapshot(self, fresh: bool = False) -> Snapshot:
        """What the store holds, looked at most every REFRESH_SECONDS (``fresh``: now); its rows are read and
        reduced once per version of the store (store.version), which a finished sweep keeps for good."""
        with self._lock:
            last = self._snapshot
            if fresh or last is None or time.monotonic() - last.taken >= REFRESH_SECONDS:
                # The status first: a sweep saves "finished" after its last rows, so rows read after it are at
                # least as new. Read the other way round, a sweep ending between the two reads showed
                # "finished" over the rows of before its last chunks until the next refresh.
                status = load_status(self.output, self.sweep)
                version = f"{store.version(self.output, self.sweep)} {current_model(self.output, self.sweep)}"
                if last is not None and version == self._version:
                    history = (
                        load_history(self.output, self.sweep)
                        if self.closed_loop or last.history is not None
                        else None
                    )
                    self._snapshot = replace(last, status=status, history=history, taken=time.monotonic())
                else:
                    self._snapshot, self._version = self._read(status), version
            return self._snapshot

    def _read(self, status: SweepReport | None) -> Snapshot:
        rows = current_rows(self.output, self.sweep, ["group", "status", *self.parameters, *self.objectives])
        ok = rows[rows["status"] == "ok"]
        last = self._snapshot
        if self.uncertain is not None:  # ranked over the draws; the charts get a row per point and scenario,
            drawn = uncertainty.with_draws(
                ok, self.uncertain.samples
            )  # its objective the mean over the draws
            ok = uncertainty.collapse(drawn, self.parameters, [self.objective])
            scenarios = _scenario_count(status, drawn, "base")
            table = draw_standings(drawn, self.parameters, self.objective, self.settings, scenarios)
            table = without_excluded(
                table,
                drawn,
                self.parameters,
                self.objectives,
                self.settings,
                scenarios,
                self.uncertain.samples,
            )
        else:
            table = standings(ok, self.parameters, self.objective, self.goal, self.settings.over_scenarios)
            table = without_excluded(
                table, ok, self.parameters, self.objectives, self.settings, _scenario_count(status, rows)
            )
        history = (
            load_history(self.output, self.sweep)
            if self.closed_loop or (last is not None and last.history is not None)
            else None
        )
        return Snapshot(status, ok, len(rows), int((rows["status"] == "failed").sum()), table, history)

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
        return (
            {uncertainty.split_name(name)[0]: group for name, group in found.items()}
            if self.uncertain is not None
            else found
        )

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
        from ...sweeps.rank import rank

        ranking = None
        try:
            ranking = rank(self.output, self.sweep) if self.uncertain is not None else None
        except DseError as e:
            note = f"<p id='uncertainty-note' class='note'>{html.escape(str(e))}</p>"
            return (
                STUDY_STYLE
                + note
                + "".join(section_html(s, "h3") for s in sections(self.output, self.sweep, None))
            )
        return STUDY_STYLE + "".join(
            section_html(s, "h3") for s in sections(self.output, self.sweep, ranking)
        )

    def track(self, scenario: str, point: dict[str, Any]) -> tuple[Comparison, float]:
        """``point`` simulated on ``scenario`` next to its recording (comparison.py), and the objective. One
        simulation at a time: the pages' worker threads and the server's loop all ask, and a process's FMU
        instances are not for two threads at once."""
        from ...simulation.run import simulate

        key = (scenario, tuple(sorted(point.items())))
        with self._track_lock:
            if key not in self._tracks:
                space, note = self.space()
                if space is None:
                    raise DseError(note)
                names = {
                    s.name: s for s in space.scenarios
                }  # a scenario of uncertain draws: its first draw's
                recording = names.get(scenario) or names[uncertainty.sample_name(scenario, 0)]
                objective = space.objectives[self.objective]
                result = simulate(
                    space.plan,
                    recording,
                    point,
                    objectives={self.objective: objective},
                    timeout=space.spec.timeout,
                    experiment=space.experiment,
                )
                self._tracks[key] = (compare(result, objective), result.objectives[self.objective])
            return self._tracks[key]


def _scenario_count(status: SweepReport | None, rows: pd.DataFrame, column: str = "scenario") -> int:
    """How many scenarios each point (each uncertain draw: ``column`` "base" of with_draws' rows) runs on: the
    status's, a sampled scenario counted once, else those with rows so far (as rank() counts)."""
    if status is not None and status.scenarios:
        return len({uncertainty.split_name(name)[0] for name in status.scenarios})
    return int(rows[column].nunique())


def search_summary(
    search: SearchStatus | None,
    history: SearchHistory | None,
    objective: str,
    goal: str,
    max_points: int,
    strategy_name: str = "–",
) -> list[tuple[str, str]]:
    """A closed-loop search's figures as (name, text): from the status the submitting process saves
    (``search``) if it has them, else counted from the history."""
    if search is not None:
        best = search.best
        cells = [
            ("strategy", search.strategy),
            ("points", f"{search.points} of {search.max_points}"),
            (f"best {objective}", "–" if best is None else f"{best:.6g}"),
            ("infeasible", str(search.infeasible)),
            ("failed", str(search.failed)),
            ("utilisation", "–" if search.utilisation is None else f"{search.utilisation:.0%}"),
        ]
        if search.reused:
            cells.append(("reused", str(search.reused)))
        if search.stopped:
            cells.append(("stopped", search.stopped))
        return cells
    if history is None:
        return [("strategy", strategy_name), ("points", f"0 of {max_points}")]
    values = [p.values[objective] for p in history.points if p.state == "ok" and objective in p.values]
    best = (min if goal == "min" else max)(values) if values else None
    return [
        ("strategy", history.strategy),
        ("points", f"{history.simulated()} of {max_points}"),
        (f"best {objective}", "–" if best is None else f"{best:.6g}"),
        ("infeasible", str(sum(p.state == "infeasible" for p in history.points))),
        ("failed", str(sum(p.state == "failed" for p in history.points))),
        ("utilisation", "–"),
    ]
