"""Closes the control study: picks the tuned gains, compares them with the defaults, checks fidelity.

    dse-runner submit defaults.yaml && dse-runner submit pareto.yaml && dse-runner submit pareto-baseline.yaml
    python bound.py   # optional: the least error any controller reaches at the defaults' effort (bound.json)
    python compare.py [--out out]

1. The tuned gains are the point of pareto.yaml's front (mean path error against mean steering
   effort, over the paths and plants) with the least effort among those that at least halve the
   defaults' mean path error; if none does, the front's least error. Written to tuned.yaml.
2. Defaults against tuned, per path (each the mean over the 5 plants, from the sweeps' stores),
   with the target "half the error at no more effort" checked per path; the front and the tracks
   of both on every path as figures.
3. Fidelity: the defaults, the tuned gains and the gains the same rule picks from the front found
   on the baseline plant (pareto-baseline.yaml: no wheel slip), each simulated on both plants.
4. If bound.json is there: per path, the least error any steering reaches at the defaults' effort.

Writes results.md and figures/ beside this file; prints results.md.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pandas as pd

from dse_runner import simulate
from dse_runner.simulation.values import read_values, write_values
from dse_runner.sweeps import store
from dse_runner.sweeps.rank import rank

HERE = Path(__file__).resolve().parent
PATHS = HERE.parents[1] / "scenarios" / "robotti-paths"
ERROR, EFFORT = "path_error_mean", "steering_effort"
PLANTS = {
    "diagnosed (wheel slip)": HERE / "multimodel.yaml",
    "baseline (no slip)": HERE / "multimodel-baseline.yaml",
}


def per_path(out: Path, sweep: str, parameters: list[str]) -> pd.DataFrame:
    """Each point's objectives per path, the mean over the plant variants (scenario <path>-<plant>)."""
    rows = store.read_results(out, sweep, ["status", "scenario", *parameters, ERROR, EFFORT])
    rows = rows[rows["status"] == "ok"].assign(path=lambda r: r["scenario"].str.rsplit("-", n=1).str[0])
    return rows.groupby([*parameters, "path"])[[ERROR, EFFORT]].mean().reset_index()


def pick(front: pd.DataFrame, error_bound: float) -> pd.Series:
    """The least-effort front point within ``error_bound``, else the least-error one."""
    within = front[front[ERROR] <= error_bound]
    return within.nsmallest(1, EFFORT).iloc[0] if len(within) else front.nsmallest(1, ERROR).iloc[0]


def point_of(row: pd.Series, parameters: list[str]) -> dict[str, float]:
    return {p: float(row[p]) for p in parameters}


def table(defaults: pd.DataFrame, tuned: pd.DataFrame) -> str:
    """Markdown: per path, defaults against tuned, and whether the target holds there."""
    lines = [
        (
            "| path | error, defaults [m] | error, tuned [m] | ratio | effort, defaults "
            "[rad] | effort, tuned [rad] | ratio | half the error at no more effort |"
        ),
        "|---|---|---|---|---|---|---|---|",
    ]
    for path in defaults.index:
        d, t = defaults.loc[path], tuned.loc[path]
        met = t[ERROR] <= 0.5 * d[ERROR] and t[EFFORT] <= d[EFFORT]
        lines.append(
            f"| {path} | {d[ERROR]:.4f} | {t[ERROR]:.4f} | {t[ERROR] / d[ERROR]:.2f} | {d[EFFORT]:.3f} "
            f"| {t[EFFORT]:.3f} | {t[EFFORT] / d[EFFORT]:.2f} | {'yes' if met else 'no'} |"
        )
    return "\n".join(lines)


def pareto_figure(
    totals: pd.DataFrame, front: pd.DataFrame, defaults: pd.Series, tuned: pd.Series, path: Path
) -> None:
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    ax.scatter(totals[EFFORT], totals[ERROR], s=8, c="0.75", label="every point")
    ax.plot(front[EFFORT], front[ERROR], "o-", c="tab:blue", ms=4, label="Pareto front")
    ax.plot(defaults[EFFORT], defaults[ERROR], "s", c="tab:red", ms=8, label="default gains")
    ax.plot(tuned[EFFORT], tuned[ERROR], "*", c="tab:green", ms=13, label="tuned (tuned.yaml)")
    ax.set(
        xlabel="steering effort, mean over paths and plants [rad]",
        yscale="log",
        ylabel="path error, mean over paths and plants [m]",
        title="Path following: accuracy against steering",
    )
    ax.set_xlim(0, max(3.0, float(tuned[EFFORT]) * 1.5))
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def tracks_figure(runs: dict[str, dict[str, object]], path: Path) -> None:
    """Per path: the reference and the vehicle's track with each gain set (diagnosed plant), and below it
    the signed cross-track error the controller sees, where centimetres show."""
    names = sorted(runs)
    fig, axes = plt.subplots(2, len(names), figsize=(4.2 * len(names), 7), squeeze=False)
    for column, name in enumerate(names):
        reference = pd.read_csv(PATHS / name / "path.csv")
        top, bottom = axes[0, column], axes[1, column]
        top.plot(reference["x"], reference["y"], "k--", lw=1, label="path")
        for label, result in runs[name].items():
            t = result.trajectory
            top.plot(t.column("vehicle.x"), t.column("vehicle.y"), lw=1.2, label=label)
            bottom.plot(t.time, t.column("controller.cross_track"), lw=1, label=label)
        top.set(title=name, xlabel="x [m]", ylabel="y [m]")
        bottom.set(xlabel="time [s]", ylabel="cross-track error [m], + = left")
        bottom.axhline(0, c="k", lw=0.5)
        top.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def fidelity(gains: dict[str, dict[str, float]]) -> tuple[str, dict[str, dict[str, object]]]:
    """Each gain set on each plant, every path: mean path error and effort over the paths (markdown), and the
    diagnosed plant's runs for the tracks figure."""
    lines = [
        "| gains | plant | mean path error [m] | mean steering effort [rad] | worst path error [m] |",
        "|---|---|---|---|---|",
    ]
    runs: dict[str, dict[str, object]] = {
        p.name: {} for p in sorted(PATHS.iterdir()) if (p / "path.csv").is_file()
    }
    for label, values in gains.items():
        for plant, model in PLANTS.items():
            results = {name: simulate(model, PATHS / name, values) for name in runs}
            errors = [r.objectives[ERROR] for r in results.values()]
            efforts = [r.objectives[EFFORT] for r in results.values()]
            lines.append(
                f"| {label} | {plant} | {sum(errors) / len(errors):.4f} | {sum(efforts) / len(efforts):.3f} "
                f"| {max(errors):.4f} |"
            )
            if model == PLANTS["diagnosed (wheel slip)"]:
                for name, result in results.items():
                    runs[name][label] = result
    return "\n".join(lines), runs


def bound_section(path: Path) -> str | None:
    """bound.py's result, if it has been run: per path, the least error any steering reaches at no more effort
    than the defaults, against half the defaults' error (the target)."""
    if not path.is_file():
        return None
    found = json.loads(path.read_text())
    lines = [
        "### What any controller could reach at the defaults' effort (bound.py, nominal plant)",
        (
            "The least mean path error of any steering sequence, knowing the whole path in advance, "
            f"with no more steering effort than {found['budget']:g} x the defaults' and within their "
            "steering limits, at their speed: a linear (mixed-integer near the step) program on the "
            "linearised plant, corrected by replaying its solution through the real plant FMU "
            "(bound.py). Where the program is solved to optimality and its replay agrees, no controller "
            "of any structure or gains does better, so a value above half the defaults' error rules the "
            "target out on that path; a replayed value below half shows a steering that meets it."
        ),
        (
            "| path | defaults: error [m] | effort [rad] | least error, linear model [m] | "
            "replayed on the plant [m] | ratio to the defaults | half the error reachable |"
        ),
        "|---|---|---|---|---|---|---|",
    ]
    for name, r in sorted(found["paths"].items()):
        ratio = r["replayed_error"] / r["defaults_error"]
        lines.append(
            f"| {name} | {r['defaults_error']:.4f} | {r['defaults_effort']:.3f} | {r['bound']:.4f} "
            f"| {r['replayed_error']:.4f} | {ratio:.2f} | {'yes' if ratio <= 0.5 else 'no'} |"
        )
    return "\n".join(lines[:2]) + "\n\n" + "\n".join(lines[2:])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "out", help="the sweeps' output folder")
    args = parser.parse_args()
    figures = HERE / "figures"
    figures.mkdir(exist_ok=True)

    ranking = rank(args.out, "robotti-control-pareto")
    parameters = ranking.parameters
    defaults_ranking = rank(args.out, "robotti-control-defaults")
    defaults_total = defaults_ranking.totals.iloc[0]
    tuned = pick(ranking.pareto, 0.5 * defaults_total[ERROR])
    tuned_point = point_of(tuned, parameters)
    write_values(
        HERE / "tuned.yaml",
        tuned_point,
        "Tuned path-controller gains on the diagnosed plant (jobs/robotti-control/compare.py): the\n"
        "least-effort point of pareto.yaml's front that at least halves the defaults' mean path error.",
    )
    baseline_pick = point_of(
        pick(rank(args.out, "robotti-control-pareto-baseline").pareto, 0.5 * defaults_total[ERROR]),
        parameters,
    )

    by_path = per_path(args.out, "robotti-control-pareto", parameters)
    tuned_by_path = by_path[(by_path[parameters] == pd.Series(tuned_point)).all(axis=1)].set_index("path")
    defaults_by_path = per_path(args.out, "robotti-control-defaults", parameters).set_index("path")
    pareto_figure(
        ranking.totals, ranking.pareto.sort_values(EFFORT), defaults_total, tuned, figures / "pareto.png"
    )
    checked, runs = fidelity(
        {
            "defaults": point_of(defaults_total, parameters),
            "tuned (tuned.yaml)": read_values(HERE / "tuned.yaml"),
            "tuned on the baseline plant": baseline_pick,
        }
    )
    tracks_figure(
        {
            name: {k: v for k, v in r.items() if k != "tuned on the baseline plant"}
            for name, r in runs.items()
        },
        figures / "tracks.png",
    )

    gains = "\n".join(
        f"| `{p}` | {defaults_total[p]:g} | {tuned_point[p]:.4g} | {baseline_pick[p]:.4g} |"
        for p in parameters
    )
    text = "\n\n".join(
        [
            "### Defaults against tuned, per path (mean over the 5 plants)",
            table(defaults_by_path, tuned_by_path),
            (
                f"Over all paths and plants: defaults {defaults_total[ERROR]:.4f} m at "
                f"{defaults_total[EFFORT]:.3f} rad; tuned {tuned[ERROR]:.4f} m at "
                f"{tuned[EFFORT]:.3f} rad. Front: {len(ranking.pareto)} of {len(ranking.totals)} "
                "points (figures/pareto.png); tracks on the diagnosed plant: figures/tracks.png."
            ),
            "### Gains\n\n| parameter | defaults | tuned | tuned on the baseline plant |\n|---|---|---|---|\n"
            + gains,
            "### Fidelity: each gain set on both plants (nominal plant, no variants)",
            checked,
        ]
        + [section for section in [bound_section(HERE / "bound.json")] if section]
    )
    (HERE / "results.md").write_text(
        "<!-- Written by compare.py from the sweeps in out/; run it again to update. -->\n\n" + text + "\n"
    )
    print(text)


if __name__ == "__main__":
    main()
