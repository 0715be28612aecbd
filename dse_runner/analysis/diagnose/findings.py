"""What a diagnosis names as the cause, typed: a library hypothesis (or ``none``) with its fitted
parameters, or a discovered correction with its terms.

The CLI and the report tell them apart by type, not by which keys a dict happens to have; ``to_json``
gives each entry of the JSON's ``effects`` list exactly as it always was.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any


@dataclass(frozen=True)
class NamedEffect:
    """A hypothesis of the library the diagnosis chose (``none`` when it chose nothing), its parameters
    as fitted jointly with the calibrated ones, and their ~95 % intervals."""

    id: str
    name: str
    parameters: dict[str, float]
    interval: dict[str, list[float]]  # parameter -> [low, high]
    magnitude: float | None = None  # the norm of its parameters; ``none`` has none
    partial: bool = False  # chosen, but leaving a residual well above the noise

    def to_json(self) -> dict[str, Any]:
        size = {} if self.magnitude is None else {"magnitude": self.magnitude}
        return {
            "id": self.id,
            "name": self.name,
            "parameters": self.parameters,
            "interval": self.interval,
            **size,
            "partial": self.partial,
        }

    def described(self) -> str:
        """Its parameters with their intervals, as the CLI and the report's finding print them."""
        return ", ".join(
            f"{k} = {v:.4g} [{self.interval[k][0]:.4g}, {self.interval[k][1]:.4g}]"
            for k, v in self.parameters.items()
        )


@dataclass(frozen=True)
class DiscoveredCorrection:
    """A data-driven correction beyond the library (discover/): its terms in readable form, its held-out
    error with and without it, and the library effect it resembles most."""

    id: str
    name: str
    terms: list[dict[str, Any]]  # discover.terms_json: text, variable, value, interval (and a shape's value)
    readable: list[str]  # one line per channel, its terms summed (correction.readable)
    parameters: dict[str, float]
    interval: dict[str, list[float]]
    resembles: (
        dict[str, Any] | None
    )  # {id, similarity, text}: the most similar library effect; None if not compared
    similarities: dict[str, float] = field(default_factory=dict)
    held_out_without: float = 0.0  # the library's best held-out error
    held_out_with: float = 0.0
    partial: bool = False  # it too leaves a residual above the noise

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    def described(self) -> str:
        """Its terms as an engineer writes them, as the CLI prints them."""
        return "; ".join(t["text"] for t in self.terms)


Finding = NamedEffect | DiscoveredCorrection
