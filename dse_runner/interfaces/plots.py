"""Figures of one simulation: what a scenario's kind draws (field data: the track over the GPS fixes),
or else the recorded signals over time, each over its recording where the scenario has one."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; workers and CI have no display
import matplotlib.pyplot as plt

from ..simulation.run import SimulationResult
from ..simulation.scenario import kind

MAX_SIGNALS = 8  # a page of small panels; the CSV has every signal


def result_plot(result: SimulationResult, path: Path) -> Path:
    """The kind's own drawing if it makes one, else signals against time."""
    fig, ax = plt.subplots(figsize=(7, 6), dpi=110)
    if not kind(result.scenario.kind).draw(result, ax):
        plt.close(fig)
        fig, axes = _signal_axes(result)
        _signals(result, axes)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path).resolve()


def _shown(result: SimulationResult) -> list[str]:
    return list(result.trajectory.names[:MAX_SIGNALS])


def _signal_axes(result: SimulationResult):
    n = max(1, len(_shown(result)))
    fig, axes = plt.subplots(n, 1, figsize=(7, 1.6 + 1.4 * n), dpi=110, sharex=True, squeeze=False)
    return fig, axes[:, 0]


def _signals(result: SimulationResult, axes) -> None:
    recorded = result.scenario.recorded
    for ax, name in zip(axes, _shown(result)):
        ax.plot(result.time, result.trajectory.column(name), lw=1.4, color="tab:blue", label="simulated")
        column = name.rpartition(".")[2]
        if recorded is not None and column in recorded.columns:
            t, v = recorded.samples(column)
            ax.plot(t, v, ".", ms=2.5, color="0.45", label=f"recorded {column}")
            ax.legend(loc="best", fontsize=7)
        ax.set_ylabel(name, fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title(result.scenario.name)
