"""Fits run as sweeps: any number of least-squares fits (fit.py) advanced in lockstep on the cluster.

Each round is one sweep of the space over the union of the points the unfinished fits ask for, into
the Parquet store: fits that ask for the same point (every fit starts from the same calibrated point)
share its simulations, and a re-run finds every finished round in the store. A round asks for the
candidates' perturbations with them only when the cluster has a thread free for each (they then cost
no wall time); otherwise a fit asks for them once its candidate is accepted.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from typing import Any

import numpy as np

from ..errors import DseError
from . import store
from .chunks import TaskScores
from .cluster import total_threads
from .domain import Point
from .expand import Key, blocks, distinct, key_of, wanted
from .fit import FitProblem, FitResult, LevenbergMarquardt, Residuals
from .spec import Space
from .sweep import submit

FitRoundProgress = Callable[
    [int, int, int, int], None
]  # (round, active fits, points, simulations this round)


def fit_all(
    space: Space,
    problems: list[FitProblem],
    client,
    residuals: str | Mapping[str, float],
    progress: FitRoundProgress | None = None,
) -> dict[str, FitResult]:
    """Run fits in lockstep, each round one sweep of ``space`` over the union of the points the fits
    ask for, minimising the vector objective named ``residuals`` (one of the space's), or several, each
    multiplied by its scale and joined (``{name: scale}``: residuals in different units made alike)."""
    for name in [residuals] if isinstance(residuals, str) else residuals:
        if name not in space.objectives:
            raise DseError(f"space {space.name}: fitting needs the objective {name!r}")
    solvers = [LevenbergMarquardt(p) for p in problems]
    threads = total_threads(client) if client is not None else 0  # without one, each round starts a cluster
    round_, cost = 0, None  # cost: seconds per task, measured by the last round
    while True:
        asked, points, only = asks(solvers, eager=True)
        if not asked:
            break
        if sum(len(s) for s in only) > threads:  # the perturbations would queue behind the candidates
            asked, points, only = asks(solvers, eager=False)
        round_ += 1
        if progress:
            progress(round_, len(asked), len(points), sum(len(s) for s in only))
        rows, cost = evaluate_points(
            space, points, client, [residuals] if isinstance(residuals, str) else list(residuals), only, cost
        )
        for solver in solvers:
            if id(solver) in asked:
                solver.tell(residuals_in(rows, residuals))
    return {s.problem.label: s.result() for s in solvers}


def asks(
    solvers: list[LevenbergMarquardt], eager: bool
) -> tuple[dict[int, list[Point]], list[Point], list[set[str]]]:
    """What the unfinished fits ask for next, by fit, and as the round's distinct points with the scenarios
    wanted of each (see :func:`wanted`)."""
    asked = {id(s): s.ask(eager=eager) for s in solvers if not s.done}
    return asked, *wanted((p, s.problem.scenarios) for s in solvers if id(s) in asked for p in asked[id(s)])


Rows = dict[tuple[Key, str], dict[str, Any]]  # (point, scenario) -> its result row


def residuals_in(rows: Rows, columns: str | Mapping[str, float]) -> Residuals:
    """The residuals of (point, scenario) as the rows hold them (several columns scaled and joined): None
    where the run failed or is missing."""
    scales = {columns: 1.0} if isinstance(columns, str) else dict(columns)

    def residuals(point: Point, scenario: str) -> np.ndarray | None:
        row = rows.get((key_of(point), scenario))
        if not row or row["status"] != "ok":
            return None
        parts = [np.asarray(row[c], dtype=float) * s for c, s in scales.items()]
        return parts[0] if len(parts) == 1 and scales[next(iter(scales))] == 1.0 else np.concatenate(parts)

    return residuals


def evaluate_points(
    space: Space,
    points: list[Point],
    client,
    columns: list[str],
    only: list[Collection[str]] | None = None,
    seconds_per_task: float | None = None,
) -> tuple[Rows, float | None]:
    """Run ``points`` on every scenario of ``space`` (or, with ``only``, each point on the scenarios
    named for it) as one sweep, skipping finished tasks. Returns their rows with ``status`` and
    ``columns``, and what a task cost (for the next round's ``seconds_per_task``, see sweep.submit).
    The tasks simulated now are told by their chunks; only those finished before are read from the store."""
    told: list[TaskScores] = []
    points, only = distinct(points, only)  # a point asked twice is simulated once; both find its rows
    tasks = list(blocks(space, points, only))  # made once: the sweep counts and sends these
    report = submit(
        space,
        client=client,
        points=points,
        only=only,
        seconds_per_task=seconds_per_task,
        told=told,
        tasks=tasks,
    )
    ids = {task.task_id: (task.point, task.scenario) for batch in tasks for task in batch}
    rows = {ids[t.task_id]: told_row(t, columns) for t in told if t.task_id in ids}
    earlier = [task_id for task_id, key in ids.items() if key not in rows]
    if earlier:
        stored = store.read_results(space.output, space.name, ["status", *columns], task_ids=earlier)
        rows.update({ids[r["task_id"]]: r for r in stored.to_dict("records")})
    return rows, report.seconds_per_task or seconds_per_task


def told_row(scores: TaskScores, columns: list[str]) -> dict[str, Any]:
    """A task's row as a fit reads it: its status and ``columns`` (None when it failed)."""
    objectives = scores.objectives
    return {
        "status": "ok" if scores.error is None else "failed",
        **{c: None if objectives is None else objectives.get(c) for c in columns},
    }
