"""What a diagnosis is asked (DiagnosisSettings) and what it answers (Diagnosis): the JSON
and the report are drawn from it."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ...analysis.diagnose import answer as answer_
from ...analysis.diagnose import discovery, explain, screens
from ...analysis.diagnose.engine import MAX_EFFECTS
from ...analysis.diagnose.explain import Candidate
from ...analysis.diagnose.findings import DiscoveredCorrection, Finding, NamedEffect
from ...analysis.diagnose.proof import honest
from ...analysis.diagnose.report import ids
from ...analysis.diagnose.validation import record_of
from ...errors import DseError
from ...simulation.scenario import dropouts_line
from . import correction, lookalike, noise
from .hypotheses import LIBRARY
from .noise import NoiseFloor

SCREEN = (
    "linearised"  # the combination screen the Robotti runs unless asked for another (screens/registry.py)
)


@dataclass(frozen=True)
class DiagnosisSettings:
    folds: int = 3
    max_effects: int = MAX_EFFECTS  # the answer grows one effect at a time up to this many (engine.grown)
    pairs: int = 4  # best screened pairs fitted for real
    triples: int = 2  # best screened triples fitted for real
    shortlist: int = (
        10  # most sets fitted for real after the screen: those pairs and triples, then look-alikes
    )
    survivors: int = 3  # most combinations cross-validated: the best by BIC of those passing its gate
    min_gain: float = explain.MIN_GAIN
    bic_margin: float = explain.BIC_MARGIN
    max_iterations: int = 15
    hypotheses: tuple[str, ...] = ()  # the library's ids to try; () tries them all
    noise_factor: float = explain.NOISE_FACTOR  # held-out error above this many noise floors is unexplained
    floor_stop: float = explain.FLOOR_STOP  # no combination is screened when a fit is within this many floors
    discovery: bool = True  # seek a data-driven correction when the library leaves a residual above the noise
    max_terms: int = 3  # most terms a discovered correction may have
    screen: str = SCREEN  # the combination screen by name (analysis/diagnose/screens/registry.py)

    def __post_init__(self) -> None:
        screens.known(self.screen)
        if not (math.isfinite(self.noise_factor) and self.noise_factor > 0):
            raise DseError(
                f"noise factor {self.noise_factor!r}: must be a positive number (default "
                f"{explain.NOISE_FACTOR:g}: held-out error above twice the noise floor is a residual)"
            )
        if not (math.isfinite(self.floor_stop) and self.floor_stop > 0):
            raise DseError(
                f"floor stop {self.floor_stop!r}: must be a positive number (default {explain.FLOOR_STOP:g})"
            )
        counts = {
            "pairs": self.pairs,
            "triples": self.triples,
            "shortlist": self.shortlist,
            "survivors": self.survivors,
            "max_effects": self.max_effects,
            "max_terms": self.max_terms,
        }
        bad = [f"{k} = {v!r}" for k, v in counts.items() if not (isinstance(v, int) and v >= 0)]
        if bad:
            raise DseError(f"diagnosis settings {', '.join(bad)}: each must be a whole number, 0 or more")

    def screen_settings(self) -> screens.ScreenSettings:
        """What of the combination screen is fitted for real: no triple when one effect more than a pair is
        not allowed."""
        return screens.ScreenSettings(
            self.pairs, self.triples if self.max_effects >= 3 else 0, self.shortlist
        )

    def singles(self) -> list[tuple[str, ...]]:
        """The hypotheses fitted alone: the chosen ids of the library, each checked."""
        unknown = [h for h in self.hypotheses if h not in LIBRARY]
        if unknown:
            raise DseError(
                f"unknown hypothesis {', '.join(map(repr, unknown))}: the library has "
                f"{', '.join(h for h in LIBRARY if h != 'none')} (and none, always tried)"
            )
        return [(hid,) for hid in dict.fromkeys(self.hypotheses or LIBRARY) if hid != "none"]


@dataclass
class Diagnosis:
    out: Path
    calibration: dict[str, Any]  # best grid point, parameters at a bound, insensitive scenarios
    candidates: list[Candidate]  # every candidate fitted, best first
    chosen: Candidate  # the baseline when nothing is missing
    baseline: Candidate
    settings: DiagnosisSettings = DiagnosisSettings()
    located: dict[str, Any] = field(
        default_factory=dict
    )  # locate.located: the residuals by group, segment, run
    files: dict[str, Path] = field(default_factory=dict)
    dropouts: dict[str, int] = field(default_factory=dict)  # GPS fixes skipped per run (scenario.dropouts)
    floor: NoiseFloor = noise.UNKNOWN  # the GPS noise floor, estimated from the recordings alone
    screen: answer_.Screen | None = None  # what the combination screen did (choice.screen_of)
    growth: list[dict[str, Any]] = field(default_factory=list)  # each round of one more effect (engine.grown)
    lookalikes: list[lookalike.LookAlike] = field(default_factory=list)  # the evidence between twin sets
    discovery: discovery.Discovery | None = None  # what was sought beyond the library; None if nothing was
    dropped: list[explain.Dropped] = field(default_factory=list)  # members the noise rule took away

    @property
    def discovered(self) -> bool:
        """Whether the chosen model carries a discovered correction."""
        return discovery.DISCOVERED in self.chosen.ids

    @property
    def library(self) -> Candidate:
        """The best the library alone did: the reference discovery started from, else the chosen set."""
        return self.discovery.reference if self.discovery is not None else self.chosen

    @property
    def verdict(self) -> str:
        """none, explained, partial, discovered or unexplained: the chosen model's held-out error against the
        noise floor; a discovered correction that passed the rule gives discovered when it leaves only noise,
        partial when it does not."""
        floor = self.floor.cross_track if self.floor.available else None
        return explain.verdict(
            self.cross_track_after,
            floor,
            self.settings.noise_factor,
            bool(discovery.library_ids(self.chosen.ids)),
            self.discovered,
        )

    @property
    def verdict_line(self) -> str:
        """The verdict with the noise floor it was judged against, as the summary prints it."""
        if self.floor_ratio is None:
            return f"{self.verdict} (no noise floor could be estimated)"
        return (
            f"{self.verdict} ({self.floor_ratio:.1f}× the noise floor of {self.floor.cross_track:.3f} m, "
            f"{self.floor.method})"
        )

    @property
    def partial(self) -> bool:
        """Whether the chosen library effects are at most part of the cause: they leave a residual well above
        the noise, or needed a discovered correction beside them."""
        return self.verdict in (explain.PARTIAL, explain.DISCOVERED, explain.UNEXPLAINED)

    @property
    def floor_ratio(self) -> float | None:
        """The chosen model's held-out error as a multiple of the noise floor (None without a floor)."""
        return self.cross_track_after / self.floor.cross_track if self.floor.available else None

    @property
    def runner_up(self) -> explain.Evidence | None:
        """The best real alternative to the chosen candidate, with the evidence against it."""
        other = explain.runner_up(self.chosen, self.candidates)
        return explain.evidence(self.chosen, other) if other is not None else None

    @property
    def noise_floor(self) -> dict[str, Any]:
        """The floor as JSON, with the factor the verdict used and the chosen model's ratio to it."""
        return {**self.floor.to_json(), "factor": self.settings.noise_factor, "ratio": self.floor_ratio}

    @property
    def findings(self) -> list[Finding]:
        """The chosen hypotheses with their fitted parameters and ~95 % intervals; [none] if nothing.
        Each says whether it is ``partial``: chosen, but leaving a residual well above the noise."""
        if not self.chosen.ids:
            return [NamedEffect("none", LIBRARY["none"].name, {}, {}, partial=False)]
        order = explain.removal_order(self.chosen, self.candidates)
        return [self._discovered() if hid == discovery.DISCOVERED else self._effect(hid) for hid in order]

    @property
    def effects(self) -> list[dict[str, Any]]:
        """The findings as the JSON's ``effects``."""
        return [finding.to_json() for finding in self.findings]

    def _discovered(self) -> DiscoveredCorrection:
        """The discovered correction: its terms in readable form, its held-out gain over the library's best
        and the library effect it resembles most."""
        fit = self.chosen.full
        interval = fit.interval()
        terms = correction.terms_json(fit)
        similar = self.discovery.resembles if self.discovery is not None else []
        return DiscoveredCorrection(
            id=discovery.DISCOVERED,
            name="a data-driven correction of the model (discovered)",
            terms=terms,
            readable=correction.readable(fit.point),
            parameters={t["variable"]: t["value"] for t in terms},
            interval={
                n.rsplit(".", 1)[-1]: list(interval[n]) for n in fit.values if correction.is_correction(n)
            },
            resembles=(
                {
                    "id": similar[0][0],
                    "similarity": similar[0][1],
                    "text": discovery.resemblance_words(similar),
                }
                if similar
                else None
            ),
            similarities=dict(similar),
            held_out_without=self.library.cross_validated,
            held_out_with=self.chosen.cross_validated,
            partial=self.verdict == explain.PARTIAL,
        )  # it too leaves a residual above the noise

    def _effect(self, hid: str) -> NamedEffect:
        h, fit = LIBRARY[hid], self.chosen.full
        refs = {v: f"{self.calibration['vehicle']}.{v}" for v in h.variables}
        values = {v: fit.values[ref] for v, ref in refs.items()}
        interval = fit.interval()
        return NamedEffect(
            hid,
            h.name,
            values,
            {v: list(interval[ref]) for v, ref in refs.items()},
            magnitude=h.magnitude(values),
            partial=self.partial,
        )

    @property
    def cross_track_before(self) -> float:
        return self.baseline.cross_validated

    @property
    def cross_track_after(self) -> float:
        """The chosen model's held-out error; with discovered terms, their proof's (proof.honest)."""
        proof = self.discovery.proof if self.discovered and self.discovery is not None else None
        return honest(self.chosen.cross_validated, proof)

    @property
    def fitted(self) -> dict[str, Any]:
        """Every parameter of the chosen model as fitted jointly (calibrated ones and effects), with ~95 %
        intervals: what a later study on the diagnosed plant starts from, e.g. plants drawn for robustness."""
        fit = self.chosen.full
        return {
            "parameters": dict(fit.values),
            "interval": {k: list(v) for k, v in fit.interval().items()},
            "at_bound": list(fit.at_bound),
        }

    def summary(self) -> list[str]:
        """What was named (a discovered correction's terms as an engineer writes them), the held-out error
        before and after, the verdict against the noise floor, and the files written."""
        lines = []
        for finding in self.findings:
            if isinstance(finding, DiscoveredCorrection):
                lines.append(
                    f"{finding.id}: {finding.described()}"
                    + (f" ({finding.resembles['text']})" if finding.resembles else "")
                )
                continue
            values = finding.described()
            lines.append(f"{finding.id}: {finding.name}" + (f": {values}" if values else ""))
        lines.append(
            f"held-out mean cross-track error: {self.cross_track_before:.3f} m before, "
            f"{self.cross_track_after:.3f} m after"
        )
        lines.append(f"verdict: {self.verdict_line}")
        if self.dropouts:
            lines.append(dropouts_line(self.dropouts))
        lines.extend(
            f"{name}: {self.files[name]}"
            for name in ("multimodel", "space", "report", "html")
            if name in self.files
        )
        return lines

    @property
    def held_out(self) -> list[answer_.HeldOut]:
        """Each run (or block of time) held out: the calibrated model's error, the chosen one's, its group."""
        groups = self.calibration.get("groups") or {}
        return answer_.HeldOut.between(
            self.baseline, self.chosen, {s: groups.get(record_of(s)) for s in self.baseline.held_out}
        )

    def answer(self) -> answer_.Answer:
        """The diagnosis in the one shape every library answers in (analysis/diagnose/answer.py); what only
        the Robotti has (its calibration grid, screen and equation-error discovery) under ``case``."""
        up, floor = self.runner_up, self.floor
        discovery = self.discovery
        return answer_.Answer(
            library="robotti",
            space=self.calibration.get("sweep"),
            verdict=self.verdict,
            verdict_text=verdict_words(self),
            held_out_before=self.cross_track_before,
            held_out_after=self.cross_track_after,
            held_out_unit="m (mean cross-track error on held-out runs, Equation 1)",
            noise_floor=answer_.NoiseFloor(
                held_out=floor.cross_track if floor.available else None,
                factor=self.settings.noise_factor,
                ratio=self.floor_ratio,
                method=floor.method,
                details=floor.to_json(),
            ),
            effects=[answer_.Effect(**finding.to_json()) for finding in self.findings],
            runner_up=up.to_json() if up is not None else None,
            candidates=[answer_.CandidateEntry.of(c) for c in self.candidates],
            dropped=[d.to_json() for d in self.dropped],
            proof=discovery.proof.to_json() if self.discovered and discovery and discovery.proof else None,
            validation=self.calibration.get("validation"),
            held_out=self.held_out,
            lookalikes=[look.to_json() for look in self.lookalikes],
            screen=self.screen,
            growth=[answer_.Growth(**g) for g in self.growth],
            calibrated=answer_.Fitted(
                parameters=dict(self.baseline.full.values),
                interval={k: list(v) for k, v in self.baseline.full.interval().items()},
                at_bound=list(self.baseline.full.at_bound),
            ),
            fitted=self.fitted,
            files={k: str(v) for k, v in self.files.items()},
            case={
                "settings": asdict(self.settings),
                "calibration": self.calibration,
                "discovery": discovery.to_json() if discovery is not None else None,
                "dropouts": self.dropouts,
                "located": self.located,  # where the residuals lie, by group, segment and run
            },
        )

    def to_json(self) -> dict[str, Any]:
        return self.answer().json_dict()


# ---- the verdict in an engineer's words: the answer's verdict_text -----------------------------------


def verdict_words(diagnosis: Diagnosis) -> str:
    """The verdict in an engineer's words: the chosen model's held-out error against the noise floor (the
    report puts the verdict itself before them)."""
    verdict, floor = diagnosis.verdict, diagnosis.floor
    after = diagnosis.cross_track_after
    factor = diagnosis.settings.noise_factor
    chosen = ids(diagnosis.chosen.label) if diagnosis.chosen.ids else ""
    if not floor.available:
        return (
            "The GPS noise could not be estimated from these recordings (no three consecutive close fixes "
            "and no stop), so the residual is not weighed against it: read the finding as the best of the "
            "library, not as proof that nothing else is missing."
        )
    level = f"{after:.3f} m, {diagnosis.floor_ratio:.1f}× the noise floor of {floor.cross_track:.3f} m"
    remains = after - floor.cross_track
    if diagnosis.discovered:
        return _discovered_words(diagnosis)
    if verdict == explain.EXPLAINED:
        return (
            f"With {chosen} the held-out error is {level}; up to {factor:g}× counts as noise, so what "
            "remains is receiver noise or too close to it to tell apart."
        )
    if verdict == explain.PARTIAL:
        return (
            f"The runs support {chosen}, but it is not the whole story: after it the held-out error is "
            f"{level}, "
            f"above the {factor:g}× that counts as noise. The library does not explain the residual: about "
            f"{remains:.3f} m of mean cross-track error remains above the noise. Read the effect as part of "
            "the cause, not as the cause."
        )
    if verdict == explain.UNEXPLAINED:
        return (
            "No hypothesis of the library explains the residual, and it is not noise: the calibrated model's "
            f"held-out error is {level}, above the {factor:g}× that counts as noise; about {remains:.3f} m "
            "of mean cross-track error remains unexplained."
        )
    return (
        f"Nothing is missing: the calibrated model's held-out error is {level}, within the {factor:g}× that "
        "counts as noise."
    )


def _discovered_words(diagnosis: Diagnosis) -> str:
    """When a discovered correction passed: the library falls short, and by how much; the term; and, when the
    correction too leaves a residual above the noise (verdict partial), how much remains."""
    floor, library, chosen = diagnosis.floor, diagnosis.library, diagnosis.chosen
    entry = next(e for e in diagnosis.effects if e["id"] == discovery.DISCOVERED)
    remains = library.cross_validated - floor.cross_track
    gain = 100.0 * (1.0 - chosen.cross_validated / library.cross_validated)
    named = [e for e in diagnosis.effects if e["id"] != discovery.DISCOVERED]
    whole = diagnosis.verdict == explain.DISCOVERED
    part = (
        " Read " + ", ".join(f"`{e['id']}`" for e in named) + " as part of the cause, not as the cause."
        if named
        else ""
    )
    resembles = entry["resembles"]["text"] if entry["resembles"] else "was not compared with the library"
    left = (
        f" It is not the whole story either: about {chosen.cross_validated - floor.cross_track:.3f} m of "
        "mean cross-track error remains above the noise, which the correction block's terms do not express; "
        "read the correction as part of the cause."
        if not whole
        else ""
    )
    without = f"with {ids(library.label)}" if library.ids else "with the calibrated model alone"
    return (
        f"The library does not explain the residual: {without} the held-out error is "
        f"{library.cross_validated:.3f} m, {library.cross_validated / floor.cross_track:.1f}× the noise "
        f"{floor.cross_track:.3f} m, so about {remains:.3f} m of mean cross-track error remains above the "
        f"noise. A data-driven correction explains {'most' if whole else 'part'} of it: "
        + "; ".join(f"`{t}`" for t in entry["readable"])
        + f". With it the held-out error is {chosen.cross_validated:.3f} m ({gain:.0f} % lower, "
        f"{chosen.cross_validated / floor.cross_track:.1f}× the floor), on runs the fits did not see, and it "
        f"passed the same rule as the library's effects. It {resembles}.{part}{left}"
    )
