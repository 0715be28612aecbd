"""Figures of an uncertainty study (sweeps/uncertainty.py): the ranking objective's distribution over the
uncertain draws at each of the best points, one box per point (median, quartiles, 5-95 % whiskers), its mean
as a dot and the ranked robust figure as a diamond: a point can have the best mean and the worst spread."""

from __future__ import annotations

import numpy as np

from ..sweeps.rank import Ranking, format_point
from .sensitivity_figures import DPI, PAGE_INCHES, plt, png_bytes

SHOWN = 8  # best points drawn


def distributions_png(ranking: Ranking, shown: int = SHOWN) -> bytes:
    """The best ``shown`` points' ranking objective over the draws, best at the top."""
    name, about = ranking.objective, ranking.uncertainty
    top = ranking.totals.head(shown)
    keys = [tuple(row) for row in top[ranking.parameters].itertuples(index=False)]
    per_point = ranking.draws.groupby(ranking.parameters, dropna=False)[name]
    values = [per_point.get_group(key if len(key) > 1 else key[0]).to_numpy(float) for key in keys]
    labels = [format_point(dict(zip(ranking.parameters, key)), 4) for key in keys]
    fig, ax = plt.subplots(figsize=(PAGE_INCHES, 1.2 + 0.45 * len(keys)), dpi=DPI)
    y = np.arange(len(keys))[::-1]
    ax.boxplot(
        values,
        positions=y,
        orientation="horizontal",
        whis=(5, 95),
        widths=0.5,
        showfliers=False,
        medianprops={"color": "tab:blue"},
    )
    ax.plot(top[name].to_numpy(float), y, "o", color="black", label="mean")
    if ranking.ranked_by != name:
        ax.plot(top[ranking.ranked_by].to_numpy(float), y, "D", color="tab:red", label=about["ranked_by"])
    ax.set_yticks(y, labels, fontsize=7)
    ax.set_xlabel(f"{ranking.reduced} {name} over the scenarios, per draw", fontsize=8)
    ax.grid(axis="x", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    ax.set_title(
        f"{ranking.sweep}: {name} over {about['samples']} uncertain draws, best first by "
        f"{about['ranked_by']} (boxes: quartiles, whiskers 5-95 %)",
        fontsize=9,
    )
    fig.tight_layout()
    return png_bytes(fig)
