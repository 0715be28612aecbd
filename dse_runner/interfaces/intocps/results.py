"""INTO-CPS's result files, written from our ranking, so scripts that read a DSE's results keep working.

INTO-CPS's DSE scripts leave four files in a DSE's results folder (docs/research/intocps-formats.md,
section 5.3): ``ranking.json`` (Ranking_pareto.py), ``dseResults.csv`` and ``results.html``
(Output_HTML.py, the Python 3 fork's Output_CSV.py) and ``graphs/pareto.png``. We write the same
shapes, with two differences on purpose:

* a design's folder name (INTO-CPS's simDir) has no scenario prefix: our points are already reduced
  over the scenarios (``ranking.over_scenarios``), so one point is one design, not one per scenario;
* the ranks are the fronts of a true non-dominated sort over every pareto objective (section 7.11),
  not the Python 2 two-objective sort-and-peel: equal designs share a front, and a ranking with one
  pareto objective or none works where INTO-CPS crashes.
"""

from __future__ import annotations

import csv
import html
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

STYLE = (
    "body { font-family: sans-serif; } table { border-collapse: collapse; } "
    "th, td { border: 1px solid #999; padding: 2px 8px; text-align: right; } th { background: #ddd; }"
)
DOCTYPE = (
    '<!DOCTYPE html PUBLIC "-//W3C//DTD XHTML 1.0 Strict//EN" '
    '"http://www.w3.org/TR/xhtml1/DTD/xhtml1-strict.dtd">'
)


def _plain(value: Any) -> Any:
    """Python's own scalar, so ``str`` prints ``0.1``, as INTO-CPS's Python did, whatever NumPy prints."""
    return value.item() if hasattr(value, "item") else value


def sim_dir(values: dict[str, Any]) -> str:
    """INTO-CPS's folder name of a design (``makeDirName``): its values by sorted parameter id, ``str()``-ed,
    joined with ``_``."""
    return "_".join(str(_plain(values[key])) for key in sorted(values))


def trimmed(param_id: str) -> str:
    """``{fmu}.instance.variable`` -> ``instance.variable``, INTO-CPS's column
    header (``trimmedParamName``)."""
    return param_id.split("}", 1)[1][1:] if param_id.startswith("{") else param_id


def fronts(values: np.ndarray, goals: list[str]) -> list[np.ndarray]:
    """Row indices of each Pareto front, the non-dominated one first; ``values`` is designs x objectives.
    pymoo's non-dominated sort, as ``sweeps.rank.pareto_mask`` uses, but every front: INTO-CPS's
    ranks 1, 2, ... are fronts peeled off one after another."""
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

    costs = np.asarray(values, dtype=float) * np.array([1.0 if g == "min" else -1.0 for g in goals])
    return list(NonDominatedSorting().do(costs)) if len(costs) else []


def _check(
    points: pd.DataFrame, parameters: dict[str, str], objectives: list[str], pareto: list[tuple[str, str]]
) -> None:
    """A NaN would be written as ``nan`` and ranked anywhere: callers pass only complete points."""
    missing = [c for c in [*parameters, *objectives] if c not in points.columns]
    if missing:
        raise ValueError(f"points have no column {', '.join(map(repr, missing))}")
    for name, goal in pareto:
        if name not in objectives or goal not in ("min", "max"):
            raise ValueError(f"pareto: {name!r} {goal!r} is not one of the objectives with 'min' or 'max'")
    for name in objectives:
        if points[name].isna().any():
            raise ValueError(f"objective {name!r} is NaN for {int(points[name].isna().sum())} point(s)")


def _ranks(points: pd.DataFrame, pareto: list[tuple[str, str]]) -> tuple[np.ndarray, np.ndarray]:
    """Each point's rank, and the table's row order: rank by rank, within a rank best first by the first
    pareto objective (stable, so equal designs keep the caller's order)."""
    rank = np.zeros(len(points), dtype=int)
    for number, members in enumerate(
        fronts(points[[n for n, _ in pareto]].to_numpy(float), [g for _, g in pareto]), start=1
    ):
        rank[members] = number
    first, goal = pareto[0]
    key = points[first].to_numpy(float) * (1.0 if goal == "min" else -1.0)
    return rank, np.lexsort((key, rank))


def _html_page(header: list[str], rows: list[list[str]]) -> str:
    """Output_HTML's page: one heading, the graph, one table (its rows closed with ``</tr>``)."""

    def row(tag: str, cells: list[str]) -> str:
        return "<tr>" + "".join(f"<{tag}>{html.escape(c)}</{tag}>" for c in cells) + "</tr>"

    return "\n".join(
        [
            DOCTYPE,
            '<html xmlns="http://www.w3.org/1999/xhtml" xml:lang="en" lang="en"><head>',
            f'<title>DSE Results Page</title><style type="text/css">{STYLE}</style></head><body>',
            "<h1>pareto</h1>",
            '<p><img src="graphs/pareto.png" alt="pareto" /></p>',
            "<table>",
            row("th", header),
            *(row("td", r) for r in rows),
            "</table></body></html>",
            "",
        ]
    )


def _graph(
    path: Path, points: pd.DataFrame, pareto: list[tuple[str, str]], rank: np.ndarray, order: np.ndarray
) -> None:
    """Ranking_pareto's graph: rank 1 a green line with markers, later ranks markers in red and yellow.
    With one pareto objective, that objective against the design's place in the table."""
    import matplotlib

    matplotlib.use("Agg")  # files only; workers and CI have no display
    import matplotlib.pyplot as plt

    if len(pareto) >= 2:
        (x_name, _), (y_name, _) = pareto[:2]
        x, y = points[x_name].to_numpy(float), points[y_name].to_numpy(float)
    else:
        x_name, y_name = "design", pareto[0][0]
        x, y = np.argsort(order).astype(float) + 1, points[y_name].to_numpy(float)
    fig, ax = plt.subplots(figsize=(8, 6), dpi=75)
    for number in sorted(set(rank.tolist())):
        on = rank == number
        if number == 1:
            by_x = np.argsort(x[on], kind="stable")
            ax.plot(x[on][by_x], y[on][by_x], "o-", color="green", label="rank 1")
        else:
            ax.plot(x[on], y[on], "o", color=("tab:red", "gold")[number % 2], linestyle="none")
    ax.set_xlabel(x_name)
    ax.set_ylabel(y_name)
    fig.savefig(path)
    plt.close(fig)


def write_results(
    folder: Path,
    points: pd.DataFrame,
    parameters: dict[str, str],
    objectives: list[str],
    pareto: list[tuple[str, str]],
    fixed: dict[str, Any] | None = None,
    unrankable: pd.DataFrame | None = None,
) -> dict[str, Path]:
    """INTO-CPS's ranking.json, dseResults.csv, results.html and graphs/pareto.png in ``folder``.

    ``points``: one complete row per design, with a column per parameter (``parameters`` maps each to its
    INTO-CPS id ``{fmu}.instance.variable``) and per objective. ``pareto``: (objective, "min" | "max") in the
    DSE config's order; empty means the first objective, minimised. ``fixed``: INTO-CPS id -> value of the
    multi-model's parameters not swept, which INTO-CPS's tables list too. ``unrankable``: the parameter
    values of designs that failed; they are listed in ranking.json (``simulations`` and ``unrankable``, as
    INTO-CPS does) and nowhere else. The folder names are those of INTO-CPS without its scenario prefix:
    our points are reduced over the scenarios."""
    if not objectives:
        raise ValueError("no objectives to rank by")
    pareto = list(pareto) or [(objectives[0], "min")]
    _check(points, parameters, objectives, pareto)
    folder = Path(folder)
    (folder / "graphs").mkdir(parents=True, exist_ok=True)
    points = points.reset_index(drop=True)
    rank, order = _ranks(points, pareto)

    name_of = {pid: name for name, pid in parameters.items()}
    ids = sorted({*name_of, *(fixed or {})})
    columns = {c: points[c].tolist() for c in [*parameters, *objectives]}

    def dirs(frame: pd.DataFrame) -> list[str]:
        values = {pid: frame[name].tolist() for pid, name in name_of.items()}
        return [sim_dir({pid: v[i] for pid, v in values.items()}) for i in range(len(frame))]

    def value(pid: str, i: int) -> str:
        return str(_plain(columns[name_of[pid]][i] if pid in name_of else fixed[pid]))

    names = dirs(points)
    failed = dirs(unrankable) if unrankable is not None else []
    header = ["Rank", *sorted(objectives), *map(trimmed, ids)]
    rows = [
        [
            str(rank[i]),
            *(str(_plain(columns[o][i])) for o in sorted(objectives)),
            *(value(pid, i) for pid in ids),
        ]
        for i in order
    ]

    paths = {
        "csv": folder / "dseResults.csv",
        "html": folder / "results.html",
        "ranking": folder / "ranking.json",
        "graph": folder / "graphs" / "pareto.png",
    }
    ranking = {
        "pareto": {n: [names[i] for i in order if rank[i] == n] for n in sorted(set(rank.tolist()))},
        "simulations": names + failed,
        "unrankable": failed,
    }
    paths["ranking"].write_text(json.dumps(ranking, sort_keys=True, indent=4))  # int ranks: "2" before "10"
    with paths["csv"].open("w", newline="") as file:
        csv.writer(file, lineterminator="\n").writerows([header, *rows])
    paths["html"].write_text(_html_page(header, rows), encoding="utf-8")
    _graph(paths["graph"], points, pareto, rank, order)
    return paths
