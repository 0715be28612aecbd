"""What a diagnosis is asked (DiagnosisSettings) and what it found (Diagnosis, the engine's Outcome with the
Robotti's fields: its calibration grid, GPS noise floor and discovery): the JSON and the report are drawn
from it; and its verdict in an engineer's words."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ...analysis.diagnose import answer as answer_
from ...analysis.diagnose import discovery, explain, screens
from ...analysis.diagnose.engine import MAX_EFFECTS
from ...analysis.diagnose.explain import Candidate
from ...analysis.diagnose.findings import DiscoveredCorrection, Finding, NamedEffect
from ...analysis.diagnose.outcome import Outcome
from ...analysis.diagnose.proof import Proof
from ...analysis.diagnose.report import ids
from ...analysis.diagnose.validation import record_of
from ...errors import DseError
from ...simulation.scenario import dropouts_line
from . import correction, noise
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
        explain.floors(self.noise_factor, "noise factor", explain.NOISE_FACTOR)
        explain.floors(self.floor_stop, "floor stop", explain.FLOOR_STOP)
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
class Diagnosis(Outcome):
    """What the Robotti's diagnosis found (the engine's Outcome), judged in metres of cross-track error
    against the GPS noise floor."""

    library_name = "robotti"
    held_out_unit = "m (mean cross-track error on held-out runs, Equation 1)"

    out: Path
    calibration: dict[str, Any]  # best grid point, parameters at a bound, insensitive scenarios
    settings: DiagnosisSettings = DiagnosisSettings()
    dropouts: dict[str, int] = field(default_factory=dict)  # GPS fixes skipped per run (scenario.dropouts)
    floor: NoiseFloor = noise.UNKNOWN  # the GPS noise floor, estimated from the recordings alone
    discovery: discovery.Discovery | None = None  # what was sought beyond the library; None if nothing was

    @property
    def discovered(self) -> bool:
        """Whether the chosen model carries a discovered correction."""
        return discovery.DISCOVERED in self.chosen.ids

    @property
    def library(self) -> Candidate:
        """The best the library alone did: the reference discovery started from, else the chosen set."""
        return self.discovery.reference if self.discovery is not None else self.chosen

    @property
    def proof(self) -> Proof | None:
        """The proof of the discovered correction's terms, when the chosen model carries it."""
        return self.discovery.proof if self.discovered and self.discovery is not None else None

    @property
    def verdict(self) -> str:
        """none, explained, partial, discovered or unexplained: the chosen model's held-out error against the
        noise floor; a discovered correction that passed the rule gives discovered when it leaves only noise,
        partial when it does not."""
        floor = self.floor.cross_track if self.floor.available else None
        return explain.verdict(
            self.held_out_after,
            floor,
            self.settings.noise_factor,
            bool(discovery.library_ids(self.chosen.ids)),
            self.discovered,
        )

    @property
    def verdict_text(self) -> str:
        """The verdict in an engineer's words (verdict_words, below)."""
        return verdict_words(self)

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
        return self.held_out_after / self.floor.cross_track if self.floor.available else None

    def noise_floor_entry(self) -> answer_.NoiseFloor:
        """The GPS noise floor, with the factor the verdict used and the chosen model's ratio to it."""
        floor = self.floor
        return answer_.NoiseFloor(
            held_out=floor.cross_track if floor.available else None,
            factor=self.settings.noise_factor,
            ratio=self.floor_ratio,
            method=floor.method,
            details=floor.to_json(),
        )

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

    def effect_entries(self) -> list[answer_.Effect]:
        return [answer_.Effect(**effect) for effect in self.effects]

    def _discovered(self) -> DiscoveredCorrection:
        """The discovered correction: its terms in readable form, its held-out gain over the library's best
        and the library effect it resembles most."""
        fit = self.chosen.full
        interval = self.interval(fit)
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
        interval = self.interval(fit)
        return NamedEffect(
            hid,
            h.name,
            values,
            {v: list(interval[ref]) for v, ref in refs.items()},
            magnitude=h.magnitude(values),
            partial=self.partial,
        )

    def groups(self) -> dict[str, str | None]:
        """Each held-out run's group (a block of time: its record's)."""
        groups = self.calibration.get("groups") or {}
        return {s: groups.get(record_of(s)) for s in self.baseline.held_out}

    def case_fields(self) -> dict[str, Any]:
        """What only the Robotti has: its settings, calibration grid, equation-error discovery, GPS dropouts
        and where the residuals lie (by group, segment and run)."""
        return {
            "settings": asdict(self.settings),
            "calibration": self.calibration,
            "discovery": self.discovery.to_json() if self.discovery is not None else None,
            "dropouts": self.dropouts,
            "located": self.located,
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
            f"held-out mean cross-track error: {self.held_out_before:.3f} m before, "
            f"{self.held_out_after:.3f} m after"
        )
        lines.append(f"verdict: {self.verdict_line}")
        if self.dropouts:
            lines.append(dropouts_line(self.dropouts))
        return lines + self.files_told(("multimodel", "space", "report", "html"))


# ---- the verdict in an engineer's words: the answer's verdict_text -----------------------------------


def verdict_words(diagnosis: Diagnosis) -> str:
    """The verdict in an engineer's words: the chosen model's held-out error against the noise floor (the
    report puts the verdict itself before them)."""
    verdict, floor = diagnosis.verdict, diagnosis.floor
    after = diagnosis.held_out_after
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
