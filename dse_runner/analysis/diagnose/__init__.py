"""Discrepancy diagnosis: calibrate, locate the mismatch, explain it, model it, show the fit improve.

:func:`diagnose` runs the whole chain on a folder of runs in the field-data
format. Every simulation is a task of a sweep on the Dask cluster, with rows
in the Parquet store under ``out``: the calibration grid is an ordinary
sweep, and each fit (fit.py) runs its rounds as sweeps of the *effects*
multi-model, the user's multi-model with the vehicle replaced by its effects
variant, in which every hypothesis of the library is a parameter that is
zero when absent.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ... import bundled
from ...cases import fielddata
from ...errors import DseError
from ...simulation.multimodel import MultiModel, split_ref
from ...simulation.scenario import dropouts
from ...sweeps.cluster import connect
from ...sweeps.fit import (
    FitProblem,
    FitResult,
    Parameter,
    Point,
    Residuals,
    evaluate_points,
    fit_all,
    key_of,
    residuals_in,
    wanted,
)
from ...sweeps.spec import Range, Space, SpaceSpec, read_spec, resolve_space
from ...sweeps.sweep import submit, trajectories_of
from ...sweeps.rank import rank
from . import correction, discover, explain, locate, lookalike, noise, screen
from .correction import variables as correction_variables
from .explain import Candidate
from .hypotheses import EFFECTS_FMU, LIBRARY, effect_variables, hypothesis
from .noise import NoiseFloor

RESIDUALS = "fix_residuals"  # the field-data case's vector objective (cases/fielddata.py): offsets at every fix

DEFAULT_SPACE = "bundled:robotti/calibration.yaml"  # the Robotti baseline's calibration grid
FITS = "diagnosis-fits"  # the sweep every fit's rounds go to
BEFORE, AFTER = "diagnosis-before", "diagnosis-after"  # sweeps holding the tracks of the report

Progress = Callable[[str], None]


@dataclass(frozen=True)
class Settings:
    folds: int = 3
    max_effects: int = 3
    pairs: int = 4  # best screened pairs fitted for real
    triples: int = 2  # best screened triples fitted for real
    shortlist: int = 10  # most sets fitted for real after the screen: those pairs and triples, then look-alikes
    survivors: int = 3  # most combinations cross-validated: the best by BIC of those passing its gate
    min_gain: float = explain.MIN_GAIN
    bic_margin: float = explain.BIC_MARGIN
    max_iterations: int = 15
    hypotheses: tuple[str, ...] = ()  # the library's ids to try; () tries them all
    noise_factor: float = explain.NOISE_FACTOR  # held-out error above this many noise floors is unexplained
    floor_stop: float = explain.FLOOR_STOP  # no combination is screened when a fit is within this many floors
    discovery: bool = True  # seek a data-driven correction when the library leaves a residual above the noise
    max_terms: int = 3  # most terms a discovered correction may have

    def __post_init__(self) -> None:
        if not (math.isfinite(self.noise_factor) and self.noise_factor > 0):
            raise DseError(f"noise factor {self.noise_factor!r}: must be a positive number (default "
                           f"{explain.NOISE_FACTOR:g}: held-out error above twice the noise floor is a residual)")
        if not (math.isfinite(self.floor_stop) and self.floor_stop > 0):
            raise DseError(f"floor stop {self.floor_stop!r}: must be a positive number (default "
                           f"{explain.FLOOR_STOP:g})")
        counts = {"pairs": self.pairs, "triples": self.triples, "shortlist": self.shortlist,
                  "survivors": self.survivors, "max_effects": self.max_effects, "max_terms": self.max_terms}
        bad = [f"{k} = {v!r}" for k, v in counts.items() if not (isinstance(v, int) and v >= 0)]
        if bad:
            raise DseError(f"diagnosis settings {', '.join(bad)}: each must be a whole number, 0 or more")

    def singles(self) -> list[tuple[str, ...]]:
        """The hypotheses fitted alone: the chosen ids of the library, each checked."""
        unknown = [h for h in self.hypotheses if h not in LIBRARY]
        if unknown:
            raise DseError(f"unknown hypothesis {', '.join(map(repr, unknown))}: the library has "
                           f"{', '.join(h for h in LIBRARY if h != 'none')} (and none, always tried)")
        return [(hid,) for hid in dict.fromkeys(self.hypotheses or LIBRARY) if hid != "none"]


@dataclass
class Diagnosis:
    out: Path
    calibration: dict[str, Any]  # best grid point, parameters at a bound, insensitive scenarios
    candidates: list[Candidate]  # every candidate fitted, best first
    chosen: Candidate  # the baseline when nothing is missing
    baseline: Candidate
    settings: Settings = Settings()
    located: dict[str, Any] = field(default_factory=dict)  # locate's tables, before and after
    files: dict[str, Path] = field(default_factory=dict)
    dropouts: dict[str, int] = field(default_factory=dict)  # GPS fixes skipped per run (scenario.dropouts)
    floor: NoiseFloor = noise.UNKNOWN  # the GPS noise floor, estimated from the recordings alone
    screened: list[screen.Screened] = field(default_factory=list)  # every combination the screen tried, best first
    shortlisted: list[str] = field(default_factory=list)  # the labels of those then fitted for real
    lookalikes: list[lookalike.LookAlike] = field(default_factory=list)  # the evidence between twin sets
    discovery: discover.Discovery | None = None  # what was sought beyond the library; None if nothing was

    @property
    def discovered(self) -> bool:
        """Whether the chosen model carries a discovered correction."""
        return discover.DISCOVERED in self.chosen.ids

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
        return explain.verdict(self.cross_track_after, floor, self.settings.noise_factor,
                               bool(discover.library_ids(self.chosen.ids)), self.discovered)

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
    def effects(self) -> list[dict[str, Any]]:
        """The chosen hypotheses with their fitted parameters and ~95 % intervals; [none] if nothing.
        Each says whether it is ``partial``: chosen, but leaving a residual well above the noise."""
        if not self.chosen.ids:
            return [{"id": "none", "name": LIBRARY["none"].name, "parameters": {}, "interval": {},
                     "partial": False}]
        order = explain.removal_order(self.chosen, self.candidates)
        return [self._discovered() if hid == discover.DISCOVERED else self._effect(hid) | {"partial": self.partial}
                for hid in order]

    def _discovered(self) -> dict[str, Any]:
        """The discovered correction: its terms in readable form, its held-out gain over the library's best
        and the library effect it resembles most."""
        fit = self.chosen.full
        interval = fit.interval()
        terms = discover.terms_json(fit)
        similar = self.discovery.resembles if self.discovery is not None else []
        return {"id": discover.DISCOVERED, "name": "a data-driven correction of the model (discovered)",
                "terms": terms, "readable": correction.readable(fit.point),
                "parameters": {t["variable"]: t["value"] for t in terms},
                "interval": {n.rsplit(".", 1)[-1]: list(interval[n]) for n in fit.values if correction.is_correction(n)},
                "resembles": ({"id": similar[0][0], "similarity": similar[0][1],
                               "text": discover.resemblance_words(similar)} if similar else None),
                "similarities": dict(similar),
                "held_out_without": self.library.cross_validated, "held_out_with": self.chosen.cross_validated,
                "partial": self.verdict == explain.PARTIAL}  # it too leaves a residual above the noise

    def _effect(self, hid: str) -> dict[str, Any]:
        h, fit = LIBRARY[hid], self.chosen.full
        refs = {v: f"{self.calibration['vehicle']}.{v}" for v in h.variables}
        values = {v: fit.values[ref] for v, ref in refs.items()}
        interval = fit.interval()
        return {"id": hid, "name": h.name, "parameters": values,
                "interval": {v: list(interval[ref]) for v, ref in refs.items()}, "magnitude": h.magnitude(values)}

    @property
    def cross_track_before(self) -> float:
        return self.baseline.cross_validated

    @property
    def cross_track_after(self) -> float:
        return self.chosen.cross_validated

    @property
    def fitted(self) -> dict[str, Any]:
        """Every parameter of the chosen model as fitted jointly (calibrated ones and effects), with ~95 %
        intervals: what a later study on the diagnosed plant starts from, e.g. plants drawn for robustness."""
        fit = self.chosen.full
        return {"parameters": dict(fit.values), "interval": {k: list(v) for k, v in fit.interval().items()},
                "at_bound": list(fit.at_bound)}

    def to_json(self) -> dict[str, Any]:
        up = self.runner_up
        return {
            "effects": self.effects,
            "cross_track_before": self.cross_track_before,
            "cross_track_after": self.cross_track_after,
            "verdict": self.verdict,
            "noise_floor": self.noise_floor,
            "runner_up": up.to_json() if up is not None else None,
            "lookalikes": [look.to_json() for look in self.lookalikes],
            "discovery": self.discovery.to_json() if self.discovery is not None else None,
            "held_out": [{"scenario": s, "before": self.baseline.held_out[s], "after": self.chosen.held_out[s]}
                         for s in sorted(self.baseline.held_out)],
            "candidates": [{"id": c.label, "cross_track_held_out": c.cross_validated, "bic": c.bic,
                            "cross_validated": c.validated, "parameters": c.full.values, "at_bound": c.full.at_bound}
                           for c in self.candidates],
            "screen": [{"id": x.label, "from": "+".join(x.anchor) or "none", "predicted_sse": x.predicted_sse,
                        "sse": x.sse, "bic": x.bic, "shortlisted": x.label in self.shortlisted}
                       for x in self.screened],
            "fitted": self.fitted,
            "calibration": self.calibration,
            "dropouts": self.dropouts,
            "files": {k: str(v) for k, v in self.files.items()},
        }


def calibration_space(space: str | Path, scenarios: str | Path, multimodel: str | Path | None, out: Path,
                      n_workers: int | None = None, address: str | None = None) -> Space:
    """The calibration's design space (parameters and their ranges) on the given runs, results in ``out``."""
    path = bundled.resolve(space, Path.cwd())
    folder = Path(scenarios).resolve()
    if not folder.is_dir():
        raise DseError(f"--scenarios {scenarios}: not a folder")
    update: dict[str, Any] = {"scenarios": [str(folder / "*")], "output": str(out), "keep_trajectories": 0}
    if multimodel is not None:
        update["multimodel"] = str(Path(multimodel).resolve())
    spec = read_spec(path).model_copy(update=update)
    return resolve_space(spec, path).with_overrides(address=address, n_workers=n_workers)


def vehicle_of(calibration: Space) -> str:
    """The instance whose outputs are the position compared with GPS: where the effects act."""
    if not calibration.scenarios or calibration.scenarios[0].kind != fielddata.KIND:
        raise DseError("diagnosis needs recorded runs in the field-data format (GPS fixes)")
    x, _ = fielddata.position_of(calibration.plan.recorded, calibration.scenarios[0])
    return split_ref(x)[0]


def at_antenna(entries: list[Any], vehicle: str) -> list[dict[str, Any]]:
    """Scenario entries whose runs are compared with GPS at the antenna's outputs (gps_x, gps_y)."""
    position = {"x": f"{vehicle}.gps_x", "y": f"{vehicle}.gps_y"}
    return [{"path": e, "position": position} if isinstance(e, str) else {**e, "position": position}
            for e in entries]


def effects_multimodel(multimodel: MultiModel, vehicle: str, folder: Path) -> dict[str, Any]:
    """The multi-model with ``vehicle`` replaced by the effects variant, to be written into ``folder``
    (FMU paths relative to it, bundled ones as ``bundled:``)."""
    bundled.bundled_path(EFFECTS_FMU)  # it ships with the package; an error names it if not
    data = multimodel.model_dump(mode="json")
    data["fmus"] = {name: ref if bundled.is_bundled(ref) else _relative(multimodel.fmu_path(name), folder)
                    for name, ref in multimodel.fmus.items()}
    data["fmus"][vehicle] = EFFECTS_FMU
    return data


def _relative(path: Path, folder: Path) -> str:
    """``path`` relative to ``folder`` where that is possible, so written files can move with the repository."""
    try:
        return os.path.relpath(path, folder)
    except ValueError:  # another drive
        return str(path)


def _write_yaml(path: Path, data: dict[str, Any], header: str = "") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(header + yaml.safe_dump(data, sort_keys=False))
    return path


def base_parameters(calibration: Space, best: dict[str, Any]) -> tuple[Parameter, ...]:
    """The calibration's numeric parameters with more than one value, bounded by their range,
    starting from the grid's best point."""
    params = []
    for name, values in calibration.parameters.items():
        numbers = [v for v in values if isinstance(v, float)]
        if len(numbers) == len(values) and len(set(numbers)) > 1:
            lower, upper = min(numbers), max(numbers)
            params.append(Parameter(name, float(best[name]), lower, upper, 0.01 * (upper - lower)))
    if not params:
        raise DseError(f"{calibration.path}: no numeric parameter with a range to calibrate")
    return tuple(params)


def fits_space(calibration: Space, vehicle: str, out: Path) -> Space:
    """A space over the effects multi-model whose rounds are given points (fit.py)."""
    mm_path = _write_yaml(out / "effects-multimodel.yaml", effects_multimodel(calibration.multimodel, vehicle, out),
                          "# The multi-model diagnosis fits: the vehicle replaced by its effects variant.\n")
    parameters = {name: values for name, values in calibration.parameters.items()}
    parameters.update({f"{vehicle}.{v}": [0.0] for v in effect_variables()})
    parameters.update({f"{vehicle}.{v}": [0.0] for v in correction_variables()})  # off until discovery frees them
    parameters.update({f"{vehicle}.{s.variable}": [s.default] for s in correction.SHAPES.values()})  # held by discovery
    entries = [e if isinstance(e, str) else e.model_dump() for e in calibration.spec.scenarios]
    spec = SpaceSpec(name=FITS, multimodel=str(mm_path), scenarios=at_antenna(entries, vehicle),
                     parameters=parameters, objectives=["cross_track_error", "fix_residuals"],
                     output=str(out), cluster=calibration.spec.cluster, keep_trajectories=0,
                     timeout=calibration.spec.timeout, chunk_seconds=calibration.spec.chunk_seconds)
    return resolve_space(spec, out / f"{FITS}.yaml")


def _effect_parameters(ids: tuple[str, ...], vehicle: str, start: dict[str, float]) -> tuple[Parameter, ...]:
    return tuple(Parameter(f"{vehicle}.{p.variable}", start.get(f"{vehicle}.{p.variable}", 0.0), p.lower, p.upper,
                           p.step)
                 for hid in ids for p in hypothesis(hid).parameters)


class Chain:
    """The state of one diagnosis between its steps."""

    def __init__(self, space: Space, vehicle: str, base: tuple[Parameter, ...], client, settings: Settings,
                 progress: Progress):
        self.space, self.vehicle, self.base, self.client = space, vehicle, base, client
        self.settings, self.say = settings, progress
        self.fixed = {name: values[0] for name, values in space.parameters.items()}
        self.folds = explain.folds(space.scenarios, settings.folds)
        self.all = tuple(s.name for s in space.scenarios)

    def problem(self, label: str, ids: tuple[str, ...], start: dict[str, float], scenarios: tuple[str, ...]
                ) -> FitProblem:
        base = tuple(Parameter(p.name, start.get(p.name, p.start), p.lower, p.upper, p.step) for p in self.base)
        params = base + _effect_parameters(ids, self.vehicle, start)
        names = {p.name for p in params}
        fixed = {k: v for k, v in self.fixed.items() if k not in names}
        return FitProblem(label, params, fixed, scenarios, self.settings.max_iterations)

    def full(self, ids: tuple[str, ...], start: dict[str, float]) -> FitProblem:
        """The fit of a set on every run."""
        return self.problem("+".join(ids) or "none", ids, start, self.all)

    def by_fold(self, candidate: Candidate) -> list[FitProblem]:
        """The fits of a set on the runs outside each fold, each from the set's fit on every run."""
        return [self.problem(f"{candidate.label}/fold{k}", candidate.ids, candidate.full.values,
                             tuple(s for s in self.all if s not in fold)) for k, fold in enumerate(self.folds)]

    def fit(self, problems: list[FitProblem], what: str) -> dict[str, FitResult]:
        """Every problem in one lockstep batch: each round one sweep."""
        def report(round_: int, active: int, points: int, simulations: int) -> None:
            self.say(f"{what}: round {round_}, {active} fits, {points} points, {simulations} simulations")

        return fit_all(self.space, problems, self.client, RESIDUALS, report) if problems else {}

    def score(self, candidates: list[Candidate], fits: dict[str, FitResult]) -> None:
        """Attach each candidate's fold fits and predict every run it held out with the fit that did not
        see it, all in one sweep."""
        points, only = wanted((fits[f"{c.label}/fold{k}"].point, fold)
                              for c in candidates for k, fold in enumerate(self.folds))
        rows, _ = evaluate_points(self.space, points, self.client, ["cross_track_error"], only)
        for c in candidates:
            for k, fold in enumerate(self.folds):
                fit = fits[f"{c.label}/fold{k}"]
                c.folds.append(fit)
                for scenario in fold:
                    row = rows.get((key_of(fit.point), scenario))
                    c.held_out[scenario] = (float(row["cross_track_error"])
                                            if row and row["status"] == "ok" else math.inf)

    def evaluate(self, points: list[Point], scenarios: Sequence[Sequence[str]] | None = None) -> Residuals:
        """The fix residuals of ``points`` on every run (or each on its ``scenarios``), as one sweep: the
        screen's probes and trials."""
        points, only = wanted((p, self.all if scenarios is None else s)
                              for p, s in zip(points, scenarios or [None] * len(points)))
        rows, _ = evaluate_points(self.space, points, self.client, [RESIDUALS], only)
        return residuals_in(rows, RESIDUALS)


def worth_screening(candidates: list[Candidate], floor: float | None, settings: Settings) -> bool:
    """Whether combinations could still explain something: not when a fit already leaves no more than
    ``floor_stop`` noise floors of error (on the runs it saw), nor when one effect at a time is the most
    allowed. Without a floor the screen always runs."""
    if settings.max_effects < 2 or len(settings.singles()) < 2:
        return False
    if floor is None or not (math.isfinite(floor) and floor > 0):
        return True
    return min(explain.fitted_error(c.full) for c in candidates) > settings.floor_stop * floor


def screen_combinations(chain: Chain, candidates: list[Candidate]) -> list[screen.Screened]:
    """Every pair, and triples of the best pairs, predicted from none and the best single fits, each checked
    by simulation (screen.py): best verified BIC first."""
    settings = chain.settings
    ids = [c.ids[0] for c in candidates if len(c.ids) == 1]
    anchors = screen.anchors({c.ids: c.full for c in candidates})
    entries = screen.catalogue(chain.base, chain.vehicle, ids)
    pairs = len(ids) * (len(ids) - 1) // 2
    chain.say(f"screening {pairs} pair{'s' * (pairs != 1)} from {', '.join(a.fit.label for a in anchors)}")
    return screen.screen(anchors, ids, entries, chain.all, chain.evaluate, triples=settings.max_effects >= 3)


@dataclass
class Choice:
    chosen: Candidate  # the baseline when nothing is missing
    candidates: list[Candidate]  # every set fitted: none, the singles, the shortlisted combinations
    screened: list[screen.Screened]  # every combination the screen tried, best first; [] when it did not run
    shortlisted: list[screen.Screened]  # those fitted for real


def choose(chain: Chain, start: dict[str, float], floor: float | None = None) -> Choice:
    """Fit none and every hypothesis alone; unless one already fits to the noise, screen every combination
    and fit the short list for real in the same batch as the singles' folds; cross-validate the combinations
    that pass the BIC gate; choose (explain.select)."""
    settings = chain.settings
    sets = [(), *settings.singles()]
    full = chain.fit([chain.full(ids, start) for ids in sets], "fitting none and each hypothesis")
    candidates = [Candidate(ids, full["+".join(ids) or "none"]) for ids in sets]
    screened, short = [], []
    if worth_screening(candidates, floor, settings):
        screened = screen_combinations(chain, candidates)
        short = screen.shortlist(screened, settings.pairs, settings.triples if settings.max_effects >= 3 else 0,
                                 settings.shortlist)
    else:
        chain.say("no combination screened: a fit is already within "
                  f"{settings.floor_stop:g}x the noise floor, or the settings allow one effect at a time")
    problems = [p for c in candidates for p in chain.by_fold(c)] + [chain.full(x.ids, x.start) for x in short]
    fits = chain.fit(problems, "cross-validating" + (f" and fitting {len(short)} combinations" if short else ""))
    chain.score(candidates, fits)
    baseline = next(c for c in candidates if not c.ids)
    current = explain.select(candidates, baseline, settings.min_gain, settings.bic_margin)
    combinations = [Candidate(x.ids, fits[x.label]) for x in short]
    everything = candidates + combinations
    survivors = explain.bic_gate(combinations, everything, current, settings.bic_margin, settings.survivors)
    if survivors:
        chain.score(survivors, chain.fit([p for c in survivors for p in chain.by_fold(c)],
                                         f"cross-validating {', '.join(c.label for c in survivors)}"))
    return Choice(explain.select(everything, baseline, settings.min_gain, settings.bic_margin), everything,
                  screened, short)


def write_model(diagnosis: Diagnosis, calibration: Space) -> dict[str, Path]:
    """The chosen effects as a multi-model and a space.yaml that re-calibrates with them."""
    if not diagnosis.chosen.ids:
        return {}
    out, vehicle = diagnosis.out, diagnosis.calibration["vehicle"]
    names = ", ".join(diagnosis.chosen.ids)
    mm_path = _write_yaml(out / "augmented-multimodel.yaml",
                          effects_multimodel(calibration.multimodel, vehicle, out),
                          f"# Written by dse-runner diagnose: the vehicle's effects variant, for {names}.\n")
    spec = calibration.spec.model_dump(mode="json", exclude={"output", "keep_trajectories"}, exclude_defaults=True)
    parameters = dict(spec["parameters"])
    fit = diagnosis.chosen.full
    interval = fit.interval()
    for name in fit.names:  # the discovered terms over their intervals, as the effects' below
        if correction.is_correction(name):
            low, high = sorted(interval[name])
            if not (math.isfinite(low) and math.isfinite(high)) or high <= low:
                low, high = sorted((0.0, 2.0 * fit.values[name]))
            parameters[name] = Range(start=round(low, 9), stop=round(high, 9), num=3).model_dump(exclude_none=True)
            shape = correction.shape_of(correction.term(name))
            if shape is not None:  # what shapes the term (when it switches on, ...), as the fits held it
                parameters[f"{vehicle}.{shape.variable}"] = [fit.point[f"{vehicle}.{shape.variable}"]]
    for hid in discover.library_ids(diagnosis.chosen.ids):
        for p in hypothesis(hid).parameters:
            ref = f"{vehicle}.{p.variable}"
            low, high = (max(p.lower, interval[ref][0]), min(p.upper, interval[ref][1]))
            if not (math.isfinite(low) and math.isfinite(high)) or high <= low:
                low, high = p.lower, p.upper
            parameters[ref] = Range(start=round(low, 6), stop=round(high, 6), num=3).model_dump(exclude_none=True)
    scenarios = at_antenna([_relative(Path(s), out) if isinstance(s, str) else s for s in spec["scenarios"]],
                           vehicle)
    spec.update(name=f"{calibration.name}-with-{'-'.join(diagnosis.chosen.ids)}", multimodel=mm_path.name,
                scenarios=scenarios, parameters=parameters, output="recalibration")
    space_path = _write_yaml(out / "space.yaml", spec,
                             f"# Written by dse-runner diagnose: the calibration with {names} added,\n"
                             "# each effect parameter over its fitted ~95 % interval. Run: dse-runner submit space.yaml\n")
    return {"multimodel": mm_path, "space": space_path}


def steering_source(multimodel: MultiModel, vehicle: str) -> str:
    """The output that drives the vehicle's steering input, as recorded in trajectories."""
    for source, targets in multimodel.connections.items():
        if f"{vehicle}.delta_f" in targets:
            return source
    raise DseError(f"diagnosis needs a connection into {vehicle}.delta_f (the steering command)")


def _locate(space: Space, vehicle: str, tracks: dict[str, Any]) -> Any:
    import pandas as pd

    signals = locate.Signals(f"{vehicle}.gps_x", f"{vehicle}.gps_y", f"{vehicle}.theta", f"{vehicle}.vx",
                             f"{vehicle}.yaw_rate", steering_source(space.multimodel, vehicle))
    return pd.concat([locate.residual_frame(tracks[s.name], s, signals) for s in space.scenarios],
                     ignore_index=True)


def seek(chain: Chain, reference: Candidate, candidates: list[Candidate], floor: NoiseFloor, space: Space
         ) -> discover.Discovery | None:
    """Discovery (discover.py) on top of the library's answer, only when that answer leaves held-out error
    above ``noise_factor`` noise floors: below it there is nothing a correction could claim but noise.
    Without a floor nothing counts as above it, so nothing is sought."""
    settings = chain.settings
    if not (floor.available and explain.above_floor(reference.cross_validated, floor.cross_track,
                                                    settings.noise_factor)):
        return None
    chain.say(f"the library leaves {reference.cross_validated:.4f} m held-out "
              f"({reference.cross_validated / floor.cross_track:.1f}x the noise floor): seeking a correction")
    runs = [discover.observe(s) for s in space.scenarios]
    found = discover.discover(chain, reference, candidates, runs, space.multimodel.parameters)
    if found.chosen is not None:
        found.resembles = discover.resembles(chain, found.chosen)
        chain.say(f"discovered {'; '.join(correction.readable(found.chosen.full.point))}: held-out "
                  f"{reference.cross_validated:.4f} -> {found.chosen.cross_validated:.4f} m")
    else:
        chain.say(f"nothing discovered: {found.reason}")
    return found


def diagnose(scenarios: str | Path, multimodel: str | Path | None = None, space: str | Path | None = None,
             out: str | Path | None = None, settings: Settings = Settings(), client=None,
             progress: Progress | None = None, n_workers: int | None = None,
             address: str | None = None) -> Diagnosis:
    """Calibrate -> locate -> explain -> model -> re-calibrate on a folder of recorded runs.

    ``space`` gives the calibration's parameters and ranges (default: the bundled Robotti
    calibration, bundled:robotti/calibration.yaml); ``multimodel`` replaces its multi-model."""
    out = Path(out or "out/diagnosis").resolve()
    settings.singles()  # an unknown hypothesis is named before anything runs
    calibration = calibration_space(space or DEFAULT_SPACE, scenarios, multimodel, out, n_workers, address)
    say = progress or (lambda message: None)
    if client is None:
        with connect(calibration.spec.cluster, calibration.path.parent) as own:
            return _diagnose(calibration, out, settings, own, say)
    return _diagnose(calibration, out, settings, client, say)


def _diagnose(calibration: Space, out: Path, settings: Settings, client, say: Progress) -> Diagnosis:
    from . import report

    floor = noise.estimate_noise(calibration.scenarios)  # from the files alone, before any model is fitted
    if floor.available:
        say(f"noise floor: GPS sigma {floor.sigma:.4f} m ({floor.method}, {floor.fixes} fixes), "
            f"{floor.cross_track:.4f} m of cross-track error")
    say(f"calibrating: the {calibration.name} grid on {len(calibration.scenarios)} runs")
    submit(calibration, client=client)
    grid = rank(out, calibration.name)
    vehicle = vehicle_of(calibration)
    base = base_parameters(calibration, grid.best)
    space = fits_space(calibration, vehicle, out)
    chain = Chain(space, vehicle, base, client, settings, say)
    choice = choose(chain, {p.name: p.start for p in base}, floor.cross_track if floor.available else None)
    baseline = next(c for c in choice.candidates if not c.ids)
    chosen, looks = lookalike.weigh(choice.chosen, choice.candidates, baseline, space.scenarios,
                                    floor.sigma if floor.available else None, settings.min_gain, settings.bic_margin)
    found = seek(chain, chosen, choice.candidates, floor, space) if settings.discovery else None
    if found is not None and found.chosen is not None:
        chosen = found.chosen
    diagnosis = Diagnosis(out, {
        "sweep": calibration.name, "vehicle": vehicle, "grid_best": grid.best,
        "grid_at_bound": [p.name for p in base if grid.best[p.name] in (p.lower, p.upper)
                          and p.name not in baseline.full.undetermined],
        "refined": baseline.full.values, "refined_at_bound": baseline.full.at_bound,
        "no_effect": baseline.full.undetermined,
        "insensitive_scenarios": locate.insensitive_scenarios(grid.table1),
        "folds": chain.folds,
    }, explain.ranked(choice.candidates + (found.candidates if found else [])), chosen, baseline, settings,
        dropouts=dropouts(calibration.scenarios), floor=floor, screened=choice.screened,
        shortlisted=[x.label for x in choice.shortlisted], lookalikes=looks, discovery=found)
    say("locating: the residuals of the calibrated model and of the chosen one")
    before = trajectories_of(space, client, baseline.full.point, BEFORE)
    lookalike.attach_responses(looks, space.scenarios, before, {"heading": f"{vehicle}.theta", "vx": f"{vehicle}.vx",
                                                                "vy": f"{vehicle}.vy"})
    after = trajectories_of(space, client, chosen.full.point, AFTER)
    frames = {"before": _locate(space, vehicle, before), "after": _locate(space, vehicle, after)}
    diagnosis.files.update(write_model(diagnosis, calibration))
    diagnosis.files.update(report.write(diagnosis, space, frames, before, after))
    return diagnosis
