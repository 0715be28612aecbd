"""Look-alikes: telling twin effects apart by where their fits differ, not by luck.

Some effects leave nearly the same residual on ordinary manoeuvres (hypotheses.LOOK_ALIKES): a
delay of every command and a steering lag both turn the vehicle late; slip and a speed lag both
put it behind. Held-out error and BIC then differ by little, and whichever wins does so by the
noise of the draw. What separates them is *where* their fits differ: a delay shifts the answer
to a steering step with its full size, a first-order lag rounds it off; slip leaves a steady
deficit while cruising, a lag none at all once the speed has settled; a delay of every command
also shows at every speed change, a steering lag does not.

So both twins' sets are fitted in full (the screen shortlists twin swaps), and the engine weighs
their fix residuals (analysis/diagnose/lookalike.py: which sets are twins by a swap of
hypotheses.LOOK_ALIKES, the LLR per segment, the autocorrelation time, the rule that decides). This module
supplies what only the Robotti knows: that a fix's x and y offsets add into one sample, the segment of each
fix (segments.py, from the command log alone), the manoeuvre that would tell a pair apart, and the forms of
the answer to a command each twin gives.

The engine's response fit (analysis/diagnose/response.py) explains the verdict in a control engineer's
terms, at no cost in simulations: the recorded course or speed (kinematics.py, from the fixes), per segment
kind, fitted against the calibrated model's own as a pure delay, a first-order lag and a gain. What it
needs of the Robotti is how GPS sees the model's signal (:class:`SignalAtFixes`: the kinematics window at
the fixes).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ...analysis.diagnose import explain
from ...analysis.diagnose import lookalike as engine
from ...analysis.diagnose.explain import Candidate
from ...analysis.diagnose.lookalike import DECISIVE
from ...analysis.diagnose.response import ResponseFit, form_llr, response_fit
from ...simulation.scenario import Scenario
from .. import fielddata
from . import kinematics, segments
from .hypotheses import LOOK_ALIKES

COURSE, SPEED = "course", "speed"  # the recorded channels a response fit compares


@dataclass(frozen=True)
class Telling:
    """What separates a pair of twins: the recorded channel in which they differ, the segment kinds
    where they differ most, and the manoeuvre to ask for when the runs have too little of it."""

    channel: str  # COURSE or SPEED
    kinds: tuple[str, ...]
    advice: str


# From the table of docs/research/diagnosis-beyond-library.md §2.4: a delay against a lag shows
# in the shape of the answer to a step; slip (a gain) against a speed lag (a phase) in the
# steady state after a speed change.
TELLING: dict[frozenset[str], Telling] = {
    frozenset({"steering_lag", "time_offset"}): Telling(
        COURSE, (segments.STEER_STEP, segments.SPEED_STEP), "a run with steering steps"
    ),
    frozenset({"wheel_slip", "speed_lag"}): Telling(
        SPEED, (segments.SPEED_STEP, segments.CRUISE), "a run with speed steps, each held for several seconds"
    ),
    frozenset({"time_offset", "speed_lag"}): Telling(
        SPEED, (segments.SPEED_STEP, segments.STEER_STEP), "a run with speed steps and steering steps"
    ),
}
FALLBACK = Telling(COURSE, (segments.STEER_STEP, segments.SPEED_STEP), "a run with steering and speed steps")


# The form each twin gives the answer to a command, in response.FORMS' terms.
FORMS = {"steering_lag": "lag", "time_offset": "delay", "speed_lag": "lag", "wheel_slip": "gain"}
MOVING_KINDS = tuple(k for k in segments.KINDS if k != segments.REST)  # a standing vehicle has no response


def telling(a: str, b: str) -> Telling:
    return TELLING.get(frozenset({a, b}), FALLBACK)


# ---- the evidence ----------------------------------------------------------------------------------


def fix_times(scenario: Scenario, count: int) -> np.ndarray:
    """The times of the first ``count`` fixes within the simulated span: those a fit's residuals are at
    (fielddata.fix_residuals: every fix from the start of the simulation on)."""
    t = fielddata.gps(scenario).time
    return t[t >= scenario.start_time - 1e-9][:count]


def fix_segments(scenarios: Sequence[Scenario]) -> engine.Segments:
    """The runs' fix residuals as the engine weighs them: per run one piece, a fix's x and y offsets (the
    two halves of fielddata.fix_residuals) adding into one sample, labelled by the segment kind it lies in."""
    labels = {s.name: segments.of_scenario(s) for s in scenarios}

    def pieces(candidate: Candidate) -> list[engine.Piece] | None:
        if len(candidate.full.residuals) != len(scenarios):
            return None  # fitted on other runs than these
        return [
            (r.reshape(2, -1), segments.kinds_at(labels[s.name], fix_times(s, len(r) // 2)))
            for s, r in zip(scenarios, candidate.full.residuals)
        ]

    return engine.Segments(pieces, segments.KINDS, "fixes")


# ---- the response, as a control engineer reads it -----------------------------------------------


@dataclass(frozen=True)
class SignalAtFixes:
    """One run's recorded signal at its fixes and the model's same signal on the model's grid, with
    the kinematics operator that turns the model's into what GPS would show (a response.Channel)."""

    fix_time: np.ndarray
    recorded: np.ndarray  # NaN where kinematics had too few fixes
    kinds: np.ndarray  # segment kind per fix
    operator: Any  # kinematics.derivative_operator: an array, or sparse with NaN rows as 0
    order: int  # how often the model signal is integrated before the operator applies
    model_time: np.ndarray  # uniform
    model: np.ndarray
    free_offset: bool = False  # compare about each run's mean difference (a course, known up to a constant)
    valid: np.ndarray | None = (
        None  # rows of ``operator`` that are estimates (None: every row that is finite)
    )

    def seen(self, model: np.ndarray) -> np.ndarray:
        """A model signal (on ``model_time``) as GPS would show it at the fixes: through the same kinematics
        window as the recorded one; NaN where the window has no estimate."""
        seen = kinematics.smoothed_like(self.operator, self.order, self.model_time, model, self.fix_time)
        return seen if self.valid is None else np.where(self.valid, seen, np.nan)


def sparse_operator(operator: np.ndarray) -> tuple[Any, np.ndarray]:
    """A local operator as a sparse matrix (each row touches a window's fixes only, so the hundreds of
    evaluations of a response fit cost little) and the mask of its rows that are estimates."""
    from scipy.sparse import csr_matrix

    valid = np.isfinite(operator).all(axis=1)
    return csr_matrix(np.where(valid[:, None], operator, 0.0)), valid


def model_signal(track: Any, name: str, columns: Mapping[str, str]) -> np.ndarray:
    """The model's ``name`` as GPS sees it at the reference point: ``course``, the heading plus the sideslip
    atan2(vy, vx) (it jumps with the steering, before the heading turns), unwrapped; ``speed``, the speed
    over ground. ``columns`` names the track's ``heading``, ``vx`` and ``vy`` (body frame)."""
    vx, vy = track[columns["vx"]].to_numpy(float), track[columns["vy"]].to_numpy(float)
    if name == COURSE:
        return np.unwrap(track[columns["heading"]].to_numpy(float) + np.arctan2(vy, vx))
    return np.hypot(vx, vy)


def channels_of(
    scenarios: Sequence[Scenario],
    tracks: Mapping[str, Any],
    columns: Mapping[str, str],
    name: str,
    labels: Mapping[str, Any],
) -> list[SignalAtFixes]:
    """Each run's recorded ``name`` (COURSE where the vehicle moves faster than kinematics.MIN_SPEED, or
    SPEED) beside the model's (:func:`model_signal` of its track in ``tracks``), with the fixes' segment
    kinds from ``labels`` (segments per run). A course, differentiated once from the fixes, shows the shape
    of a steering step; a yaw rate, differentiated twice, is mostly noise at 2 cm."""
    out = []
    for s in scenarios:
        if s.name not in tracks:
            continue
        fixes = fielddata.gps(s)
        kin = kinematics.gps_kinematics(fixes.time, fixes.x, fixes.y)
        velocity = kinematics.derivative_operator(fixes.time, kinematics.VELOCITY_WINDOW, 1, 1)
        recorded = (
            np.where(kin.speed >= kinematics.MIN_SPEED, kin.course, np.nan) if name == COURSE else kin.speed
        )
        track = tracks[s.name]
        model_time = track["time"].to_numpy(float)
        recorded = np.where(fixes.time <= model_time[-1] + 1e-9, recorded, np.nan)
        operator, valid = sparse_operator(velocity)
        out.append(
            SignalAtFixes(
                fixes.time,
                recorded,
                segments.kinds_at(labels[s.name], fixes.time),
                operator,
                1,
                model_time,
                model_signal(track, name, columns),
                free_offset=name == COURSE,
                valid=valid,
            )
        )
    return out


# ---- the verdict between twins ----------------------------------------------------------------------


@dataclass
class LookAlike(engine.Twins):
    """The engine's evidence between two twin sets (``members``: the look-alikes swapped between them), with
    what tells them apart (``telling``) and the response fits in that channel."""

    telling: Telling
    response: list[ResponseFit] = field(default_factory=list)
    sample: ClassVar[str] = "fixes"

    @property
    def shape(self) -> dict[str, Any]:
        """What the answer's shape alone says on the segments that tell these twins apart: which member's form
        (FORMS) fits the recorded channel better, by the LLR between the two forms (response.form_llr), or
        cannot_tell (below DECISIVE, or no such segment in these runs)."""
        forms = [FORMS.get(m, "") for m in self.members]
        fits = [r for r in self.response if r.kind in self.telling.kinds[:1]]
        if not fits or "" in forms or forms[0] == forms[1]:
            return {"segment": self.telling.kinds[0], "favours": None, "llr": 0.0, self.sample: 0}
        r = fits[0]
        llr = form_llr(r, *forms)
        favours = (self.members[0] if llr > 0 else self.members[1]) if abs(llr) >= DECISIVE else None
        return {"segment": r.kind, "favours": favours, "llr": llr, self.sample: r.samples}

    @property
    def telling_fixes(self) -> int:
        """Fixes in the segments that separate these twins best."""
        return sum(self.evidence.samples.get(k, 0) for k in self.telling.kinds)

    def to_json(self) -> dict[str, Any]:
        return {
            **super().to_json(),
            "telling_segments": list(self.telling.kinds),
            "telling_fixes": self.telling_fixes,
            "would_tell": self.telling.advice,
            "shape": self.shape,
            "response_fit": [r.to_json(self.sample) for r in self.response],
        }


def weigh(
    chosen: Candidate,
    candidates: Sequence[Candidate],
    baseline: Candidate,
    scenarios: Sequence[Scenario],
    sigma: float | None,
    min_gain: float = explain.MIN_GAIN,
    bic_margin: float = explain.BIC_MARGIN,
) -> tuple[Candidate, list[LookAlike]]:
    """The engine's weighing (lookalike.weigh: the LLR, and the answer where it decides) of each twin pair of
    the chosen set, on these runs' fixes. ``sigma``: the GPS noise per axis; without it, the better fit's
    own residual scatter."""
    answer, twins = engine.weigh(
        chosen,
        engine.twin_pairs(chosen, candidates, LOOK_ALIKES),
        candidates,
        baseline,
        fix_segments(scenarios),
        sigma,
        min_gain,
        bic_margin,
    )
    looks = [
        LookAlike(t.pair, t.members, t.evidence, t.decision, t.chosen, telling(*t.members)) for t in twins
    ]
    return answer, looks


def attach_responses(
    looks: Sequence[LookAlike],
    scenarios: Sequence[Scenario],
    tracks: Mapping[str, Any],
    columns: Mapping[str, str],
) -> None:
    """Each look-alike's response fit, in its telling channel, against the model whose ``tracks`` are given
    (the calibrated baseline: the model without either twin); ``columns`` names the tracks' ``heading``,
    ``vx`` and ``vy``."""
    labels = {s.name: segments.of_scenario(s) for s in scenarios}
    cache: dict[str, list[ResponseFit]] = {}
    for look in looks:
        name = look.telling.channel
        if name not in cache:
            channels = channels_of(scenarios, tracks, columns, name, labels)
            cache[name] = response_fit(channels, name, MOVING_KINDS)
        look.response = cache[name]
