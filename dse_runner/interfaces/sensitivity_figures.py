"""Figures of a sensitivity analysis (analysis/sensitivity.py), one PNG per objective: Sobol' (or
eFAST) S1 and ST bars with their confidence intervals, over all scenarios and in each scenario
group; or Morris' mu*-sigma plane, where a point far right matters and a point high up acts
non-linearly or through interactions."""

from __future__ import annotations

import io
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only
import matplotlib.pyplot as plt
import numpy as np

from ..analysis.sensitivity import Scope, Sensitivity

DPI = 110
PAGE_INCHES = 12.0  # a figure's width: 1320 px at DPI, as wide as the report's page, which it fills unblurred
PER_ROW = 3  # panels side by side: wider rows would set their labels too small once fitted to the page


def write_figures(found: Sensitivity, folder: Path) -> dict[str, Path]:
    """``folder``/sensitivity-<objective>.png for each objective."""
    folder.mkdir(parents=True, exist_ok=True)
    written = {}
    for name, png in pngs(found).items():
        path = folder / f"sensitivity-{name}.png"
        path.write_bytes(png)
        written[name] = path.resolve()
    return written


def pngs(found: Sensitivity, largest: int | None = None) -> dict[str, bytes]:
    """Each objective's figure as PNG bytes: files for the command, inline images for the report and the
    dashboard. At most ``largest`` panels (all scenarios, then the least responsive groups), if given."""
    return {name: png_bytes(figure(found, name, largest)) for name in found.objectives}


def figure(found: Sensitivity, name: str, largest: int | None = None):
    """One objective's panels: over all scenarios, then each group, least responsive first."""
    objective = found.objectives[name]
    groups = [g for g, _ in found.least_responsive(name)]
    groups = groups if largest is None else groups[: max(0, largest - 1)]
    scopes = {"all scenarios": objective.overall, **{f"group {g}": objective.groups[g] for g in groups}}
    draw = _sobol if found.indices else _morris
    columns = min(PER_ROW, len(scopes))
    rows = math.ceil(len(scopes) / columns)
    fig, axes = plt.subplots(
        rows, columns, figsize=(PAGE_INCHES, 0.6 + 3.0 * rows), dpi=DPI, squeeze=False, sharey=found.indices
    )
    for ax in axes.flat[len(scopes) :]:
        ax.set_visible(False)  # the last row's empty places
    for ax, (label, scope) in zip(axes.flat, scopes.items()):
        draw(ax, scope, found.parameters)
        cv = scope.spread.get("cv")
        ax.set_title(label + (f"\ncv {cv:.3g}" if cv is not None else ""), fontsize=9)
    level = f"{100 * found.confidence:g}%"
    fig.suptitle(f"{found.sweep}: {name} ({found.reduced} over scenarios), {level} intervals", fontsize=10)
    fig.tight_layout()
    return fig


def png_bytes(fig) -> bytes:
    """The figure as PNG, and closed (pyplot keeps every open figure)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    return buffer.getvalue()


def _short(parameter: str) -> str:
    return parameter.rsplit(".", 1)[-1]


def _sobol(ax, scope: Scope, parameters: list[str]) -> None:
    x = np.arange(len(parameters))
    for offset, key, color in ((-0.2, "S1", "tab:blue"), (0.2, "ST", "tab:orange")):
        values = [scope.parameters[p][key] for p in parameters]
        errors = [scope.parameters[p][f"{key}_conf"] for p in parameters]
        if all(v is None for v in values):
            continue  # an eFAST curve with a point missing leaves its parameter alone without a bar
        values = [np.nan if v is None else v for v in values]
        errors = [0.0 if e is None else e for e in errors]
        ax.bar(x + offset, values, 0.4, yerr=errors, capsize=3, color=color, label=key)
    ax.axhline(0, color="0.3", lw=0.8)
    ax.set_xticks(x, [_short(p) for p in parameters], fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=7)


def _morris(ax, scope: Scope, parameters: list[str]) -> None:
    for p in parameters:
        v = scope.parameters[p]
        if v["mu_star"] is None:
            continue
        ax.errorbar(v["mu_star"], v["sigma"], xerr=v["mu_star_conf"], fmt="o", capsize=3)
        ax.annotate(
            _short(p), (v["mu_star"], v["sigma"]), fontsize=8, xytext=(4, 4), textcoords="offset points"
        )
    ax.set_xlabel("mu*", fontsize=8)
    ax.set_ylabel("sigma", fontsize=8)
    ax.grid(alpha=0.3)
