"""Locate, for any model: where, in which compared signal, run and stretch of time, the model misses the
recordings, before and after the diagnosis' answer, against each recording's noise.

Why windows of fixed length: the diagnosis knows nothing of a model's dynamics (no motion, no manoeuvre
kinds as field data has), so segments have to exist for every model and every run, inputs or none.
Each run is cut into ``WINDOWS`` equal stretches of time (fewer when a stretch would hold fewer than
``MIN_SAMPLES`` recorded samples, too few for an RMS), and each stretch is labelled by what its inputs
do in it: ``changing`` when a driven input moves within it (a late or sluggish actuator shows there),
``steady`` when none does (a gain or an offset shows there too, a delay hardly), ``no input`` when the
run drives none. The RMS residual of each stretch, divided by the recording's noise σ, says how many
noise floors the model misses by there: about 1 is the noise itself.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from ...simulation.scenario import Scenario
from ...simulation.trajectory import Series

WINDOWS = 10  # stretches per run
MIN_SAMPLES = 8  # recorded samples a stretch needs for its RMS to mean anything
CHANGING, STEADY, NO_INPUT = "changing", "steady", "no input"
STILL = 1e-9  # an input whose range within a stretch is below this share of its whole range is steady
METHOD = (
    f"each run cut into up to {WINDOWS} equal windows of time (at least {MIN_SAMPLES} recorded samples "
    "each), labelled 'changing' where a driven input moves within the window, 'steady' where none does; "
    "per compared signal, run and window the RMS of simulated minus recorded, and that over the "
    "recording's noise sigma (1 = the noise itself), for the calibrated model (before) and the chosen "
    "one (after)"
)


@dataclass(frozen=True)
class Residual:
    """One compared signal's residual (simulated minus recorded) on one run, at the recorded times."""

    signal: str
    scenario: str
    time: np.ndarray
    values: np.ndarray


def residual_times(scenario: Scenario, recorded: str, count: int) -> np.ndarray:
    """The times of a residual vector's samples: the recorded ones from the run's start on, as the
    ``residuals`` metric takes them (objectives.fit), ``count`` of them."""
    if scenario.recorded is None:
        return np.arange(count, dtype=float)
    t, _ = scenario.recorded.samples(recorded)
    start = scenario.start_time or 0.0
    times = t[t >= start - 1e-9][:count]
    if len(times) != count:  # not what the metric saw: number the samples rather than misplace them
        return np.arange(count, dtype=float)
    return times


def windows(time: np.ndarray, count: int = WINDOWS, min_samples: int = MIN_SAMPLES) -> np.ndarray:
    """Window edges over ``time``: ``count`` equal ones, fewer when they would hold too few samples."""
    if time.size == 0:
        return np.array([0.0, 0.0])
    count = max(1, min(count, time.size // max(min_samples, 1)))
    return np.linspace(float(time[0]), float(time[-1]), count + 1)


def window_of(time: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """The window index of each time (the last edge belongs to the last window)."""
    return np.clip(np.searchsorted(edges, time, side="right") - 1, 0, len(edges) - 2)


def activity(scenario: Scenario, start: float, stop: float) -> str:
    """Whether a driven input moves within [start, stop]: ``changing``, ``steady`` or ``no input``."""
    driven = [s for s in scenario.inputs.values() if isinstance(s, Series) and len(s.values) > 1]
    if not driven:
        return NO_INPUT
    for series in driven:
        inside = (series.time > start) & (series.time <= stop)
        values = np.concatenate([series.at(np.array([start, stop])), series.values[inside]])
        whole = float(np.ptp(series.values))
        if whole > 0 and float(np.ptp(values)) > STILL * whole:
            return CHANGING
    return STEADY


def rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else math.nan


def table(
    before: Sequence[Residual],
    after: Sequence[Residual],
    noise: Mapping[str, float],
    scenarios: Mapping[str, Scenario],
) -> pd.DataFrame:
    """One row per compared signal, run and window: its RMS residual before and after, in the signal's
    units and in noise floors."""
    later = {(r.signal, r.scenario): r for r in after}
    rows = []
    for b in before:
        a = later.get((b.signal, b.scenario))
        edges = windows(b.time)
        index_b = window_of(b.time, edges)
        index_a = window_of(a.time, edges) if a is not None else None
        sigma = noise[b.signal]
        for k in range(len(edges) - 1):
            rb = b.values[index_b == k]
            ra = a.values[index_a == k] if a is not None else np.array([])
            rows.append(
                {
                    "signal": b.signal,
                    "scenario": b.scenario,
                    "window": k,
                    "start": float(edges[k]),
                    "stop": float(edges[k + 1]),
                    "input": activity(scenarios[b.scenario], edges[k], edges[k + 1]),
                    "samples": int(rb.size),
                    "rms_before": rms(rb),
                    "rms_after": rms(ra),
                    "floors_before": rms(rb) / sigma,
                    "floors_after": rms(ra) / sigma,
                }
            )
    return pd.DataFrame(rows)


def summary(frame: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """The RMS over whole groups of windows (weighted by their samples), in noise floors."""

    def pooled(group: pd.DataFrame, column: str) -> float:
        weights = group["samples"].to_numpy()
        values = group[column].to_numpy()
        ok = np.isfinite(values) & (weights > 0)
        return (
            float(np.sqrt(np.sum(weights[ok] * values[ok] ** 2) / np.sum(weights[ok])))
            if ok.any()
            else math.nan
        )

    rows = [
        {
            **dict(zip(by, key if isinstance(key, tuple) else (key,))),
            "windows": len(group),
            "samples": int(group["samples"].sum()),
            "floors_before": pooled(group, "floors_before"),
            "floors_after": pooled(group, "floors_after"),
        }
        for key, group in frame.groupby(by, sort=False)
    ]
    return pd.DataFrame(rows)


def worst(frame: pd.DataFrame, count: int = 3) -> pd.DataFrame:
    """The windows the calibrated model misses most, in noise floors."""
    return frame.sort_values("floors_before", ascending=False).head(count)


def located(
    before: Sequence[Residual],
    after: Sequence[Residual],
    noise: Mapping[str, float],
    scenarios: Mapping[str, Scenario],
) -> dict[str, Any]:
    """The JSON's ``located``: the method, every window, and the summaries by run and by input activity."""
    frame = table(before, after, noise, scenarios)

    def records(f: Any) -> list[dict[str, Any]]:
        return f.to_dict("records")

    return {
        "method": METHOD,
        "noise": dict(noise),
        "unit": "noise floors (RMS residual over the recording's sigma)",
        "windows": records(frame),
        "by_scenario": records(summary(frame, ["signal", "scenario"])),
        "by_input": records(summary(frame, ["signal", "input"])),
        "worst": records(worst(frame)),
    }
