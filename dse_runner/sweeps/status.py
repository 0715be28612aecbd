"""A sweep's status: what a submission has done so far, saved beside its results as ``<sweep>.status.json``.

The models here are that file's format. The sweep writes it (sweep.py) while it runs; the dashboard, the
report and ``submit --json`` read it, also in another process than the sweep's, without Dask.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, Field, computed_field

from . import store


class SearchStatus(BaseModel):
    """How a search is going: part of the sweep's status
    (``<sweep>.status.json``) and of ``submit --json``."""

    strategy: str
    objective: str
    goal: str
    max_points: int
    max_seconds: float | None = None
    points: int = 0  # simulated points told to the strategy, in all submissions
    reused: int = 0  # of which told from the store without simulating (a replay), in this submission
    repeats: int = 0  # points asked again after (or while) an equal one ran: told its result, not counted
    infeasible: int = 0  # points the constraints rejected: never simulated
    failed: int = 0  # points with a failed task
    best: float | None = None  # the best reduced objective so far
    best_point: dict[str, Any] | None = None
    threads: int = 0
    busy_seconds: float = 0.0  # time the workers spent on this submission's chunks (simulating, writing rows)
    window_seconds: float = 0.0  # from the first point sent to the last result
    ask_seconds: float = (
        0.0  # the client's time in the strategy's ask() in this submission (told points included)
    )
    replayed: bool = False  # went on from an earlier submission's points (told from the store)
    stopped: str | None = None  # why the search ended: budget, time, strategy, interrupted
    notes: list[str] = []

    @computed_field
    @property
    def utilisation(self) -> float | None:
        """Share of the worker threads' time spent on the search's chunks while it ran."""
        if self.window_seconds <= 0 or not self.threads:
            return None
        return min(1.0, self.busy_seconds / (self.window_seconds * self.threads))


class WorkerActivity(BaseModel):
    """One Dask worker as the dashboard shows it."""

    name: str
    threads: int
    executing: int = 0  # tasks running on it now
    cpu: float = 0.0  # percent
    memory: int = 0  # bytes


class SweepReport(BaseModel):
    """What a submission has done so far: returned by :func:`sweep.submit`, shown by the progress bar,
    and saved beside the results as ``<sweep>.status.json`` for the dashboard (also when it runs
    in another process than the sweep)."""

    sweep: str
    output: str | Path
    total: int  # tasks in the space
    skipped: int  # already had a row
    spec: str = ""  # the space.yaml the sweep ran from, to find its recordings again
    scenarios: dict[str, str] = {}  # scenario -> group
    state: Literal["running", "finished", "interrupted", "failed"] = "running"  # failed: submit raised
    started_at: float = Field(default_factory=time.time)  # Unix time
    updated_at: float = Field(default_factory=time.time)
    ok: int = 0
    failed: int = 0
    seconds: float = 0.0  # wall time of this submission
    simulation_seconds: float = 0.0  # summed on the workers
    chunk_seconds: float = (
        0.0  # the chunks' whole time on the workers, summed: simulations, unpacking, writing rows
    )
    chunk_size: int = 0  # tasks in the largest chunk handed out (chunks adapt, and shrink towards the end)
    chunks: int = 0
    workers: int = 0
    activity: list[WorkerActivity] = []
    dashboard: str | None = None  # Dask's
    interrupted: bool = False
    crashed_chunks: int = 0  # chunks Dask gave up on because workers died running them; split and rerun
    reconnects: int = 0  # times the scheduler went away and the sweep resumed from the store
    waiting: str | None = None  # what the sweep is waiting for, if it is not running tasks
    errors: list[str] = []
    search: SearchStatus | None = None  # a closed-loop search's progress

    @property
    def ran(self) -> int:
        return self.ok + self.failed

    @property
    def remaining(self) -> int:
        return max(0, self.total - self.skipped - self.ran)

    @property
    def rate(self) -> float:
        """Simulations per second in this submission."""
        return self.ran / self.seconds if self.seconds > 0 else 0.0

    @property
    def eta_seconds(self) -> float | None:
        return self.remaining / self.rate if self.rate > 0 else None

    @property
    def seconds_per_task(self) -> float | None:
        """The mean wall time of this submission's simulations on the workers, if all went well."""
        return self.simulation_seconds / self.ok if self.ok and not self.failed else None


STATUS_FILE = "status.json"
STATUS_SECONDS = 1.0  # how often a running sweep saves its status


def save_status(report: SweepReport, kept: SweepReport | None = None) -> None:
    """Save ``report`` as the sweep's status; or, if it finished without running a task (every task was
    done), ``kept``, the status found when it started, if that finished submission ran tasks: the
    status, and the report's summary, stay those of the run that made the rows, not of a
    resubmission that had nothing to do. A submission that has ended runs nothing: its workers are saved
    with no task running, whatever the last sample of them, up to a second old, said."""
    report.updated_at = time.time()
    if report.state != "running":
        report.activity = [w.model_copy(update={"executing": 0}) for w in report.activity]
    noop = report.state == "finished" and not report.ran
    shown = kept if noop and kept is not None and kept.state == "finished" and kept.ran else report
    store.write_text(report.output, f"{report.sweep}.{STATUS_FILE}", shown.model_dump_json(indent=1))


def load_status(output: store.Root, sweep: str) -> SweepReport | None:
    """The last status a submission saved, or None if no submission of ``sweep`` saved one."""
    text = store.read_text(output, f"{sweep}.{STATUS_FILE}")
    return SweepReport.model_validate_json(text) if text is not None else None
