"""Diagnosis for any model with recordings: which effects outside the model, and which physical terms
inside it, the recordings support.

Why: a user with an FMU and recordings, and no hypothesis library of their own, still wants to know
whether what the model misses is a late, sluggish, scaled or biased input or sensor, a limit of a state,
or a law its equations leave out (a spring that hardens, dry friction, a leak). The signal effects and
state limits (signal_hypotheses.py) act outside any FMU; the terms (term_hypotheses.py) are added to a
model-exchange FMU's state derivatives by the master that integrates it.

The space says everything: its scenarios give the inputs and recordings, its objectives
``{signal, recorded, metric}`` what is compared, its parameters the calibration. Each hypothesis is fitted
jointly with the calibrated parameters by simulating the whole model (fit.py's Levenberg-Marquardt, every
round a sweep), judged as the field-data diagnosis judges its library (explain.py): held-out error, the
BIC (charged for the search among terms), the simplest of the equally good, a verdict against the noise
floor. Residuals of each compared signal are divided by its noise (estimated from its recording alone), so
signals in different units weigh alike and an error of 1 is the noise itself.

The stages, in diagnose_space's order: calibrate (from many starts), fit every single, screen combinations
(screens/, the mixed screen unless asked for another), cross-validate, grow (choice.py), recalibrate the
answer with its effects in place, decide each member against its look-alike across the model's skin, the
answer against the sets that fit alike (the engine's look-alike rule, lookalike.py), the noise rule and the
limits the recordings reach (signal_claims.py), prove the answer's terms by choosing them again on each fold;
then locate (signal_locate.py) and report (the engine's report.py, with signal_report.py's sections).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import DseError
from ...simulation import objectives as objs
from ...simulation import signal_effects, state_limits
from ...simulation.run import qualify
from ...sweeps.cluster import connect
from ...sweeps.expand import key_of
from ...sweeps.fit import FitProblem, FitResult, Parameter
from ...sweeps.fit_rounds import evaluate_points, fit_all
from ...sweeps.spec import Space, derived_space
from . import answer as answer_
from . import explain, lookalike, screens, signal_claims, signal_figures, signal_locate, signal_report
from .calibration import held_at, parameters_at, searched
from .choice import choose, screen_of
from .derivatives import model_exchange_instances, observe
from .engine import (
    REFITTED,
    Fits,
    best_of,
    fitted_set,
    held_to_proof,
    joining,
    judge_members,
    proven,
    recalibrated,
    restarts,
)
from .explain import Candidate
from .fitter import MAX_ITERATIONS, label, round_report
from .hypotheses import EffectParameter
from .hypotheses import Hypothesis as LibraryHypothesis
from .library import HypothesisLibrary, Messages, Request, space_with
from .noise import NoiseEstimate, Whiteness, estimate_noise, whiteness
from .one_thread import one_thread
from .outcome import Outcome
from .proof import Proof, honest
from .report import Section
from .signal_hypotheses import PHYSICS, SignalHypothesis, shares, signal_hypotheses, state_hypotheses
from .term_hypotheses import readable as term_readable
from .term_hypotheses import rivals, shown, term_hypotheses, term_names
from .validation import validated

FITS = "diagnosis-signal-fits"  # the sweep every fit's rounds go to
CALIBRATION_FITS = "diagnosis-calibration"  # the sweep the calibration's least squares goes to
DIFFERENCE = 0.001  # a calibrated parameter's finite-difference step, as a share of its range: over a long
# record of an oscillation a step of a percent moves the phase by a good part of a cycle, and the Jacobian
# it measures is no slope at all
SCREEN = "mixed"  # the combination screen this library runs unless asked for another (screens/registry.py)


@dataclass(frozen=True)
class Compared:
    """One signal an objective compares with a recording, and the noise in that recording."""

    objective: str
    signal: str
    recorded: str
    noise: float  # σ of the recording's noise, in the signal's units (the median over the scenarios)
    estimate: NoiseEstimate | None = (
        None  # how the scenario nearest that median was estimated, and what it assumes
    )

    @property
    def residuals(self) -> str:
        return f"{self.objective}__residuals"


@dataclass
class SignalDiagnosis(Outcome):
    """What the library of signal effects explains of the mismatch between a space's model and recordings
    (the engine's Outcome), judged in noise floors: each compared signal's residuals over its noise."""

    library_name = "signals"
    held_out_unit = "noise floors (RMS of each compared signal's residuals over its recording's noise)"

    compared: list[Compared]
    verdict: str
    verdict_text: str = ""
    hypotheses: dict[str, SignalHypothesis] = field(default_factory=dict)
    noise_factor: float = explain.NOISE_FACTOR  # held-out error above this many floors is unexplained
    decided: list[Decided] = field(default_factory=list)  # members against their look-alikes across the skin
    proof: Proof | None = None  # the terms inside the model chosen again on each fold
    figures: list[str] = field(
        default_factory=list
    )  # recorded against simulated, per compared signal and run
    whiteness: dict[str, Whiteness] = field(
        default_factory=dict
    )  # the chosen fit's residuals, per compared signal

    def interval(self, fit: FitResult) -> dict[str, tuple[float, float]]:
        """At least as wide as the residuals' serial correlation makes them: a signal's samples are no
        independent draws (FitResult.interval)."""
        return fit.interval(serial=True)

    @property
    def calibrated(self) -> answer_.Fitted:
        """The model before, as calibrated: its values, with no interval quoted."""
        return answer_.Fitted(
            parameters=dict(self.baseline.full.values), at_bound=list(self.baseline.full.at_bound)
        )

    def noise_floor_entry(self) -> answer_.NoiseFloor:
        return answer_.NoiseFloor(
            held_out=1.0,  # residuals are divided by each recording's noise
            factor=self.noise_factor,
            ratio=self.held_out_after,
            method="each compared signal's noise, estimated from its recording alone",
            details={c.signal: c.noise for c in self.compared},
        )

    def effect_entries(self) -> list[answer_.Effect]:
        return [self._effect(name) for name in self.chosen.ids] or [
            answer_.nothing_missing(
                "no effect or term: what is left is the recordings' noise, or unexplained"
            )
        ]

    def written(self) -> dict[str, Any]:
        """The files, and the figures of recorded against simulated per compared signal and run."""
        return {**super().written(), "figures": self.figures} if self.files else {}

    def case_fields(self) -> dict[str, Any]:
        """The signals compared and their noise, whether the answer's residuals are white, the members
        decided against their look-alikes across the model's skin, and where the misfit lies."""
        return {
            "compared": [
                {
                    "objective": c.objective,
                    "signal": c.signal,
                    "recorded": c.recorded,
                    "noise": c.noise,
                    "noise_estimate": c.estimate.to_json() if c.estimate else None,
                }
                for c in self.compared
            ],
            "whiteness": {signal: w.to_json() for signal, w in self.whiteness.items()},
            "decided": [d.to_json() for d in self.decided],
            "located": self.located,
        }

    def _effect(self, name: str) -> answer_.Effect:
        hypothesis, fit = self.hypotheses[name], self.chosen.full
        values, intervals = {}, {}
        for kind, parameter in zip(hypothesis.kinds, hypothesis.parameters):
            value, (low, high) = fit.values[parameter.name], self.interval(fit)[parameter.name]
            if parameter is hypothesis.parameters[0]:  # its resolution widens the interval
                low, high = min(low, value - hypothesis.resolution), max(high, value + hypothesis.resolution)
            values[kind], intervals[kind] = value, [low, high]
        term = hypothesis.term
        return answer_.Effect(
            id=hypothesis.id,
            name=hypothesis.physics[0],
            parameters=values,
            interval=intervals,
            partial=self.verdict == explain.PARTIAL,
            # pinned at an end of its range: the data push it past, so the value is no estimate
            at_bound=[k for k, p in zip(hypothesis.kinds, hypothesis.parameters) if p.name in fit.at_bound],
            hypothesis=name,  # as candidates, dropped and decided name it
            target=hypothesis.target,
            into=hypothesis.into,
            resolution=hypothesis.resolution,
            term=shown(term) if term is not None else None,  # a term inside the model: what it is and means
            law=hypothesis.law or None,
            readable=[term_readable(term, fit.values)] if term is not None else [],
        )

    def summary(self) -> list[str]:
        """The effects named, the held-out error before and after, and the verdict, as the CLI prints them."""
        found = self.to_json()
        lines = []
        for effect in found["effects"]:
            if effect["id"] == answer_.NONE:
                continue  # the verdict says what nothing named means
            if effect["readable"]:  # a term inside the model, and its coefficient's interval
                low, high = effect["interval"]["coefficient"]
                lines.append(f"{effect['readable'][0]} (coefficient 95 % {low:.4g} to {high:.4g})")
                continue
            told = [
                f"{kind} {value:.4g} (95 % {effect['interval'][kind][0]:.4g} "
                f"to {effect['interval'][kind][1]:.4g})"
                for kind, value in effect["parameters"].items()
            ]
            into = f" into {effect['into']}" if effect.get("into") else ""
            lines.append(f"{effect['id']}({effect['target']}){into}: {', '.join(told)}")
        alone = (found.get("calibrated") or {}).get("parameters") or {}
        fitted = (found.get("fitted") or {}).get("parameters") or {}
        together = {name: value for name, value in fitted.items() if name in alone}
        if alone:  # what the missing physics did to the calibration: it bent the parameters to make up for it
            lines.append(
                "calibrated: "
                + ", ".join(f"{name} = {value:.4g}" for name, value in alone.items())
                + (
                    "; with the effects: " + ", ".join(f"{n} = {v:.4g}" for n, v in together.items())
                    if self.chosen.ids and together
                    else ""
                )
            )
        pinned = (found.get("fitted") or {}).get("at_bound") or []
        if pinned:
            lines.append(f"at a bound of its interval, not an estimate: {', '.join(pinned)}")
        judged = (
            "error on the samples fitted (nothing could be held out)"
            if (self.validation is not None and not self.validation.folds)
            else "held-out error"
        )
        lines.append(
            f"{judged}: {found['held_out_before']:.2f} before, {found['held_out_after']:.2f} after, "
            "in noise floors (each compared signal's residuals over its recording's noise)"
        )
        if self.validation is not None:
            lines.append(self.validation.text)
        lines.append(
            f"verdict: {found['verdict_text']}"
            + (f"; runner-up {found['runner_up']['id']}" if found["runner_up"] else "")
        )
        return lines + self.files_told(("report", "html", "values"))


def compared_signals(space: Space) -> list[Compared]:
    """Every signal an objective compares with a recording, once (a least-squares space compares one signal
    twice: its residuals and the sum of their squares), with the noise of that recording (the median over
    the scenarios that record it)."""
    found = []
    seen = set()
    for name, spec in space.objectives.items():
        if not isinstance(spec, objs.Fit) or (spec.signal, spec.recorded) in seen:
            continue
        seen.add((spec.signal, spec.recorded))
        estimates = [
            estimate_noise(s.recorded.samples(spec.recorded)[1]) for s in space.scenarios if s.recorded
        ]
        sigmas = [e.sigma for e in estimates]
        noise = float(np.nanmedian(sigmas)) if sigmas and np.isfinite(sigmas).any() else math.nan
        if not noise > 0:
            raise DseError(
                f"objective {name}: no noise could be estimated from the recorded {spec.recorded!r}"
            )
        typical = min(estimates, key=lambda e: abs(e.sigma - noise) if math.isfinite(e.sigma) else math.inf)
        found.append(Compared(name, qualify(space.plan, spec.signal), spec.recorded, noise, typical))
    if not found:
        raise DseError(
            f"{space.path}: diagnosis compares signals with recordings: give an objective "
            "{signal: inst.var, recorded: column, metric: rmse}"
        )
    return found


def library_of(
    space: Space, compared: Sequence[Compared], point: Mapping[str, Any] | None, terms: bool = True
) -> dict[str, SignalHypothesis]:
    """The hypotheses for ``space``: signal effects on its driven inputs and compared signals, and on its
    model-exchange instances state limits and physical terms inside their derivatives, ranged and sized
    over what the states do at ``point`` (the calibration's start; simulated here on every scenario).
    Without a point (a listing), every state's limits by name, and no terms (they are known once sized);
    nor without ``terms``."""
    found = signal_hypotheses(space, [(c.signal, c.recorded) for c in compared])
    instances = model_exchange_instances(space.plan)
    if not instances:
        return found
    if point is None:
        runs = [{f"{i.name}.{s}": np.array([0.0, 1.0]) for i in instances for s in i.states}]
        return {**found, **state_hypotheses({i.name: i.states for i in instances}, runs)}
    runs = observe(space, dict(point), instances)
    return {
        **found,
        **state_hypotheses({i.name: i.states for i in instances}, runs),
        **(term_hypotheses(instances, runs) if terms else {}),
    }


def restricted(found: dict[str, SignalHypothesis], only: Sequence[str]) -> dict[str, SignalHypothesis]:
    """The effects ``only`` names (all when it names none); an unknown name is an error listing them."""
    unknown = [name for name in only if name not in found]
    if unknown:
        raise DseError(
            f"--hypothesis {', '.join(unknown)}: not a signal effect of this space; it has {', '.join(found)}"
        )
    return {name: h for name, h in found.items() if not only or name in only}


def fits_space(
    space: Space, compared: Sequence[Compared], hypotheses: Mapping[str, SignalHypothesis], name: str = FITS
) -> Space:
    """The space the fits run in (its scenarios as they are: a record's blocks stay blocks): its own
    parameters and every effect's (each at its neutral value unless a fit frees it), scored by the residuals
    of each compared signal."""
    parameters = dict(space.spec.parameters)
    parameters.update({name: [value] for h in hypotheses.values() for name, value in h.absent().items()})
    objectives = {
        **space.objectives,
        **{c.residuals: objs.Fit(signal=c.signal, recorded=c.recorded, metric="residuals") for c in compared},
    }
    return derived_space(
        space,
        name=name,
        parameters=parameters,
        objectives=objectives,
        search=space.spec.search.model_copy(update={"strategy": "given"}),
        constraints=[],
        keep_trajectories=0,
    )


@one_thread
def diagnose_space(
    path: str | Path | Space,
    out: str | Path | None = None,
    folds: int = 3,
    noise_factor: float = explain.NOISE_FACTOR,
    say: Messages | None = None,
    n_workers: int | None = None,
    address: str | None = None,
    discover: bool = True,
    only: Sequence[str] = (),
    screen: str = SCREEN,
) -> SignalDiagnosis:
    """Calibrate the space (a file, or a Space as the library contract gives it), fit each hypothesis with
    it (``only`` these, when given): the signal effects and state limits, and the physical terms inside its
    model-exchange FMUs (unless not ``discover``); screen combinations (by the strategy ``screen`` names)
    when no single explains to the noise, grow the answer, keep what the recordings support and reach, decide
    each member against its look-alike across the model's skin, and locate the misfit before and after."""
    say = say or (lambda message: None)
    strategy = screens.strategy(screen)  # an unknown name is told before anything runs
    space = (
        path
        if isinstance(path, Space)
        else space_with(path, None, Path(out) if out else None, n_workers=n_workers, address=address)
    )
    compared = compared_signals(space)
    with connect(space.spec.cluster, space.path.parent) as client:
        f, space = calibrated_fits(space, compared, client, say, folds, discover, only)
        library, validation = f.library, f.validation
        choice = choose(f, strategy, strategy.shortlisted, 1.0, noise_factor)  # residuals in noise units
        baseline, everything, full, growth = choice.baseline, choice.everything, choice.full, choice.growth
        selected = recalibrated(f, choice.chosen, everything)
        judge_members(f, selected, everything)
        selected, decided = _decided(f, selected, full, everything)
        selected = _told_from_twins(f, selected, everything, baseline, compared)
        chosen, dropped = explain.claimed(selected, everything, baseline)
        chosen = _reached(f, chosen, everything, compared, dropped)
        proof = proven(f, chosen, full)
        chosen = held_to_proof(f, chosen, proof, everything, baseline, dropped)
        proof = proof if proof is not None and set(proof.terms) <= set(chosen.ids) else None
        decided = [
            d for d in decided if d.winner in chosen.ids
        ]  # a winner the rules then dropped is no answer
        floor = 1.0  # residuals are in units of each recording's noise
        inside = any(library[i].term is not None for i in chosen.ids)
        after = honest(chosen.cross_validated, proof)
        verdict = explain.verdict(after, floor, noise_factor, bool(chosen.ids), inside)
        interfaces = dict(space.plan.interfaces)
        twins = signal_claims.alike(chosen, everything)
        residuals = located_residuals(f.space, client, [baseline, chosen, *twins], compared, f.scenarios)
    noise = {c.signal: c.noise for c in compared}
    by_name = {s.name: s for s in space.scenarios}
    looks = [signal_claims.weigh(chosen, t, residuals, noise, by_name) for t in twins]
    located = signal_locate.located(residuals[baseline.label], residuals[chosen.label], noise, by_name)
    formulas = [term_readable(library[i].term, chosen.full.values) for i in chosen.ids if library[i].term]
    white = {
        c.signal: whiteness([r.values for r in residuals[chosen.label] if r.signal == c.signal])
        for c in compared
    }
    coloured = {signal: w for signal, w in white.items() if not w.white}
    verdict = explain.unless_white(verdict, not coloured)
    offered = any(h.term is not None for h in library.values())
    text = signal_claims.verdict_text(
        verdict,
        after,
        chosen,
        interfaces,
        looks,
        dropped,
        noise_factor,
        formulas,
        coloured,
        offered,
    )
    diagnosis = SignalDiagnosis(
        compared,
        verdict,
        verdict_text=text,
        hypotheses=library,
        noise_factor=noise_factor,
        baseline=baseline,
        chosen=chosen,
        candidates=everything,
        space=space.name,
        screen=screen_of(choice),
        growth=growth,
        validation=validation,
        whiteness=white,
        lookalikes=looks,
        decided=decided,
        proof=proof,
        dropped=dropped,
        located=located,
    )
    figures = signal_figures.draw(
        residuals[baseline.label],
        residuals[chosen.label],
        by_name,
        {c.signal: c.recorded for c in compared},
        located.get("worst", []),
        Path(space.output),
    )
    diagnosis.files, diagnosis.figures = signal_report.files_in(Path(space.output)), [str(f) for f in figures]
    signal_report.write(diagnosis.answer())
    return diagnosis


def calibrated_fits(
    space: Space,
    compared: Sequence[Compared],
    client,
    say: Messages,
    folds: int = 3,
    discover: bool = True,
    only: Sequence[str] = (),
) -> tuple[Fits, Space]:
    """The engine's fits of this library on ``space``: the calibration (from many starts), the hypotheses
    sized at its point (``only`` these, when given; no terms unless ``discover``), what is held out; and
    ``space`` as validated (a record's blocks among its scenarios)."""
    base, held = _calibrated(space, compared, client, say)
    start = {**held, **{p.name: p.start for p in base}}
    library = restricted(library_of(space, compared, start, terms=discover), only)
    space, validation = validated(space, folds, sorted({c.recorded for c in compared}))
    say(f"validation: {validation.text}")
    # what a fit does not free: the space's single-valued parameters, and every other effect at neutral
    unfreed = {**held, **{k: v for h in library.values() for k, v in h.absent().items()}}
    scales = {c.residuals: 1.0 / c.noise for c in compared}
    fits = Fits(
        space=fits_space(space, compared, library),
        client=client,
        base=base,
        parameters=lambda h: library[h].parameters,
        unfreed=unfreed,
        validation=validation,
        residuals=scales,
        scored=list(scales),
        score=lambda row: scaled_rms(row, scales),
        say=say,
        library=library,
        shares=lambda a, b: shares(library[a], library[b]),
    )
    return fits, space


def _calibrated(
    space: Space, compared: Sequence[Compared], client, say: Messages
) -> tuple[tuple[Parameter, ...], dict[str, Any]]:
    """Where every effect's fit starts: the space's calibration (its own search's best point, refined by
    least squares), and the parameters least squares does not refine, held where the search put them."""
    ranking = searched(space, client, say)
    best = ranking.best if ranking is not None else {}
    base = parameters_at(space, best, DIFFERENCE)
    calibrated = {p.name for p in base}
    held = {k: v for k, v in held_at(space, best).items() if k not in calibrated}
    if base:
        say("calibrating: least squares from the best point")
        plain = fits_space(space, compared, {}, CALIBRATION_FITS)
        names = tuple(s.name for s in space.scenarios)
        scales = {c.residuals: 1.0 / c.noise for c in compared}
        problem = FitProblem("calibration", base, held, names, MAX_ITERATIONS)
        refined = fit_all(plain, [problem], client, scales, round_report(say))["calibration"]
        if refined.error is None:
            # from the designs around it too: every hypothesis is judged against this model at its best, so
            # that none wins only by shaking a stuck calibration loose (a gain standing in for a mass)
            points = restarts(base, refined.point)
            say(f"calibrating: {len(points)} more starts, the best {REFITTED} fitted")

            def problem_at(tag: str, start: Mapping[str, float], iterations: int) -> FitProblem:
                starts = tuple(replace(p, start=start[p.name]) for p in base)
                return FitProblem(f"calibration{tag}", starts, held, names, iterations)

            again = best_of(plain, client, scales, points, problem_at, names, say)
            refined = again if again.sse < refined.sse else refined
            base = tuple(replace(p, start=refined.values[p.name]) for p in base)
    return base, held


@dataclass(frozen=True)
class Decided:
    """A member of the answer against its look-alike on the other side of the model's skin (an input's dead
    zone against dry friction): both fitted with the rest of the answer and cross-validated; the loser is
    named a look-alike, with both held-out errors."""

    member: str
    rival: str
    held_out: tuple[float, float]  # the answer with the member, and with the rival in its place
    winner: str

    def to_json(self) -> dict[str, Any]:
        loser = self.rival if self.winner == self.member else self.member
        return {
            "member": self.member,
            "rival": self.rival,
            "held_out": {self.member: self.held_out[0], self.rival: self.held_out[1]},
            "winner": self.winner,
            "lookalike": loser,
        }


def _decided(
    f: Fits, chosen: Candidate, full: Mapping[tuple[str, ...], FitResult], everything: list[Candidate]
) -> tuple[Candidate, list[Decided]]:
    """Each member of ``chosen`` that has a look-alike across the model's skin (term_hypotheses.rivals)
    against the best of them by its single fit: the answer with the rival in the member's place, fitted from
    the answer's fit and cross-validated. The rival takes the place if it beats the answer (explain.beats);
    the answer, and what was decided."""
    decided: list[Decided] = []
    if not f.parts:
        return chosen, decided
    for member in list(chosen.ids):
        options = [r for r in rivals(member, f.library) if r not in chosen.ids and (r,) in full]
        options = [r for r in options if not any(shares(f.library[r], f.library[i]) for i in chosen.ids)]
        if not options or member not in chosen.ids:
            continue
        rival = min(options, key=lambda r: explain.bic(full[(r,)]))
        ids = tuple(sorted((*(i for i in chosen.ids if i != member), rival)))
        known = fitted_set(everything, ids)
        if known is None:
            f.say(f"deciding {member} against its look-alike {rival}")
            start = {**chosen.full.values, **joining(f, full, rival)}
            fit = f.fit([f.problem(label(ids), ids, f.scenarios, start)])[label(ids)]
            known = f.candidate(ids, fit)
            f.hold_out([known], f.fit(f.by_fold(ids, fit.values)))
            everything.append(known)
        wins = explain.beats(known, chosen)
        decided.append(
            Decided(member, rival, (chosen.cross_validated, known.cross_validated), rival if wins else member)
        )
        if wins:
            chosen = known
    if any(d.winner != d.member for d in decided):
        judge_members(f, chosen, everything)  # the noise rule weighs the rival as it weighed the member
    return chosen, decided


def _told_from_twins(
    f: Fits, chosen: Candidate, everything: list[Candidate], baseline: Candidate, compared: Sequence[Compared]
) -> Candidate:
    """The engine's rule between the answer and each set that fits alike (signal_claims.alike): where
    held-out error and BIC cannot separate them and the LLR between their residuals can, the LLR's favourite
    is the answer, if it could be chosen at all (lookalike.weigh). The residuals are read, not simulated."""
    twins = signal_claims.alike(chosen, everything)
    if not twins:
        return chosen
    residuals = located_residuals(f.space, f.client, [chosen, *twins], compared, f.scenarios)
    noise = {c.signal: c.noise for c in compared}
    segments = signal_claims.segments(residuals, noise, {s.name: s for s in f.space.scenarios})
    answer, looks = lookalike.weigh(chosen, [(chosen, t) for t in twins], everything, baseline, segments, 1.0)
    for look in looks:
        f.say(
            f"look-alikes: {look.pair[0]} against {look.pair[1]}, "
            f"LLR {look.evidence.llr:+.1f}: {look.decision}"
        )
    if answer is not chosen:
        f.say(
            f"look-alikes: {answer.label} rather than {chosen.label}, "
            "as the LLR between their residuals decides"
        )
    return answer


def _reached(
    f: Fits,
    chosen: Candidate,
    everything: Sequence[Candidate],
    compared: Sequence[Compared],
    dropped: list[explain.Dropped],
) -> Candidate:
    """``chosen`` without the limits the recordings never reach (signal_claims.unreached), one at a time, each
    into ``dropped`` with its reason, while the set without it was fitted and cross-validated (judged)."""
    noise = {c.signal: c.noise for c in compared}
    recorded = {
        c.signal: {s.name: _recorded_after_start(s, c.recorded) for s in f.space.scenarios if s.recorded}
        for c in compared
    }
    while chosen.ids:
        shown = located_residuals(f.space, f.client, [chosen], compared, f.scenarios)[chosen.label]
        reasons = signal_claims.unreached(chosen, f.library, shown, recorded, noise)
        rest = next(
            (
                found
                for member in reasons
                if (found := fitted_set(everything, [i for i in chosen.ids if i != member])) is not None
            ),
            None,
        )
        if rest is None:
            return chosen
        member = next(iter(set(chosen.ids) - set(rest.ids)))
        f.say(f"not claimed: {member}: {reasons[member]}")
        dropped.append(explain.Dropped(member, math.nan, reasons[member]))
        chosen = rest
    return chosen


def _recorded_after_start(scenario, column: str) -> np.ndarray:
    """A recorded column's values from the run's start on: the samples its residuals are taken at."""
    t, values = scenario.recorded.samples(column)
    return np.asarray(values, float)[t >= (scenario.start_time or 0.0) - 1e-9]


def located_residuals(
    space: Space, client, shown: Sequence[Candidate], compared: Sequence[Compared], fitted: Sequence[str]
) -> dict[str, list[signal_locate.Residual]]:
    """Each shown candidate's residuals (in the signals' units) per compared signal and run it was ``fitted``
    on, from its fit on every run: already in the store, so read rather than simulated again."""
    points = [c.full.point for c in shown]
    rows, _ = evaluate_points(
        space, points, client, [c.residuals for c in compared], [set(fitted)] * len(points)
    )
    scenarios = {s.name: s for s in space.scenarios if s.name in fitted}
    found: dict[str, list[signal_locate.Residual]] = {}
    for candidate in shown:
        found[candidate.label] = []
        for name, scenario in scenarios.items():
            row = rows.get((key_of(candidate.full.point), name))
            if row is None or row["status"] != "ok":
                continue
            for c in compared:
                values = np.asarray(row[c.residuals], dtype=float)
                found[candidate.label].append(
                    signal_locate.Residual(
                        c.signal,
                        name,
                        signal_locate.residual_times(scenario, c.recorded, values.size),
                        values,
                    )
                )
    return found


def scaled_rms(row: Mapping[str, Any] | None, scales: Mapping[str, float]) -> float:
    """The RMS of a run's residuals, each column times its scale (noise floors); infinite for a run that
    failed or was never made."""
    if row is None or row["status"] != "ok":
        return math.inf
    r = np.concatenate([np.asarray(row[col], float) * scale for col, scale in scales.items()])
    return float(np.sqrt(np.mean(r**2))) if r.size else math.inf


class SignalEffects(HypothesisLibrary):
    """The built-in library: every signal effect on every driven input and compared output, for any FMU."""

    name = SignalDiagnosis.library_name
    general = True
    screen = SCREEN

    def serves(self, space: Space) -> bool:
        return any(isinstance(spec, objs.Fit) for spec in space.objectives.values())

    def diagnose(self, space: Space, request: Request, say: Messages) -> SignalDiagnosis:
        return diagnose_space(
            space,
            folds=request.folds,
            noise_factor=request.noise_factor,
            say=say,
            discover=request.discovery,
            only=request.hypotheses,
            screen=self.screen_for(request),
        )

    def sections(self, answer: answer_.Answer) -> list[Section]:
        return signal_report.sections(answer)

    def hypotheses(self, space: Space) -> list[LibraryHypothesis]:
        """Every hypothesis by name; a state limit's range is known only once the calibrated model has run,
        and a term's range (and whether its derivative is physics at all) once the runs size it."""
        units = {**signal_effects.UNITS, **state_limits.UNITS}
        effects = [
            LibraryHypothesis(
                id=name,
                name=f"{h.id.replace('_', ' ')} of {h.target}" + (f" into {h.into}" if h.into else ""),
                explanation=h.physics[0],
                signature=h.physics[1],
                parameters=tuple(
                    EffectParameter(
                        variable=p.name, unit=units[kind], lower=p.lower, upper=p.upper, step=p.step
                    )
                    for kind, p in zip(h.kinds, h.parameters)
                ),
            )
            for name, h in library_of(space, compared_signals(space), None).items()
        ]
        terms = [
            LibraryHypothesis(
                id=name,
                name=f"a {law} term: {name}",
                explanation=PHYSICS[f"term_{law}"][0],
                signature=PHYSICS[f"term_{law}"][1],
            )
            for instance in model_exchange_instances(space.plan)
            for name, law in term_names(instance).items()
        ]
        return effects + terms
