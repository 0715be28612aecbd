"""How a diagnosis validates: folds of scenarios, or, with a single record, contiguous blocks of its time.

Why: a candidate is judged by its error on data its fit did not see. With several scenarios a fold holds
some of them out. A real process is often recorded once, in one long record; judging a fit on the samples
it was fitted to would reward every extra parameter. So one record is cut into contiguous blocks of time:
each block is a *view* of the whole run whose recording keeps only that block's samples (the others are
dropouts, which every objective skips). The views are scenarios like any other, so folds of them are
folds of blocks: a fit on the other blocks predicts the held-out block from the run's start, free-running
through it. What the fit saw and what it predicts share the run's initial state and its inputs, never
the held-out samples.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ...simulation.scenario import Recording, Scenario
from ...sweeps.spec import Space
from . import explain

BLOCK = "block"  # a view's name: <scenario>~block<k>


@dataclass(frozen=True)
class Validation:
    """What held-out means in a diagnosis: the folds (scenario names each), and how they were made."""

    by: str  # "scenarios", "time blocks", or "in sample" (one record too short to cut)
    folds: list[list[str]]
    record: str | None = None  # the record cut into blocks

    def to_json(self) -> dict[str, Any]:
        found: dict[str, Any] = {"by": self.by, "folds": len(self.folds)}
        if self.record is not None:
            found["record"] = self.record
        return found

    @property
    def text(self) -> str:
        if self.by == "time blocks":
            return (f"held out: {len(self.folds)} contiguous blocks of time of the one record {self.record}, each "
                    "predicted free-running by a fit on the others")
        if self.by == "scenarios":
            return f"held out: {len(self.folds)} folds of scenarios, each predicted by a fit on the others"
        return "in sample: one record too short to cut into blocks; every error is on the samples fitted"


MIN_SAMPLES = 8  # a block holds at least this many recorded samples of each compared signal


def blocks(scenario: Scenario, count: int, columns: list[str]) -> list[Scenario]:
    """``scenario`` as ``count`` views, each keeping the recorded samples of one contiguous block of time
    (equal shares of its recorded samples); none if a block would hold fewer than MIN_SAMPLES of a column."""
    recording = scenario.recorded
    if recording is None or count < 2:
        return []
    present = np.zeros(recording.time.size, dtype=bool)
    for column in columns:
        present |= np.isfinite(recording.columns[column])
    index = np.flatnonzero(present)
    parts = np.array_split(index, count)
    views = []
    for k, part in enumerate(parts):
        if part.size < MIN_SAMPLES:
            return []
        keep = np.zeros(recording.time.size, dtype=bool)
        keep[part[0]:part[-1] + 1] = True
        views.append(view(scenario, recording, keep, k))
    return views


def view(scenario: Scenario, recording: Recording, keep: np.ndarray, k: int) -> Scenario:
    """The scenario with only the ``keep`` samples recorded; its own name and identity, so that its tasks
    are its own (a task's id hashes the scenario's settings, options included)."""
    columns = {name: np.where(keep, values, np.nan) for name, values in recording.columns.items()}
    missing = int(sum(np.count_nonzero(~np.isfinite(v)) for v in columns.values()))
    return replace(scenario, name=f"{scenario.name}~{BLOCK}{k + 1}",
                   recorded=replace(recording, columns=columns, missing=missing),
                   options={**scenario.options, "validation_block": [k + 1, int(np.count_nonzero(keep))]})


def validated(space: Space, count: int, columns: list[str]) -> tuple[Space, Validation]:
    """The space a diagnosis runs on, with its folds: several scenarios are folded as they are; one record is
    cut into ``count`` blocks of time, each a fold."""
    if len(space.scenarios) > 1:
        return space, Validation("scenarios", explain.folds(space.scenarios, count))
    record = space.scenarios[0]
    views = blocks(record, count, columns)
    if not views:
        return space, Validation("in sample", [])
    cut = Space(space.spec, space.path, space.plan, views, space.distributions, space.draws)
    return cut, Validation("time blocks", [[v.name] for v in views], record.name)
