"""A search's history (``<sweep>.search.json`` beside its results): every asked point, in order.

The rows in the Parquet store say how each point did; the history says in
which order the strategy asked for points and was told about them. Both
together let a later submission *replay* the search: a new strategy with the
same seed is asked and told in exactly the recorded order, with the stored
rows as results, so it reaches the state the last submission left, without
one simulation, and goes on from there (a larger budget continues the same
search). The dashboard and report draw best-so-far and the growing Pareto
front from it.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator
from typing import Any, Literal

from pydantic import BaseModel

from . import store
from .domain import Point

HISTORY_FILE = "search.json"

State = Literal["ok", "failed", "infeasible"]


class Asked(BaseModel):
    """One point the strategy asked for."""

    number: int  # ask order
    point: dict[str, Any]
    asked_after: int  # how many tells came before the ask
    told: int | None = None  # its place among the tells; None while it runs (or if the run stopped)
    state: State | None = None
    values: dict[str, float] = {}  # each scalar objective reduced over scenarios (ok points)


class SearchHistory(BaseModel):
    sweep: str
    strategy: str
    settings: str  # digest of what a replay depends on (settings_digest)
    points: list[Asked] = []
    tells: int = 0

    def ask(self, point: Point) -> int:
        self.points.append(Asked(number=len(self.points), point=point, asked_after=self.tells))
        return len(self.points) - 1

    def tell(self, number: int, state: State, values: dict[str, float]) -> None:
        asked = self.points[number]
        asked.told, asked.state, asked.values = self.tells, state, dict(values)
        self.tells += 1

    def events(self) -> Iterator[tuple[Literal["ask", "tell"], Asked]]:
        """The asks and tells in the order they happened."""
        told = sorted((p for p in self.points if p.told is not None), key=lambda p: p.told)
        position = 0
        for asked in self.points:
            while position < len(told) and told[position].told < asked.asked_after:
                yield "tell", told[position]
                position += 1
            yield "ask", asked
        for rest in told[position:]:
            yield "tell", rest

    def outstanding(self) -> list[int]:
        """Points asked and never told: running when the last submission stopped."""
        return [p.number for p in self.points if p.told is None]

    def simulated(self) -> int:
        """Points told with a simulation result (ok or failed): what the budget counts."""
        return sum(p.state in ("ok", "failed") for p in self.points)


def settings_digest(*parts: Any) -> str:
    text = json.dumps(parts, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def load_history(output: store.Root, sweep: str) -> SearchHistory | None:
    text = store.read_text(output, f"{sweep}.{HISTORY_FILE}")
    return SearchHistory.model_validate_json(text) if text is not None else None


def save_history(output: store.Root, history: SearchHistory) -> None:
    store.write_text(output, f"{history.sweep}.{HISTORY_FILE}", history.model_dump_json())
