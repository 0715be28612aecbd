"""The report's figures: each compared signal on each run, recorded against simulated, before and after.

Why: a table of noise floors says how much the model misses; a figure says how. A user sees where the
calibrated model overshoots a flat top, lags a step or drifts, and whether the diagnosed one follows, with
the windows where the model missed most marked. The simulated signals are the recordings plus the fits'
residuals (simulated minus recorded), already in hand: nothing is simulated again.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ...simulation.scenario import Scenario
from .signal_locate import Residual

FOLDER = "figures"
WIDTH, HEIGHT = 11.0, 3.6  # inches, at 100 dpi: a figure a report's page width


def file_name(signal: str, scenario: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", f"{scenario}-{signal}") + ".png"


def draw(
    before: Sequence[Residual],
    after: Sequence[Residual],
    scenarios: Mapping[str, Scenario],
    recorded: Mapping[str, str],
    worst: Sequence[Mapping[str, Any]],
    folder: Path,
    labels: tuple[str, str] = ("calibrated", "diagnosed"),
) -> list[Path]:
    """One figure per compared signal and run, into ``folder``/figures; their paths. ``recorded``: the
    recorded column of each compared signal; ``worst``: the located windows to mark (signal, scenario, start,
    stop)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = folder / FOLDER
    out.mkdir(parents=True, exist_ok=True)
    later = {(r.signal, r.scenario): r for r in after}
    paths: list[Path] = []
    for first in before:
        path = out / file_name(first.signal, first.scenario)
        if path in paths:  # two objectives may compare the same signal
            continue
        scenario = scenarios[first.scenario]
        time, values = scenario.recorded.samples(recorded[first.signal])
        figure, axes = plt.subplots(figsize=(WIDTH, HEIGHT), dpi=100)
        axes.plot(time, values, color="black", linewidth=1.0, label="recorded")
        axes.plot(
            first.time,
            values[: first.values.size] + first.values,
            color="tab:grey",
            linewidth=1.0,
            linestyle="--",
            label=labels[0],
        )
        second = later.get((first.signal, first.scenario))
        if second is not None:
            axes.plot(
                second.time,
                values[: second.values.size] + second.values,
                color="tab:blue",
                linewidth=1.2,
                label=labels[1],
            )
        marked = [w for w in worst if w["signal"] == first.signal and w["scenario"] == first.scenario]
        for k, w in enumerate(marked):
            axes.axvspan(
                w["start"],
                w["stop"],
                color="tab:orange",
                alpha=0.15,
                label="worst windows before" if k == 0 else None,
            )
        axes.set_xlabel("time [s]")
        axes.set_ylabel(first.signal)
        axes.set_title(f"{first.signal} on {first.scenario}")
        axes.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small")
        figure.tight_layout()
        figure.savefig(path)
        plt.close(figure)
        paths.append(path)
    return paths
