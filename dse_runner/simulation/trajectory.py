"""What a co-simulation takes and gives, apart from how it runs: input signals (:class:`Series`), the recorded
:class:`Trajectory` (with the :class:`Stop` of a run an FMU ended early), and :class:`CosimError` when an FMU
fails.

Why a module of their own: the master (cosim.py), the scenarios that feed it (scenario.py), the
objectives that read its output (objectives.py) and the fresh processes that carry a failure back
(isolation.py) all speak these types; kept here, none of them imports another for them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from ..errors import DseError, did_you_mean
from .variables import Value


class CosimError(DseError):
    """An FMU failed or diverged during a co-simulation."""

    def __init__(self, message: str, instance: str | None = None):
        super().__init__(message)
        self.instance = instance  # the instance that failed, when one did


@dataclass(frozen=True)
class Series:
    """An input signal sampled at ``time``: held from sample to sample, or interpolated linearly.
    Before the first sample it has the first value, after the last the last one."""

    time: np.ndarray
    values: np.ndarray
    interpolation: Literal["hold", "linear"] = "linear"

    def at(self, t: np.ndarray) -> np.ndarray:
        if self.interpolation == "linear":
            return np.interp(t, self.time, self.values)
        index = np.searchsorted(self.time, t, side="right") - 1
        return self.values[np.clip(index, 0, len(self.values) - 1)]


@dataclass(frozen=True)
class Stop:
    """An FMU asked to end the run before the experiment's stop time (FMI 2.0: fmi2DoStep returned
    fmi2Discard and fmi2Terminated is true; FMI 3.0: fmi3DoStep's terminateSimulation; model exchange: the
    event update's): which instance, and the time the run reached. Not a failure: the trajectory holds the
    run up to that time, as FMPy's ``simulate_fmu`` keeps it, and is scored over that span."""

    instance: str
    time: float

    @property
    def message(self) -> str:
        return f"the FMU asked to stop at t = {self.time:g}"


@dataclass(frozen=True)
class Trajectory:
    """Recorded values at the communication points: ``values[k, j]`` is ``names[j]`` at ``time[k]``. A run an
    FMU ended early (``stopped``) ends at its stop time, which may lie between two communication points."""

    time: np.ndarray
    names: tuple[str, ...]
    values: np.ndarray
    texts: dict[str, list[str]] = field(default_factory=dict)  # string outputs, one value per point
    stopped: Stop | None = None  # an FMU asked to end the run at stopped.time, the trajectory's last time

    @property
    def end(self) -> float:
        """The time the run reached: the experiment's stop time, or an early stop's."""
        return float(self.time[-1])

    def column(self, name: str) -> np.ndarray:
        try:
            return self.values[:, self.names.index(name)]
        except ValueError:
            if name in self.texts:
                return np.array(self.texts[name], dtype=object)
            have = ", ".join((*self.names, *self.texts))
            raise DseError(
                f"no recorded signal {name!r}{did_you_mean(name, self.names)}; recorded are {have}"
            ) from None

    @property
    def outputs(self) -> dict[str, np.ndarray]:
        """Every recorded signal by name."""
        return {
            **{n: self.values[:, j] for j, n in enumerate(self.names)},
            **{n: np.array(v, dtype=object) for n, v in self.texts.items()},
        }

    def final(self) -> dict[str, Value]:
        """Every recorded signal's last value."""
        numbers = {n: float(self.values[-1, j]) for j, n in enumerate(self.names)}
        return {**numbers, **{n: v[-1] for n, v in self.texts.items()}}

    def with_columns(self, changed: Mapping[str, np.ndarray]) -> Trajectory:
        """The same trajectory with some numeric signals replaced (output effects, signal_effects.py)."""
        if not changed:
            return self
        values = self.values.copy()
        for name, column in changed.items():
            self.column(name)  # names the signal if it is not recorded
            values[:, self.names.index(name)] = column
        return Trajectory(self.time, self.names, values, self.texts, self.stopped)

    def renamed(self, rename: Callable[[str], str]) -> Trajectory:
        return Trajectory(
            self.time,
            tuple(map(rename, self.names)),
            self.values,
            {rename(n): v for n, v in self.texts.items()},
            self.stopped,
        )

    def to_csv(self, path: Path) -> None:
        """``time`` then one column per signal; text values are quoted. Sixteen significant digits
        keep integers exact up to 2^53 (Int64 counters, millisecond stamps) and still print
        0.1 * 3 as 0.3."""
        import csv

        with open(path, "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["time", *self.names, *self.texts])
            numbers = np.column_stack([self.time, self.values])
            for k, row in enumerate(numbers):
                writer.writerow([f"{v:.16g}" for v in row] + [v[k] for v in self.texts.values()])
