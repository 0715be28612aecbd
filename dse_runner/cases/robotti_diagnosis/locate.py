"""Locate: where and when the calibrated simulation misses the recordings.

Residuals are recorded minus simulated position at each GPS fix, turned into
the simulated vehicle's frame: *along* the heading (positive = the vehicle
is ahead of the model) and *cross* it (positive = to the left). Position
errors accumulate, so besides the residuals themselves their growth rate
(per second) is what a cause drives: it is correlated with the motion
signals and summarised by segment (straight, turning, accelerating, braking).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from ...simulation.scenario import Scenario
from .. import fielddata

FEATURES = [
    "speed",
    "acceleration",
    "steering",
    "steering_rate",
    "lateral_acceleration",
    "heading_cos",
    "heading_sin",
    "distance",
]
COMPONENTS = ["along", "cross", "along_growth", "cross_growth"]
TURNING_YAW_RATE = 0.05  # rad/s
ACCELERATING = 0.05  # m/s^2
STOPPED = 0.1  # m/s
GROWTH_WINDOW = 2.0  # s over which growth rates are taken, well above the fixes' noise


@dataclass(frozen=True)
class Signals:
    """Where the diagnosis finds what it needs in a trajectory's columns."""

    x: str
    y: str
    heading: str
    speed: str
    yaw_rate: str
    steering: str


def segment_of(speed: np.ndarray, acceleration: np.ndarray, yaw_rate: np.ndarray) -> np.ndarray:
    """Each instant's kind of motion: stopped, turning, accelerating, braking or straight."""
    kind = np.full(len(speed), "straight", dtype=object)
    kind[acceleration < -ACCELERATING] = "braking"
    kind[acceleration > ACCELERATING] = "accelerating"
    kind[np.abs(yaw_rate) > TURNING_YAW_RATE] = "turning"
    kind[np.abs(speed) < STOPPED] = "stopped"
    return kind


def _growth(time: np.ndarray, values: np.ndarray) -> np.ndarray:
    """d values / dt over a window of GROWTH_WINDOW seconds (central difference of the raw series)."""
    half = GROWTH_WINDOW / 2
    before = np.interp(time - half, time, values)
    after = np.interp(time + half, time, values)
    span = np.interp(time + half, time, time) - np.interp(time - half, time, time)
    return np.divide(after - before, span, out=np.zeros_like(values), where=span > 0)


def residual_frame(trajectory: pd.DataFrame, scenario: Scenario, signals: Signals) -> pd.DataFrame:
    """One row per GPS fix within the simulation: residual components and the motion there."""
    t = trajectory["time"].to_numpy()
    gps = fielddata.gps(scenario)
    inside = (gps.time >= t[0]) & (gps.time <= t[-1] + 1e-9)
    ft = gps.time[inside]

    def at(column: str) -> np.ndarray:
        return np.interp(ft, t, trajectory[column].to_numpy())

    speed_series = trajectory[signals.speed].to_numpy()
    steering_series = trajectory[signals.steering].to_numpy()
    heading = at(signals.heading)
    ex, ey = gps.x[inside] - at(signals.x), gps.y[inside] - at(signals.y)
    c, s = np.cos(heading), np.sin(heading)
    along, cross = ex * c + ey * s, -ex * s + ey * c
    speed = at(signals.speed)
    acceleration = np.interp(ft, t, np.gradient(speed_series, t))
    yaw_rate = at(signals.yaw_rate)
    travelled = np.concatenate([[0.0], np.cumsum(np.abs(speed_series[1:]) * np.diff(t))])
    return pd.DataFrame(
        {
            "scenario": scenario.name,
            "group": scenario.group,
            "time": ft,
            "along": along,
            "cross": cross,
            "distance_error": np.hypot(ex, ey),
            "along_growth": _growth(ft, along),
            "cross_growth": _growth(ft, cross),
            "speed": speed,
            "acceleration": acceleration,
            "steering": np.interp(ft, t, steering_series),
            "steering_rate": np.interp(ft, t, np.gradient(steering_series, t)),
            "lateral_acceleration": speed * yaw_rate,
            "heading_cos": c,
            "heading_sin": s,
            "distance": np.interp(ft, t, travelled),
            "segment": segment_of(speed, acceleration, yaw_rate),
        }
    )


def _magnitudes(frame: pd.DataFrame, by: str) -> pd.DataFrame:
    grouped = frame.groupby(by)
    table = pd.DataFrame(
        {
            "fixes": grouped.size(),
            "cross_track_error": grouped["distance_error"].mean(),
            "along_rms": grouped["along"].apply(lambda v: float(np.sqrt(np.mean(v**2)))),
            "cross_rms": grouped["cross"].apply(lambda v: float(np.sqrt(np.mean(v**2)))),
            "along_growth_rms": grouped["along_growth"].apply(lambda v: float(np.sqrt(np.mean(v**2)))),
            "cross_growth_rms": grouped["cross_growth"].apply(lambda v: float(np.sqrt(np.mean(v**2)))),
        }
    )
    return table.reset_index()


def by_group(frame: pd.DataFrame) -> pd.DataFrame:
    return _magnitudes(frame, "group")


def by_segment(frame: pd.DataFrame) -> pd.DataFrame:
    return _magnitudes(frame, "segment")


def by_scenario(frame: pd.DataFrame) -> pd.DataFrame:
    return _magnitudes(frame, "scenario")


def correlations(frame: pd.DataFrame) -> pd.DataFrame:
    """Pearson correlation of each residual component (rows) with each motion signal (columns)."""
    table = pd.DataFrame(index=COMPONENTS, columns=FEATURES, dtype=float)
    for component in COMPONENTS:
        for feature in FEATURES:
            a, b = frame[component].to_numpy(), frame[feature].to_numpy()
            table.loc[component, feature] = (
                float(np.corrcoef(a, b)[0, 1]) if np.std(a) > 0 and np.std(b) > 0 else 0.0
            )
    return table


def strongest(table: pd.DataFrame, count: int = 3) -> list[tuple[str, str, float]]:
    """The (component, signal, r) pairs with the largest |r|."""
    pairs = [(c, f, float(table.loc[c, f])) for c in table.index for f in table.columns]
    return sorted(pairs, key=lambda p: -abs(p[2]))[:count]


def signature(frames: dict[str, pd.DataFrame]) -> dict[str, Any]:
    """What changed between the calibrated model's residuals (``before``) and the chosen model's (``after``):
    the segment and component whose rms fell most, and the strongest correlations before."""
    before, after = (by_segment(frames[k]).set_index("segment") for k in ("before", "after"))
    columns = ["along_rms", "cross_rms", "along_growth_rms", "cross_growth_rms"]
    drop = (before[columns] - after[columns].reindex(before.index)).stack()
    (segment, component), amount = drop.idxmax(), float(drop.max())
    return {
        "segment": segment,
        "component": component,
        "before": float(before.loc[segment, component]),
        "after": float(before.loc[segment, component] - amount),
        "correlations": strongest(correlations(frames["before"])),
    }


def located(frames: dict[str, pd.DataFrame]) -> dict[str, Any]:
    """Where the calibrated model's residuals lie, as the answer's JSON holds them (pandas' ``split`` tables):
    by scenario group, segment of the motion and run, their correlations with the motion, and the signature
    of what the chosen model changed."""
    before = frames["before"]
    tables = {
        "by_group": by_group(before),
        "by_segment": by_segment(before),
        "by_scenario": by_scenario(before),
        "correlations": correlations(before),
    }
    return {
        **{k: json.loads(v.to_json(orient="split")) for k, v in tables.items()},
        "signature": signature(frames),
    }


def insensitive_scenarios(table1: pd.DataFrame, tolerance: float = 0.05) -> list[str]:
    """Scenarios whose error no point of the design space changes by more than ``tolerance``
    of its calibrated value: no tuned parameter can improve them."""
    spread = (table1["max_error"] - table1["min_error"]) / table1["computed"]
    return sorted(table1.loc[spread < tolerance, "scenario"])
