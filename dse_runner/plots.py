"""Figures: the simulated track drawn over the recorded one."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; workers and CI have no display
import matplotlib.pyplot as plt  # noqa: E402

from .simulate import SimulationResult  # noqa: E402


def track_plot(result: SimulationResult, path: Path) -> Path:
    """Recorded GPS fixes and the simulated track, equal axes, objectives in the title."""
    gps = result.scenario.gps
    x, y = result.trajectory.xy()
    fig, ax = plt.subplots(figsize=(7, 6), dpi=110)
    ax.plot(gps.x, gps.y, ".", ms=2.5, color="0.45", label="recorded GPS")
    ax.plot(x, y, "-", lw=1.6, color="tab:blue", label="simulated")
    ax.plot([x[0]], [y[0]], "o", color="tab:green", label="start")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    cte = result.objectives.get("cross_track_error")
    title = f"{result.scenario.name}" + (f": mean cross-track error {cte:.3f} m" if cte is not None else "")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(loc="best")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
