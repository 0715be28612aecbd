"""What a diagnosis found, before it is written as JSON: the calibrated model, the answer, every set fitted on
the way, and what the rules and screens did; the one place the Answer (answer.py) is built from them.

Why: every library ends a diagnosis with the same things under its own names (its held-out error in a unit
of its own: metres of a track, noise floors of a signal), and the libraries wrote the same JSON from them
twice: runner-up evidence, candidates ranked, held-out error before and after (after made honest by the
proof of searched terms), per held-out run, calibrated and fitted values with intervals. A library
subclasses :class:`Outcome` with its own fields and fills its hooks, as an Optuna sampler fills
BaseSampler's (a subclass that leaves one unfilled is refused where it is defined):

- ``library_name`` and ``held_out_unit`` (class attributes): who answers, in what unit it judges;
- ``verdict``, ``verdict_text`` and ``proof`` (fields or properties): the verdict, in its own words, and
  the proof of the answer's searched terms (proof.py; None when it has none);
- :meth:`effect_entries`, :meth:`noise_floor_entry` and :meth:`case_fields` (required): its effects as the
  JSON names them, its noise floor and the fields only it has;
- :meth:`interval`, :meth:`groups`, :attr:`calibrated` and :meth:`written` (optional): how wide an interval
  it quotes, each held-out run's group, the model before, and what it wrote.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

from ...sweeps.fit import FitResult
from . import answer as answer_
from . import explain
from .explain import Candidate
from .proof import honest
from .validation import Validation


class Jsonable(Protocol):
    """A library's own record (its evidence between sets that fit alike) as the JSON holds it."""

    def to_json(self) -> dict[str, Any]: ...


@dataclass(kw_only=True)
class Outcome(ABC):
    """What every library's diagnosis found; its :meth:`answer` is the JSON every diagnosis gives."""

    library_name: ClassVar[str]  # the hypothesis library that answers
    held_out_unit: ClassVar[str]  # what its held-out error is measured in
    FILLED: ClassVar[tuple[str, ...]] = ("verdict", "verdict_text", "proof")  # a field or a property each

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """A library's outcome that leaves a hook unfilled is refused when its module is imported, not after
        a whole diagnosis has run and before its JSON is written."""
        super().__init_subclass__(**kwargs)
        if ABC in cls.__bases__:
            return  # an abstract step between: its subclasses fill the hooks
        own = [k for k in cls.__mro__ if k not in (Outcome, ABC, object)]
        declared = {name for k in own for name in (*vars(k), *vars(k).get("__annotations__", {}))}
        missing = [n for n in ("library_name", "held_out_unit") if not isinstance(getattr(cls, n, None), str)]
        missing += [n for n in cls.FILLED if n not in declared]
        if missing:
            raise TypeError(
                f"{cls.__qualname__} subclasses Outcome but fills no {', '.join(missing)} (outcome.py: "
                "a library's outcome names its library and unit, and gives its verdict, words and proof)"
            )

    baseline: Candidate  # the calibrated model: no effect
    chosen: Candidate  # the answer; the baseline when nothing is missing
    candidates: list[Candidate]  # every set fitted on the way
    space: str | None = None  # the name of the space diagnosed: the report's title
    validation: Validation | None = None  # what held-out means here
    screen: answer_.Screen | None = None  # what the combination screen did (choice.screen_of)
    growth: list[dict[str, Any]] = field(default_factory=list)  # each round of one more effect (engine.grown)
    lookalikes: list[Jsonable] = field(default_factory=list)  # the evidence between twin sets
    dropped: list[explain.Dropped] = field(default_factory=list)  # members a rule took away
    located: dict[str, Any] = field(default_factory=dict)  # where the residuals lie, before and after
    files: dict[str, Any] = field(default_factory=dict)  # what was written: report, page, values ...

    # ---- what each library fills ---------------------------------------------------------------------

    @abstractmethod
    def effect_entries(self) -> list[answer_.Effect]:
        """The answer's members as the JSON's ``effects``; [none] when nothing is named."""

    @abstractmethod
    def noise_floor_entry(self) -> answer_.NoiseFloor:
        """The noise floor the verdict was judged against, in ``held_out_unit``."""

    @abstractmethod
    def case_fields(self) -> dict[str, Any]:
        """What only this library has: the JSON's ``case``."""

    def interval(self, fit: FitResult) -> dict[str, tuple[float, float]]:
        """The ~95 % intervals this library quotes for a fit's values."""
        return fit.interval()

    def groups(self) -> Mapping[str, str | None]:
        """Each held-out scenario's group, where the runs have groups (scenario -> group)."""
        return {}

    @property
    def calibrated(self) -> answer_.Fitted:
        """The model before: calibrated, no effect, with its intervals."""
        return self._fitted(self.baseline.full)

    def written(self) -> dict[str, Any]:
        """What was written, as the JSON's ``files``: each path as text."""
        return {name: str(path) for name, path in self.files.items()}

    # ---- the skeleton every library shares -----------------------------------------------------------

    @property
    def held_out_before(self) -> float:
        """The calibrated model's held-out error."""
        return self.baseline.cross_validated

    @property
    def held_out_after(self) -> float:
        """The answer's held-out error; with searched terms, their proof's if worse (proof.honest)."""
        return honest(self.chosen.cross_validated, self.proof)

    @property
    def runner_up(self) -> explain.Evidence | None:
        """The best real alternative to the answer, with the evidence against it."""
        other = explain.runner_up(self.chosen, self.candidates)
        return explain.evidence(self.chosen, other) if other is not None else None

    @property
    def held_out(self) -> list[answer_.HeldOut]:
        """Each run (or block of time) held out: the calibrated model's error, the answer's, its group."""
        return answer_.HeldOut.between(self.baseline, self.chosen, self.groups())

    @property
    def fitted(self) -> answer_.Fitted:
        """Every value the answer fitted jointly (calibrated ones and effects), with its interval: what a
        later study on the diagnosed plant starts from, e.g. plants drawn for robustness."""
        return self._fitted(self.chosen.full)

    def _fitted(self, fit: FitResult) -> answer_.Fitted:
        return answer_.Fitted(
            parameters=dict(fit.values),
            interval={name: list(bounds) for name, bounds in self.interval(fit).items()},
            at_bound=list(fit.at_bound),
        )

    def answer(self) -> answer_.Answer:
        """The diagnosis in the one shape every library answers in (answer.py)."""
        up, proof = self.runner_up, self.proof
        return answer_.Answer(
            library=self.library_name,
            space=self.space or None,
            verdict=self.verdict,
            verdict_text=self.verdict_text,
            held_out_before=self.held_out_before,
            held_out_after=self.held_out_after,
            held_out_unit=self.held_out_unit,
            noise_floor=self.noise_floor_entry(),
            effects=self.effect_entries(),
            runner_up=up.to_json() if up is not None else None,
            candidates=[answer_.CandidateEntry.of(c) for c in explain.ranked(self.candidates)],
            dropped=[d.to_json() for d in self.dropped],
            proof=proof.to_json() if proof is not None else None,
            validation=self.validation.to_json() if self.validation is not None else None,
            held_out=self.held_out,
            lookalikes=[look.to_json() for look in self.lookalikes],
            screen=self.screen,
            growth=[answer_.Growth(**g) for g in self.growth],
            calibrated=self.calibrated,
            fitted=self.fitted,
            files=self.written(),
            case=self.case_fields(),
        )

    def to_json(self) -> dict[str, Any]:
        return self.answer().json_dict()

    def files_told(self, names: Iterable[str]) -> list[str]:
        """The lines a summary ends with: where each of ``names`` was written, of those that were."""
        return [f"{name}: {self.files[name]}" for name in names if name in self.files]
