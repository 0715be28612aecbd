"""The answer every diagnosis gives, as one pydantic model: the JSON that ``diagnose --json`` prints and
``diagnosis.json`` holds, whichever library diagnosed.

Why: a user (or a notebook, or a later study) reads one shape, whether the Robotti's library or the
built-in signal effects answered. What every diagnosis has is typed here; what only one library has sits
under ``case``, a key of its own (the Robotti's calibration grid, equation-error proposal and screen; the
signal library's compared signals and growth rounds).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from .explain import Candidate

Verdict = Literal["none", "explained", "partial", "discovered", "unexplained"]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class NoiseFloor(_Strict):
    """What the recordings' noise alone leaves of held-out error: the yardstick of the verdict."""

    held_out: float | None  # in held_out_unit; None when it could not be estimated
    factor: float  # held-out error above factor × held_out is left unexplained
    ratio: float | None  # the answer's held-out error over held_out
    method: str  # how it was estimated
    details: dict[str, Any] = Field(default_factory=dict)  # the library's own figures (per run, per signal)


class Effect(_Strict):
    """One member of the answer: a hypothesis of the library, a term inside the model, or a correction
    discovered beyond the library; ``none`` when nothing is named."""

    id: str
    name: str  # in words
    parameters: dict[str, float]
    interval: dict[str, list[float | None]]  # parameter -> [low, high], ~95 % (null: undetermined)
    partial: bool  # named, but leaving a residual well above the noise
    at_bound: list[str] = Field(default_factory=list)  # parameters pinned at their range's end: no estimate
    magnitude: float | None = None  # the norm of its parameters, where the library defines one
    hypothesis: str | None = None  # as candidates, dropped and decided name it (its target included)
    target: str | None = None  # the signal, state or derivative it acts on
    into: str | None = None  # an overflow's receiving state
    resolution: float | None = None  # the finest change of its first parameter the runs can tell
    term: str | None = None  # a term inside the model, as written
    law: str | None = None  # the physics it stands for
    readable: list[str] = Field(default_factory=list)  # sentences as an engineer writes them
    terms: list[dict[str, Any]] = Field(default_factory=list)  # a discovered correction's, with intervals
    resembles: dict[str, Any] | None = None  # the library effect a discovered correction is most like
    similarities: dict[str, float] = Field(default_factory=dict)
    held_out_without: float | None = None  # a discovered correction's gain: the library's best ...
    held_out_with: float | None = None  # ... and with the correction


NONE = "none"  # the one effect named when nothing is missing: what is left is the recordings' noise


def nothing_missing(name: str) -> Effect:
    """The answer's only effect when no hypothesis is named (``name``: the library's words for it)."""
    return Effect(id=NONE, name=name, parameters={}, interval={}, partial=False)


class Evidence(_Strict):
    """The best alternative to the answer, and what tells them apart."""

    id: str
    held_out: float | None
    delta_bic: float | None
    delta_held_out: float | None
    delta_held_out_percent: float | None
    runs_better: str  # on how many held-out runs the answer did better, "k/n"
    runs_tied: int


class CandidateEntry(_Strict):
    """A set of hypotheses fitted on the way to the answer."""

    id: str
    held_out: float | None  # None when it was never cross-validated
    bic: float | None
    validated: bool
    error: str | None = None  # why its fit failed
    parameters: dict[str, float] = Field(default_factory=dict)
    at_bound: list[str] = Field(default_factory=list)

    @classmethod
    def of(cls, c: Candidate) -> CandidateEntry:
        return cls(
            id=c.label,
            held_out=c.cross_validated if c.validated else None,
            bic=c.bic,
            validated=c.validated,
            error=c.full.error or None,
            parameters=dict(c.full.values),
            at_bound=list(c.full.at_bound),
        )


class Dropped(_Strict):
    """A member the choice had named and a rule took away."""

    id: str
    worth: float | None  # noise variances its removal adds to the held-out mean square (the noise rule)
    rule: str


class Proof(_Strict):
    """Terms found by searching, chosen again on each fold (proof.py)."""

    terms: list[str]
    offered: int
    folds: list[list[str]]
    agree: int
    held_out: float | None
    rule: str


class Screen(_Strict):
    """What the combination screen did (screens/): how it predicts, every set it checked by simulation
    (best real BIC first: ``id``, ``from``, ``predicted_sse``, ``sse``, ``bic``, ``shortlisted``), those
    fitted for real; or why nothing was screened (``reason``)."""

    strategy: str
    how: str = ""
    predicted: int = 0
    screened: list[dict[str, Any]] = Field(default_factory=list)
    fitted: list[str] = Field(default_factory=list)
    reason: str = ""


class Growth(_Strict):
    """One round of growth (engine.grown): the set grown, how many sets with one more effect were tried, the
    best by BIC, and its held-out error and acceptance when it passed the BIC gate."""

    parent: str
    tried: int
    best: str
    bic: float | None
    held_out: float | None = None
    accepted: bool = False


class HeldOut(_Strict):
    """One held-out run or block: the calibrated model's error and the answer's."""

    scenario: str
    before: float | None
    after: float | None
    group: str | None = None  # the scenario's group (a time block: its record's), where the space gives one

    @classmethod
    def between(
        cls, baseline: Candidate, chosen: Candidate, groups: Mapping[str, str | None] = {}
    ) -> list[HeldOut]:
        """Every scenario the calibrated model was held out on, with its error and the answer's (and its
        group, from ``groups``: scenario -> group)."""
        return [
            cls(scenario=s, before=e, after=chosen.held_out.get(s), group=groups.get(s))
            for s, e in sorted(baseline.held_out.items())
        ]


class Fitted(_Strict):
    """Parameters as fitted, with ~95 % intervals where known."""

    parameters: dict[str, float]
    interval: dict[str, list[float | None]] = Field(default_factory=dict)  # null where undetermined
    at_bound: list[str] = Field(default_factory=list)


class Validation(_Strict):
    by: str  # "scenarios", "time blocks" or "in sample"
    folds: int
    record: str | None = None


class Answer(_Strict):
    """What every diagnosis answers (``diagnose --json``, ``diagnosis.json``)."""

    library: str  # the hypothesis library that diagnosed
    space: str | None = None  # the name of the space diagnosed: the report's title
    verdict: Verdict
    verdict_text: str
    held_out_before: float | None  # the calibrated model's held-out error
    held_out_after: float | None  # the answer's (with searched terms: their proof's, if worse)
    held_out_unit: str
    noise_floor: NoiseFloor
    effects: list[Effect]
    runner_up: Evidence | None
    candidates: list[CandidateEntry]
    dropped: list[Dropped] = Field(default_factory=list)
    proof: Proof | None = None
    validation: Validation | None = None
    held_out: list[HeldOut] = Field(default_factory=list)
    lookalikes: list[dict[str, Any]] = Field(default_factory=list)  # each library's evidence between twins
    screen: Screen | None = None  # what the combination screen did (None where no screen ran at all)
    growth: list[Growth] = Field(default_factory=list)  # each round of one more effect
    calibrated: Fitted  # the model before: calibrated, no effect
    fitted: Fitted  # the answer: every parameter fitted jointly
    files: dict[str, Any] = Field(default_factory=dict)  # what was written: report, values, space, figures
    case: dict[str, Any] = Field(default_factory=dict)  # the library's own fields

    def json_dict(self) -> dict[str, Any]:
        """As the JSON prints it (None as null)."""
        return self.model_dump(mode="json")
