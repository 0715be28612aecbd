"""A response's form: which of a pure delay, a first-order lag or a gain carries a model's signal onto a
recorded one.

Twin effects can leave nearly the same residual (lookalike.py weighs them), yet they answer a command in a
different form: a delay shifts the answer to a step with its full size, a first-order lag rounds it off, a
gain scales it. A control engineer tells them apart by fitting each form to the recording, per segment kind
(what the inputs did there), and asking which fits best. That costs no simulation: the model's own signal,
from the calibrated model without either twin, is transformed, not simulated again.

A library supplies what only it knows (:class:`Channel`): its recorded signal at its samples, and how the
model's signal would be *seen* there (a signal estimated from other measurements is seen through the
estimator's window, not as the model's instantaneous value; the model's signal goes through the same
window, so that the window's smoothing is not mistaken for a lag). The forms, their fits and the
log-likelihood ratio between two forms are the engine's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter, lfilter_zi

from . import explain

MAX_SHIFT = 2.0  # s: the longest delay or lag a response fit tries
SHIFT_GRID = 0.05  # s: the coarse search before the bounded refinement
GAINS = (0.5, 1.5, 0.02)  # the gains a response fit tries: from, to, coarse step
FORMS = ("delay", "lag", "gain")

Transform = Callable[..., np.ndarray]  # (model time, model signal, parameter) -> the signal transformed


class Channel(Protocol):
    """One run's recorded signal beside the model's, as a library lays it out. ``recorded`` and ``kinds``
    are per sample (NaN where the recording has no estimate; the segment kind each sample lies in);
    ``model`` is on ``model_time`` (uniform). ``free_offset``: compare about the run's mean difference (a
    signal known up to a constant). :meth:`seen` turns a model signal into what the recording
    would show at its samples (NaN where it would show nothing)."""

    recorded: np.ndarray
    kinds: np.ndarray
    model_time: np.ndarray
    model: np.ndarray
    free_offset: bool

    def seen(self, model: np.ndarray) -> np.ndarray: ...


def delayed(time: np.ndarray, signal: np.ndarray, delay: float) -> np.ndarray:
    """The signal ``delay`` seconds late, holding its first value before it starts."""
    return np.interp(time - delay, time, signal, left=signal[0])


def lagged(time: np.ndarray, signal: np.ndarray, tau: float) -> np.ndarray:
    """The signal through a first-order lag of time constant ``tau``, starting settled."""
    if tau <= 0:
        return np.asarray(signal, float)
    a = math.exp(-float(np.median(np.diff(time))) / tau)
    out, _ = lfilter([1.0 - a], [1.0, -a], signal, zi=lfilter_zi([1.0 - a], [1.0, -a]) * signal[0])
    return out


def _gained(time: np.ndarray, signal: np.ndarray, gain: float) -> np.ndarray:
    return gain * signal


def _sse(
    channels: Sequence[Channel], transform: Callable[[np.ndarray, np.ndarray], np.ndarray]
) -> dict[str, tuple[float, int]]:
    """Per segment kind: the SSE of the recorded signal against the model's, transformed and seen as the
    recording would see it, and how many samples count (both finite)."""
    out: dict[str, tuple[float, int]] = {}
    for c in channels:
        error = c.recorded - c.seen(transform(c.model_time, c.model))
        usable = np.isfinite(error)
        if c.free_offset and usable.any():
            error = error - np.mean(error[usable])
        for kind in np.unique(c.kinds[usable]):
            use = usable & (c.kinds == kind)
            sse, count = out.get(str(kind), (0.0, 0))
            out[str(kind)] = (sse + float(np.sum(error[use] ** 2)), count + int(use.sum()))
    return out


def _best(
    channels: Sequence[Channel], kinds: Sequence[str], transform: Transform, grid: np.ndarray
) -> dict[str, tuple[float, float]]:
    """Per kind, the transform's parameter on ``grid``'s span with the least SSE, and that SSE:
    a coarse grid shared by the kinds (the transform acts on whole runs), then a bounded
    search about each kind's best."""

    def sse(s: float) -> dict[str, tuple[float, int]]:
        return _sse(channels, lambda t, u: transform(t, u, s))

    coarse = [sse(s) for s in grid]
    out = {}
    for kind in kinds:
        values = np.array([c.get(kind, (math.inf, 0))[0] for c in coarse])
        k = int(np.argmin(values))
        low, high = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
        fine = minimize_scalar(
            lambda s, kind=kind: sse(s).get(kind, (math.inf, 0))[0],
            bounds=(low, high),
            method="bounded",
            options={"xatol": 1e-3},
        )
        out[kind] = (
            (float(fine.x), float(fine.fun)) if fine.fun < values[k] else (float(grid[k]), float(values[k]))
        )
    return out


@dataclass(frozen=True)
class ResponseFit:
    """The recorded ``channel`` on segments of ``kind``, against the model's, as the model's delayed by
    ``delay`` s, lagged by ``lag`` s, or scaled by ``gain``, each with its SSE, and the SSE of the model as
    it is, over ``samples`` samples. Units: the channel's, squared."""

    channel: str
    kind: str
    samples: int
    sse: float
    delay: float
    delay_sse: float
    lag: float
    lag_sse: float
    gain: float
    gain_sse: float

    def sse_of(self, form: str) -> float:
        """The SSE of one of FORMS."""
        return {"delay": self.delay_sse, "lag": self.lag_sse, "gain": self.gain_sse}[form]

    @property
    def best(self) -> str:
        """Which form fits best: delay, lag or gain ("none" when none improves
        on the model as it is by 5 %)."""
        name = min(FORMS, key=self.sse_of)
        return name if self.sse_of(name) < (1 - explain.MIN_GAIN) * self.sse else "none"

    def to_json(self, sample: str = "samples") -> dict[str, Any]:
        """``sample``: what one sample is called (lookalike.Twins.sample)."""
        return {
            "channel": self.channel,
            "segment": self.kind,
            sample: self.samples,
            "sse": self.sse,
            "delay": self.delay,
            "delay_sse": self.delay_sse,
            "lag": self.lag,
            "lag_sse": self.lag_sse,
            "gain": self.gain,
            "gain_sse": self.gain_sse,
            "best": self.best,
        }


def response_fit(
    channels: Sequence[Channel], name: str, kinds: Sequence[str], min_samples: int = 20
) -> list[ResponseFit]:
    """Per segment kind of ``kinds`` with at least ``min_samples`` usable samples: the delay, lag and gain
    that best carry the model's signal onto the recorded one (pooled over runs). Leave out the kinds
    where the model does not answer at all (a machine at rest): there the fits only reach their bounds."""
    as_is = _sse(channels, lambda t, u: u)
    kinds = [k for k in kinds if as_is.get(k, (0.0, 0))[1] >= min_samples]
    if not kinds:
        return []
    shifts = np.arange(0.0, MAX_SHIFT + 1e-9, SHIFT_GRID)
    delays, lags = _best(channels, kinds, delayed, shifts), _best(channels, kinds, lagged, shifts)
    gains = _best(channels, kinds, _gained, np.arange(GAINS[0], GAINS[1] + 1e-9, GAINS[2]))
    return [
        ResponseFit(name, kind, as_is[kind][1], as_is[kind][0], *delays[kind], *lags[kind], *gains[kind])
        for kind in kinds
    ]


def form_llr(fit: ResponseFit, a: str, b: str) -> float:
    """The log-likelihood ratio of form ``a`` over form ``b`` (positive favours a) on ``fit``'s samples,
    from their SSEs, with σ² the better form's SSE per sample (0 when that is 0)."""
    sse_a, sse_b = fit.sse_of(a), fit.sse_of(b)
    return (sse_b - sse_a) / (2.0 * min(sse_a, sse_b) / fit.samples) if min(sse_a, sse_b) > 0 else 0.0
