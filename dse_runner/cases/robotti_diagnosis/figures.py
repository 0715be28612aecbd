"""The Robotti's figures of its diagnosis report: what the residuals, tracks and held-out errors look like
before (the calibrated model) and after (the chosen one). They need the simulated tracks, which the JSON
does not hold, so they are drawn once, when the diagnosis runs; the report shows them by their files."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ...analysis.diagnose.answer import HeldOut
from ...sweeps.spec import Space
from .. import fielddata


def draw(
    folder: Path,
    space: Space,
    frames: dict[str, pd.DataFrame],
    tracks: dict[str, dict[str, pd.DataFrame]],
    gps: tuple[str, str],
    held_out: Sequence[HeldOut],
    chosen_label: str,
) -> dict[str, Path]:
    """The along- and cross-track residuals over time, the tracks (GPS, before, after) and the held-out
    errors per run, before and after, as PNGs in ``folder``; their paths by name."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    names = [s.name for s in space.scenarios]
    files = {}

    fig, axes = plt.subplots(len(names), 2, figsize=(11, 1.9 * len(names)), sharex="row", squeeze=False)
    for row, name in enumerate(names):
        for col, component in enumerate(["along", "cross"]):
            ax = axes[row][col]
            for key, colour in (("before", "tab:red"), ("after", "tab:blue")):
                part = frames[key][frames[key]["scenario"] == name]
                label = "calibrated baseline" if key == "before" else chosen_label
                ax.plot(part["time"], part[component], color=colour, lw=1, label=label)
            ax.axhline(0, color="0.6", lw=0.5)
            ax.set_ylabel(f"{name}\n{component} [m]", fontsize=8)
    axes[0][0].set_title("along-track residual (recorded ahead of model > 0)", fontsize=9)
    axes[0][1].set_title("cross-track residual (recorded left of model > 0)", fontsize=9)
    axes[0][1].legend(fontsize=7, loc="upper left")
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    fig.tight_layout()
    files["residuals"] = folder / "residuals.png"
    fig.savefig(files["residuals"], dpi=80)
    plt.close(fig)

    cols = 4
    rows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.2 * rows), squeeze=False)
    for ax, scenario in zip(axes.flat, space.scenarios):
        fixes = fielddata.gps(scenario)
        ax.plot(fixes.x, fixes.y, ".", color="k", ms=1.5, label="GPS")
        for key, colour in (("before", "tab:red"), ("after", "tab:blue")):
            frame = tracks[key][scenario.name]
            label = "calibrated baseline" if key == "before" else chosen_label
            ax.plot(frame[gps[0]], frame[gps[1]], color=colour, lw=1, label=label)
        ax.set_title(scenario.name, fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(names) :]:
        ax.axis("off")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    files["tracks"] = folder / "tracks.png"
    fig.savefig(files["tracks"], dpi=80)
    plt.close(fig)

    runs = sorted(held_out, key=lambda h: (h.group or "", h.scenario))
    fig, ax = plt.subplots(figsize=(max(6, 0.6 * len(runs)), 3.2))
    index = np.arange(len(runs))
    ax.bar(index - 0.2, [h.before for h in runs], 0.4, color="tab:red", label="calibrated baseline")
    ax.bar(index + 0.2, [h.after for h in runs], 0.4, color="tab:blue", label=chosen_label)
    ax.set_xticks(index, [h.scenario for h in runs], rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("held-out cross-track error [m]")
    ax.legend(fontsize=8)
    fig.tight_layout()
    files["held_out"] = folder / "held_out.png"
    fig.savefig(files["held_out"], dpi=80)
    plt.close(fig)
    return files
