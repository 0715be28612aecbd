"""Segments: what the operator asked for, and when, read from the command log alone.

Look-alike effects differ only in *how* the vehicle answers a command: a delay shifts the
answer to a steering step, a first-order lag rounds it off, slip leaves a steady deficit while
cruising and a speed lag none. To weigh that evidence one must know where each kind of command
happened, and that must not come from any model (it would then judge itself). So each instant
of a run gets one kind, from the steering and speed commands only:

* ``steer_step`` / ``speed_step``: the command jumps (by more than ``STEER_JUMP`` / ``SPEED_JUMP``
  within ``STEP_SPAN``);
* ``steer_ramp`` / ``speed_ramp``: it changes steadily (faster than ``STEER_RATE`` / ``SPEED_RATE``
  for at least ``STEER_RAMP_SECONDS`` / ``SPEED_RAMP_SECONDS``); the flanks of a sine are ramps;
* ``rest``: the speed command is 0; ``steer_hold``: moving with a steady, non-zero steering angle;
  ``cruise``: moving straight at a steady speed.

A step or ramp keeps its kind for ``SETTLE`` seconds after it ends, while the vehicle settles
(that is where a lag and a delay differ). Where kinds overlap, the more telling one wins, in the
order of ``KINDS``, so the segments partition the run and evidence summed over them counts
every fix once.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from ...simulation.scenario import Scenario, read_table

STEER_STEP, STEER_RAMP, STEER_HOLD = "steer_step", "steer_ramp", "steer_hold"
SPEED_STEP, SPEED_RAMP, CRUISE, REST = "speed_step", "speed_ramp", "cruise", "rest"
KINDS = (STEER_STEP, SPEED_STEP, STEER_RAMP, SPEED_RAMP, STEER_HOLD, CRUISE, REST)  # most telling first

STEP_SPAN = 0.2  # s: a jump happens within this
STEER_JUMP = 0.02  # rad
SPEED_JUMP = 0.1  # m/s
STEER_RATE = 0.005  # rad/s: slower than this, the steering is held
SPEED_RATE = 0.02  # m/s²
STEER_RAMP_SECONDS = 2.0
SPEED_RAMP_SECONDS = 1.0
RATE_WINDOW = 0.5  # s over which a ramp's rate is taken (the logged command is rounded)
HOLD_ANGLE = 0.01  # rad: a steady angle above this is a held turn, not straight driving
SETTLE = 3.0  # s a step or ramp keeps its kind after it ends


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True in ``flags``."""
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1))


def jumps(
    time: np.ndarray, command: np.ndarray, jump: float, span: float = STEP_SPAN
) -> list[tuple[float, float]]:
    """[start, end] of each jump: consecutive log intervals changing faster than ``jump / span`` that
    together last at most ``span`` and change the command by at least ``jump``. A steep but long
    change (a fast sine) is not a jump: it lasts longer than ``span``."""
    dt = np.diff(time)
    change = np.diff(command)
    fast = np.abs(change) >= (jump / span) * dt - 1e-12
    fast &= change != 0
    out = []
    for first, last in _runs(fast):
        start, end = time[first], time[last + 1]
        if end - start <= span + 1e-9 and abs(command[last + 1] - command[first]) >= jump - 1e-12:
            out.append((float(start), float(end)))
    return out


def ramps(
    time: np.ndarray, command: np.ndarray, rate: float, seconds: float, window: float = RATE_WINDOW
) -> list[tuple[float, float]]:
    """[start, end] of each stretch of at least ``seconds`` over which the command's rate, taken over
    ``window`` (so that a rounded log does not break a ramp into pieces), exceeds ``rate``."""
    half = window / 2
    ahead = np.interp(time + half, time, command)
    behind = np.interp(time - half, time, command)
    span = np.interp(time + half, time, time) - np.interp(time - half, time, time)
    slope = np.divide(ahead - behind, span, out=np.zeros_like(command, dtype=float), where=span > 0)
    return [
        (float(time[a]), float(time[b]))
        for a, b in _runs(np.abs(slope) > rate)
        if time[b] - time[a] >= seconds
    ]


def _mark(
    label: np.ndarray, time: np.ndarray, windows: Sequence[tuple[float, float]], kind: str, settle: float
) -> None:
    for start, end in windows:
        label[(time >= start) & (time < end + settle)] = kind


def command_segments(
    time: np.ndarray,
    speed: np.ndarray,
    steering: np.ndarray,
    end: float | None = None,
    settle: float = SETTLE,
) -> pd.DataFrame:
    """The run cut into segments [start, end) of one kind each (``KINDS``), from its command log alone:
    columns start, end, kind. Commands hold until the next row; the last segment ends at ``end``
    (default: the log's last time)."""
    time = np.asarray(time, float)
    speed, steering = np.asarray(speed, float), np.asarray(steering, float)
    if time.size == 0:
        return pd.DataFrame({"start": [], "end": [], "kind": []})
    label = np.where(speed == 0, REST, np.where(np.abs(steering) > HOLD_ANGLE, STEER_HOLD, CRUISE)).astype(
        object
    )
    steer_jumps = jumps(time, steering, STEER_JUMP)
    speed_jumps = jumps(time, speed, SPEED_JUMP)
    layers = [  # least telling first: each overwrites the ones before
        (ramps(time, speed, SPEED_RATE, SPEED_RAMP_SECONDS), SPEED_RAMP),
        (ramps(time, steering, STEER_RATE, STEER_RAMP_SECONDS), STEER_RAMP),
        (speed_jumps, SPEED_STEP),
        (steer_jumps, STEER_STEP),
    ]
    for windows, kind in layers:
        _mark(label, time, windows, kind, settle)
    changes = np.flatnonzero(label[1:] != label[:-1]) + 1
    starts = np.concatenate([[0], changes])
    stops = [*time[changes], float(time[-1] if end is None else max(end, time[-1]))]
    return pd.DataFrame(
        {
            "start": time[starts].astype(float),
            "end": np.asarray(stops, float),
            "kind": label[starts].astype(str),
        }
    )


def of_scenario(scenario: Scenario) -> pd.DataFrame:
    """A field-data run's segments, from its steering log (``velocity`` and ``delta_f`` columns)."""
    log = read_table(scenario.files["steering_inputs"], ("time", "velocity", "delta_f"))
    time, speed, steering = log.columns
    return command_segments(time, speed, steering, end=scenario.stop_time)


def kinds_at(segments: pd.DataFrame, times: np.ndarray) -> np.ndarray:
    """The kind of segment each of ``times`` falls in ("" before the first or after the last)."""
    times = np.asarray(times, float)
    if segments.empty:
        return np.full(times.size, "", dtype=object)
    starts = segments["start"].to_numpy(float)
    index = np.searchsorted(starts, times, side="right") - 1
    inside = (index >= 0) & (times <= segments["end"].to_numpy(float)[-1] + 1e-9)
    kinds = segments["kind"].to_numpy(object)
    return np.where(inside, kinds[np.clip(index, 0, None)], "")
