"""How a diagnosis validates: folds of scenarios, or, with a single record, contiguous blocks of its time.

Why: a candidate is judged by its error on data its fit did not see. With several scenarios a fold holds
some of them out. A real process is often recorded once, in one long record; judging a fit on the samples
it was fitted to would reward every extra parameter. So one record is cut into contiguous blocks of time.
The first block is always fitted: the run's unknown initial state shows there, and only there. Every other
block is a fold, with two *views* of the whole run: one whose recording keeps all but the block, one that
keeps only the block (the other samples are dropouts, which every objective skips). Views are scenarios like
any other: a fold's fit runs on the first and is judged on the second, which it predicts from the run's
start, free-running through the block. What the fit saw and what it predicts share the run's initial state
and inputs, never the held-out samples. A fit on everything runs on the record itself, so each point is
simulated once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ...simulation.scenario import Recording, Scenario
from ...sweeps.spec import Space
from . import explain


@dataclass(frozen=True)
class Fold:
    """One fold: fitted on ``train``, judged on ``test`` (scenario names)."""

    train: tuple[str, ...]
    test: tuple[str, ...]


def complements(folds: Sequence[Sequence[str]], scenarios: Sequence[str]) -> list[Fold]:
    """Folds of scenarios: each fold's scenarios judged by a fit on all the others."""
    return [Fold(tuple(s for s in scenarios if s not in fold), tuple(fold)) for fold in folds]


def as_folds(folds: Sequence[Sequence[str] | Fold], scenarios: Sequence[str]) -> list[Fold]:
    """Folds as Fold: a list of scenario names is judged by a fit on the other ``scenarios``."""
    return [f if isinstance(f, Fold) else complements([f], scenarios)[0] for f in folds]


@dataclass(frozen=True)
class Validation:
    """What held-out means in a diagnosis: what a fit on everything is fitted on, the folds,
    the pieces that partition the data (scenarios, or a record's blocks: what a regression
    groups by), and how they were made."""

    by: str  # "scenarios", "time blocks", or "in sample" (one record too short to cut)
    fitted: tuple[str, ...]
    folds: list[Fold]
    pieces: tuple[str, ...]
    record: str | None = None  # the record cut into blocks

    @property
    def tests(self) -> list[list[str]]:
        return [list(f.test) for f in self.folds]

    def to_json(self) -> dict[str, Any]:
        found: dict[str, Any] = {"by": self.by, "folds": len(self.folds)}
        if self.record is not None:
            found["record"] = self.record
        return found

    @property
    def text(self) -> str:
        if self.by == "time blocks":
            return (
                f"held out: {len(self.folds)} contiguous blocks of time of the one record "
                f"{self.record}, each predicted free-running by a fit on the rest (the "
                "first block, where the unknown initial state shows, is always fitted)"
            )
        if self.by == "scenarios":
            return f"held out: {len(self.folds)} folds of scenarios, each predicted by a fit on the others"
        return "in sample: one record too short to cut into blocks; every error is on the samples fitted"


MIN_SAMPLES = 8  # a block holds at least this many recorded samples of each compared signal


def blocks(scenario: Scenario, count: int, columns: list[str]) -> list[tuple[Scenario, Scenario]]:
    """``scenario`` cut into ``count`` + 1 contiguous blocks of time (equal shares of its recorded samples):
    per block but the first, the view that keeps all but the block (what a fold fits on) and the view that
    keeps only the block (what it is judged on); none if a block would hold fewer than MIN_SAMPLES recorded
    samples. The first block is never held out: the run's unknown initial state shows there, and only
    there, so a fit without it could not know where the run starts."""
    recording = scenario.recorded
    if recording is None or count < 2:
        return []
    present = np.zeros(recording.time.size, dtype=bool)
    for column in columns:
        present |= np.isfinite(recording.columns[column])
    parts = np.array_split(np.flatnonzero(present), count + 1)
    if min(part.size for part in parts) < MIN_SAMPLES:
        return []
    views = []
    for k, part in enumerate(parts[1:], start=1):
        keep = np.zeros(recording.time.size, dtype=bool)
        keep[part[0] : part[-1] + 1] = True
        views.append(
            (
                view(scenario, recording, ~keep, f"train{k + 1}"),
                view(scenario, recording, keep, f"block{k + 1}"),
            )
        )
    return views


VIEW = "~"  # a view's name is its scenario's, this, and its label


def record_of(name: str) -> str:
    """The scenario a view (or the scenario itself) was cut from, by name."""
    return name.split(VIEW, 1)[0]


def view(scenario: Scenario, recording: Recording, keep: np.ndarray, label: str) -> Scenario:
    """The scenario with only the ``keep`` samples recorded, named ``<scenario>~<label>``; its identity its
    own, so that its tasks are its own (a task's id hashes the scenario's settings, options included)."""
    columns = {name: np.where(keep, values, np.nan) for name, values in recording.columns.items()}
    missing = int(sum(np.count_nonzero(~np.isfinite(v)) for v in columns.values()))
    return replace(
        scenario,
        name=f"{scenario.name}{VIEW}{label}",
        recorded=replace(recording, columns=columns, missing=missing),
        options={**scenario.options, "validation_view": label},
    )


def validated(space: Space, count: int, columns: list[str]) -> tuple[Space, Validation]:
    """The space a diagnosis runs on, with what held-out means in it: several scenarios are folded as they
    are; one record is cut into ``count`` blocks of time, each a fold, its views added to the scenarios."""
    names = tuple(s.name for s in space.scenarios)
    if len(space.scenarios) > 1:
        return space, Validation(
            "scenarios", names, complements(explain.folds(space.scenarios, count), names), names
        )
    record = space.scenarios[0]
    views = blocks(record, count, columns)
    if not views:
        return space, Validation("in sample", names, [], names)
    scenarios = [record, *(v for pair in views for v in pair)]
    cut = space.with_scenarios(scenarios)
    folds = [Fold((train.name,), (test.name,)) for train, test in views]
    return cut, Validation("time blocks", names, folds, tuple(test.name for _, test in views), record.name)
