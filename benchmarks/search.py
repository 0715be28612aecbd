"""Closed-loop search on the paper's calibration: how many simulations each strategy needs,
and dse-runner on 2 workers against plain Optuna in one process, measured side by side in one run.

    python benchmarks/search.py [--json] [--strategies tpe,sobol] [--seeds 3] [--points 60]
                                [--baseline tpe] [--work DIR] [--variant NAME=JSON ...]

Everything runs on ONE local Dask cluster of 2 single-threaded worker processes, started once
before the clock (its start-up is in no figure) and shared by every run. Before any run is timed,
a 2-point random search loads the FMUs on the workers and, when gp is measured, a 12-point gp
search imports PyTorch in this process, so that the first run measured pays for neither:

1. The exhaustive grid of jobs/robotti/space.yaml (125 points x the 12 bundled runs), into a
   store of its own: its best total cross_track_error (the paper's Equation 2) is the reference
   every search is compared with; nothing is hard-coded.
2. The same space made continuous (cAlphaF 20000-38000, mass 1000-3000, mu 0.3-0.7, intervals
   {low, high}), written as a space.yaml of its own per (strategy, seed) with a fresh output, and
   run with ``load_space`` + ``submit`` for each strategy and seed (0, 1, ...), ``--points``
   simulated points each (``search.max_points``; 60 by default):
   - ``points_to_1pct``: from the search's history (``<sweep>.search.json``), the 1-based count of
     simulated points, in the order they were told to the strategy (infeasible ones excluded),
     at which the best-so-far total first comes within 1% of the grid's best; null if never
     within the budget. Per strategy: the median over seeds (a seed that never gets there counts
     as infinitely many, so the median is null when most seeds never get there);
   - ``best_total_60``: the best total among those points (the key keeps its name when
     ``--points`` is not 60), median over seeds, with every seed's in ``best_totals``;
   - ``wall_s``: the median wall time of ``submit`` (the cluster already up; tracks of the best
     points are not kept, ``keep_trajectories: 0``);
   - ``utilisation``: the median of the search's worker utilisation (SearchStatus: simulation
     seconds on the workers / (threads x the time from the first point sent to the last result));
   - ``ask_s``: the median of the client's seconds in the strategy's ask() (SearchStatus.ask_seconds),
     with ``ask_ms`` the mean per asked point: the client's share, which the workers wait for when
     it outgrows a point's simulations divided by the workers.
   Each ``--variant NAME=JSON`` runs every strategy and seed once more with JSON merged into its
   ``search:`` block (e.g. ``async={"order": "asynchronous"}``), right after the others of the same
   seed, so that variants are compared under the same load; rows are named ``strategy [NAME]``.
   nsga2 optimises the Pareto pair (cross_track_error, max_error); its figures are for the best
   cross_track_error total it found. least_squares fits the vector objective fix_residuals
   (added to its space's objectives when missing) and every point it asks, finite-difference
   perturbations included, counts; it may stop before the budget when its steps stop gaining.
3. The ``--baseline`` strategy (tpe by default: Optuna's default sampler and the one a user of
   plain Optuna would reach for) run through plain Optuna in this one process: ``create_study``
   with the very sampler dse-runner builds for it (same class, options and seed), then
   ``study.optimize`` for the same number of trials, whose objective simulates the 12 runs one
   after another with ``dse_runner.simulate`` and sums cross_track_error.
   ``speedup_vs_plain_optuna`` = median plain wall / median dse-runner wall over the seeds.
   Both sides also report CPU seconds (``cpu_s``: this process, which holds the client, the
   strategy and LocalCluster's scheduler, plus the worker processes; psutil), which other load on
   the machine does not inflate: on 2 cores the speedup cannot exceed 2 x plain cpu_s / dse cpu_s.
"""

from __future__ import annotations

import argparse
import copy
import json
import logging
import math
import shutil
import statistics
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path
from typing import Any

import psutil
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import dask
import numpy as np
import optuna
from distributed import Client

from dse_runner import simulate, strict_json
from dse_runner.sweeps.cluster import MESSAGE_LOG_LENGTH
from dse_runner.sweeps.history import SearchHistory, load_history
from dse_runner.sweeps.makers import Cluster as ClusterSpec
from dse_runner.sweeps.makers import Local
from dse_runner.sweeps.rank import rank
from dse_runner.sweeps.spec import Space, load_space
from dse_runner.sweeps.sweep import submit

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "jobs" / "robotti" / "space.yaml"
BOUNDS = {  # issue 14: the grid's extent, made continuous
    "vehicle.cAlphaF": {"low": 20000, "high": 38000},
    "vehicle.mass": {"low": 1000, "high": 3000},
    "vehicle.mu": {"low": 0.3, "high": 0.7},
}
STRATEGIES = ["random", "sobol", "lhs", "tpe", "gp", "cmaes", "nsga2", "genetic", "least_squares"]
OPTUNA_BACKED = ["tpe", "gp", "cmaes", "nsga2"]  # strategies whose sampler plain Optuna has as such
OBJECTIVE = "cross_track_error"
PARETO = ["cross_track_error", "max_error"]  # nsga2's two objectives
RESIDUALS = "fix_residuals"  # least_squares' vector objective
WITHIN = 0.01  # "within 1% of the grid's best"
TARGETS = {"points_to_1pct": 25, "speedup": 1.8, "utilisation": 0.9}


# --- the spaces -----------------------------------------------------------------------------------


def paper_data() -> dict[str, Any]:
    """jobs/robotti/space.yaml as data, its relative scenario paths made absolute."""
    data = yaml.safe_load(PAPER.read_text())
    scenarios = []
    for entry in data.get("scenarios", []):
        if isinstance(entry, str):
            entry = str((PAPER.parent / entry).resolve()) if not Path(entry).is_absolute() else entry
        elif isinstance(entry, dict) and "path" in entry and not Path(entry["path"]).is_absolute():
            entry = {**entry, "path": str((PAPER.parent / entry["path"]).resolve())}
        scenarios.append(entry)
    data["scenarios"] = scenarios
    data.pop("cluster", None)  # we pass our own client
    data["keep_trajectories"] = 0  # tracks of the best points: not part of what is measured
    return data


def with_objective(objectives: list | dict | None, name: str) -> list | dict:
    objectives = objectives or []
    if name in objectives:
        return objectives
    return {**objectives, name: name} if isinstance(objectives, dict) else [*objectives, name]


def write_space(data: dict[str, Any], folder: Path) -> Space:
    """``data`` as ``folder/space.yaml`` with its output in ``folder/out``, loaded as a user would."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "space.yaml"
    path.write_text(yaml.safe_dump({**data, "output": "out"}, sort_keys=False))
    return load_space(path)


def grid_space(base: dict[str, Any], work: Path) -> Space:
    data = copy.deepcopy(base)
    data["name"] = "robotti-grid"
    data["search"] = {"strategy": "exhaustive"}
    return write_space(data, work / "grid")


def search_space(
    base: dict[str, Any],
    work: Path,
    strategy: str,
    seed: int,
    points: int,
    prefix: str = "",
    variant: tuple[str, dict[str, Any]] = ("", {}),
) -> Space:
    data = copy.deepcopy(base)
    data["name"] = f"robotti-{strategy}-s{seed}"
    data["parameters"] = copy.deepcopy(BOUNDS)
    data["search"] = {"strategy": strategy, "max_points": points, "seed": seed, **variant[1]}
    ranking = dict(data.get("ranking") or {})
    ranking["objective"] = OBJECTIVE
    if strategy == "nsga2":
        ranking["pareto"] = list(PARETO)
    data["ranking"] = ranking
    for name in (OBJECTIVE, *ranking.get("pareto", []), *ranking.get("weights", {})):
        data["objectives"] = with_objective(data.get("objectives"), name)
    if strategy == "least_squares":
        data["objectives"] = with_objective(data.get("objectives"), RESIDUALS)
        data["search"]["residuals"] = RESIDUALS
    folder = work / f"{prefix}{strategy}-s{seed}{'-' + variant[0] if variant[0] else ''}"
    shutil.rmtree(folder, ignore_errors=True)  # a fresh store: nothing told from earlier runs
    return write_space(data, folder)


# --- measuring ------------------------------------------------------------------------------------


def best_so_far(history: SearchHistory, objective: str, goal: str) -> list[float]:
    """Best-so-far of ``objective`` after each simulated point, in tell order (infeasible points
    excluded; a failed point counts, without improving anything)."""
    told = sorted(
        (p for p in history.points if p.told is not None and p.state != "infeasible"), key=lambda p: p.told
    )
    better = (lambda a, b: a < b) if goal == "min" else (lambda a, b: a > b)
    trace, best = [], math.nan
    for asked in told:
        value = asked.values.get(objective) if asked.state == "ok" else None
        if value is not None and math.isfinite(value) and (math.isnan(best) or better(value, best)):
            best = value
        trace.append(best)
    return trace


def points_to_within(trace: list[float], reference: float, goal: str, limit: int) -> int | None:
    threshold = reference + WITHIN * abs(reference) if goal == "min" else reference - WITHIN * abs(reference)
    for count, best in enumerate(trace[:limit], start=1):
        if not math.isnan(best) and (best <= threshold if goal == "min" else best >= threshold):
            return count
    return None


def median_or_none(values: list[float | None]) -> float | None:
    """The median, a None counting as infinitely many (never got there); None if the median is."""
    if not values:
        return None
    middle = statistics.median([math.inf if v is None else v for v in values])
    return None if math.isinf(middle) else middle


def _process_cpu() -> float:
    times = psutil.Process().cpu_times()
    return times.user + times.system


def cluster_cpu(client) -> tuple[float, float]:
    """CPU seconds so far of this process (the client and LocalCluster's scheduler) and of the workers."""
    return _process_cpu(), sum(client.run(_process_cpu).values())


def run_search(space: Space, client, reference: float, goal: str, points: int) -> dict[str, Any]:
    client_cpu, workers_cpu = cluster_cpu(client)
    start = time.perf_counter()
    report = submit(space, client=client)
    wall = time.perf_counter() - start
    client_after, workers_after = cluster_cpu(client)
    client_cpu, workers_cpu = client_after - client_cpu, workers_after - workers_cpu
    history = load_history(space.output, space.name)
    trace = best_so_far(history, OBJECTIVE, goal) if history is not None else []
    status = report.search
    best = trace[min(points, len(trace)) - 1] if trace else math.nan
    return {
        "wall_s": wall,
        "cpu_s": client_cpu + workers_cpu,  # what the machine spent on the search, whatever else ran on it
        "client_cpu_s": client_cpu,  # the client, the strategy and LocalCluster's scheduler (one process)
        "workers_cpu_s": workers_cpu,
        "points": len(trace),
        "points_to_1pct": points_to_within(trace, reference, goal, points),
        "best_total": None if math.isnan(best) else best,
        "best_point": status.best_point if status else None,
        "utilisation": status.utilisation if status else None,
        "ask_s": status.ask_seconds if status else None,  # the client's time in the strategy's ask()
        "asks": len(history.points) if history is not None else 0,
        "busy_s": status.busy_seconds if status else None,
        "window_s": status.window_seconds if status else None,
        "failed": status.failed if status else report.failed,
        "infeasible": status.infeasible if status else 0,
        "stopped": status.stopped if status else None,
        "tasks": report.ran,
    }


def plain_optuna(space: Space, points: int) -> dict[str, Any]:
    """The same sampler (dse-runner's, built for this space and seed) in a plain Optuna loop in
    this process: study.optimize, each trial simulating the 12 runs one after another."""
    strategy = space.strategy(1)
    sampler = strategy.study.sampler  # a fresh one: the strategy was never asked
    goals = strategy.goals
    dims = space.dimensions
    plan, scenarios = space.plan, space.scenarios
    settings = {"objectives": space.objectives, "experiment": space.experiment}  # as the workers score

    def objective(trial: optuna.Trial) -> float | list[float]:
        point = {d.name: trial.suggest_float(d.name, d.low, d.high, log=d.log) for d in dims}
        totals = {name: 0.0 for name, _ in goals}
        for scenario in scenarios:
            scored = simulate(plan, scenario, point, **settings).objectives
            for name in totals:
                totals[name] += scored[name]
        values = [totals[name] for name, _ in goals]
        return values if len(values) > 1 else values[0]

    simulate(plan, scenarios[0], {d.name: d.low for d in dims}, **settings)  # warm-up, off the clock
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        study = optuna.create_study(
            sampler=sampler, directions=["minimize" if g == "min" else "maximize" for _, g in goals]
        )
        cpu = _process_cpu()
        start = time.perf_counter()
        study.optimize(objective, n_trials=points)
        wall = time.perf_counter() - start
        cpu = _process_cpu() - cpu
    values = [t.values[0] for t in study.trials if t.values]
    best = (min if goals[0][1] == "min" else max)(values) if values else None
    return {"wall_s": wall, "cpu_s": cpu, "points": len(study.trials), "best_total": best}


def _simulate_points(spec: str, points: list[dict[str, float]]) -> float:
    """Seconds per simulation of ``points`` on every scenario, in this (worker) process."""
    space = load_space(spec)
    settings = {"objectives": space.objectives, "experiment": space.experiment}
    for scenario in space.scenarios:  # warm-up: FMUs loaded and instantiated, off the clock
        simulate(space.plan, scenario, points[0], **settings)
    start = time.perf_counter()
    for point in points:
        for scenario in space.scenarios:
            simulate(space.plan, scenario, point, **settings)
    return (time.perf_counter() - start) / (len(points) * len(space.scenarios))


def parallel_ceiling(space: Space, count: int = 10) -> dict[str, float]:
    """What two processes can gain on this machine at all, with no Dask and no strategy: the same
    simulations timed in one process, then in two at once (2 x one / two-at-once seconds per
    simulation). Two cores that share caches, memory bandwidth or a host's other load give less than
    2, and no distributed runner can beat this figure."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    rng = np.random.default_rng(0)
    dims = space.dimensions
    points = [
        {d.name: float(d.from_unit(u)) for d, u in zip(dims, row)} for row in rng.random((count, len(dims)))
    ]
    context = get_context("spawn")
    with ProcessPoolExecutor(1, mp_context=context) as one:
        alone = one.submit(_simulate_points, str(space.path), points).result()
    with ProcessPoolExecutor(2, mp_context=context) as two:
        pair = list(two.map(_simulate_points, [str(space.path)] * 2, [points, points]))
    return {
        "one_process_s_per_simulation": alone,
        "two_processes_s_per_simulation": statistics.mean(pair),
        "ceiling": 2 * alone / statistics.mean(pair),
    }


# --- the run --------------------------------------------------------------------------------------


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="strict JSON only on stdout (progress on stderr)")
    parser.add_argument(
        "--strategies", default=",".join(STRATEGIES), help="comma-separated (default: all nine)"
    )
    parser.add_argument("--seeds", type=int, default=3, help="seeds 0 .. N-1 per strategy (default 3)")
    parser.add_argument("--points", type=int, default=60, help="simulated points per search (default 60)")
    parser.add_argument(
        "--baseline",
        default="tpe",
        help=f"strategy run through plain Optuna too: one of {', '.join(OPTUNA_BACKED)}, "
        "'best' (the best of those measured) or 'none' (default tpe)",
    )
    parser.add_argument(
        "--work",
        type=Path,
        default=None,
        help="keep stores here (the grid is reused when it is there); default: a temp folder",
    )
    parser.add_argument(
        "--variant",
        action="append",
        default=[],
        metavar="NAME=JSON",
        help="also run every strategy and seed with JSON merged into its search: block, "
        'e.g. \'async={"order": "asynchronous"}\' (repeatable)',
    )
    args = parser.parse_args()
    try:
        args.variants = [("", {})] + [parse_variant(v) for v in args.variant]
    except ValueError as e:
        parser.error(f"--variant: {e}")
    strategies = [s.strip() for s in args.strategies.split(",") if s.strip()]
    unknown = sorted(set(strategies) - set(STRATEGIES))
    if unknown or args.seeds < 1 or args.points < 1:
        parser.error(f"unknown strategies {unknown}" if unknown else "--seeds and --points must be positive")
    if args.baseline not in (*OPTUNA_BACKED, "best", "none"):
        parser.error(f"--baseline: one of {', '.join(OPTUNA_BACKED)}, best or none")
    if args.baseline in OPTUNA_BACKED and args.baseline not in strategies:
        strategies.append(args.baseline)  # its dse-runner wall time is half the ratio
    seeds = list(range(args.seeds))

    def say(text: str) -> None:
        print(text, file=sys.stderr if args.json else sys.stdout, flush=True)

    work = args.work.resolve() if args.work else Path(tempfile.mkdtemp(prefix="dse-bench-search-"))
    base = paper_data()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    logging.getLogger("distributed").setLevel(logging.ERROR)
    figures: dict[str, Any] = {
        "points": args.points,
        "seeds": seeds,
        "workers": 2,
        "threads_per_worker": 1,
        "cluster_startup_in_wall_s": False,
        "strategies": {},
    }
    say(f"work folder {work}; one local cluster of 2 workers x 1 thread, started before any clock")
    # as a sweep's connect holds them: the local cluster's own settings for as long as it lives
    with dask.config.set({"distributed.admin.low-level-log-length": MESSAGE_LOG_LENGTH, **Local.settings}):
        started = time.perf_counter()
        cluster = Local().start(
            ClusterSpec(n_workers=2, threads_per_worker=1), None, None
        )  # dse-runner's own
        client = Client(cluster)
        try:
            client.wait_for_workers(2)
            client.run(lambda: None)
            figures["cluster_startup_s"] = time.perf_counter() - started
            say(f"cluster up in {figures['cluster_startup_s']:.1f} s (not in any wall_s below)")
            measure(figures, client, base, work, strategies, seeds, args, say)
        finally:
            client.close()
            cluster.close()
    if args.work is None:
        shutil.rmtree(work, ignore_errors=True)
    if args.json:
        print(strict_json.dumps(figures))
    else:
        print_table(figures)


def measure(
    figures: dict[str, Any],
    client,
    base: dict[str, Any],
    work: Path,
    strategies: list[str],
    seeds: list[int],
    args,
    say,
) -> None:
    # 1. the grid: the reference
    grid = grid_space(base, work)
    start = time.perf_counter()
    grid_report = submit(grid, client=client)
    grid_wall = time.perf_counter() - start
    ranking = rank(grid.output, grid.name)
    goal = ranking.goal
    reference = ranking.best_total
    figures["grid"] = {
        "points": len(ranking.totals),
        "tasks": grid_report.total,
        "ran": grid_report.ran,
        "found_in_store": grid_report.skipped,
        "wall_s": grid_wall,
        "best_total": reference,
        "best_point": ranking.best,
        "objective": ranking.objective,
        "within_1pct_of": reference + WITHIN * abs(reference),
    }
    say(
        f"grid: {len(ranking.totals)} points x {len(grid.scenarios)} runs ({grid_report.ran} simulated now, "
        f"{grid_report.skipped} found in the store) in {grid_wall:.1f} s; best total {ranking.objective} "
        f"{reference:.4f} at {ranking.best}"
    )

    # every worker unpacks the shipment and loads the FMUs before any clock (the grid may have been
    # found in --work's store), as the plain loop's warm-up simulation does for its process
    warm_up = search_space(base, work, "random", 0, 2, "warm-up-")
    submit(warm_up, client=client)
    if "gp" in strategies:  # PyTorch imported and the GP's code run once in this process, off the clock
        submit(
            search_space(base, work, "gp", 0, 12, "warm-up-", ("", {"n_startup_trials": 10})), client=client
        )

    # 2. every strategy, every seed, every variant (a seed's variants one after another: the same load)
    figures["variants"] = {v: options for v, options in args.variants if v}
    for name in strategies:
        runs: dict[str, list[dict[str, Any]]] = {row_name(name, v): [] for v, _ in args.variants}
        errors: dict[str, list[str]] = {row: [] for row in runs}
        for seed in seeds:
            for variant in args.variants:
                row = row_name(name, variant[0])
                try:
                    space = search_space(base, work, name, seed, args.points, variant=variant)
                    run = run_search(space, client, reference, goal, args.points)
                except Exception as e:  # noqa: BLE001  (a strategy that breaks must not sink the others' figures)
                    errors[row].append(f"seed {seed}: {type(e).__name__}: {e}")
                    say(f"{row} seed {seed}: FAILED {type(e).__name__}: {e}")
                    traceback.print_exc(file=sys.stderr)
                    continue
                run["seed"] = seed
                runs[row].append(run)
                util = f"{run['utilisation'] * 100:.0f}%" if run["utilisation"] is not None else "-"
                say(
                    f"{row} seed {seed}: {run['points']} points in {run['wall_s']:.1f} s, "
                    f"best {run['best_total']}, within 1% after {run['points_to_1pct']}, utilisation {util}, "
                    f"asks {run['ask_s']:.1f} s, stopped: {run['stopped']}"
                )
        for row, done in runs.items():
            figures["strategies"][row] = summarise(done, errors[row])
    ranked = [n for n, s in figures["strategies"].items() if s["runs"]]
    figures["best_strategy"] = min(ranked, key=lambda n: order_key(figures["strategies"][n]), default=None)

    # 3. plain Optuna against dse-runner
    baseline = args.baseline
    if baseline == "best":
        measured = [n for n in OPTUNA_BACKED if figures["strategies"].get(n, {}).get("runs")]
        baseline = min(measured, key=lambda n: order_key(figures["strategies"][n]), default=None)
    if baseline in (None, "none") or not figures["strategies"].get(baseline, {}).get("runs"):
        figures["speedup_vs_plain_optuna"] = None
        return
    plain_runs = []
    for seed in seeds:
        space = search_space(base, work, baseline, seed, args.points, "plain-")  # only its sampler is used
        run = plain_optuna(space, args.points)
        run["seed"] = seed
        plain_runs.append(run)
        say(
            f"plain Optuna {baseline} seed {seed}: {run['points']} trials in {run['wall_s']:.1f} s "
            f"in one process, best {run['best_total']:.4f}"
        )
    dse = figures["strategies"][baseline]
    plain_wall = statistics.median(r["wall_s"] for r in plain_runs)
    figures["plain_optuna"] = {
        "strategy": baseline,
        "wall_s": plain_wall,
        "dse_runner_wall_s": dse["wall_s"],
        # CPU seconds, whatever else ran on the machine: dse-runner's cost over plain Optuna's
        "cpu_s": statistics.median(r["cpu_s"] for r in plain_runs),
        "dse_runner_cpu_s": dse["cpu_s"],
        "best_total": statistics.median(r["best_total"] for r in plain_runs),
        "runs": plain_runs,
        "speedups_by_seed": {
            d["seed"]: p["wall_s"] / d["wall_s"]
            for d in dse["runs"]
            for p in plain_runs
            if p["seed"] == d["seed"]
        },
    }
    figures["speedup_vs_plain_optuna"] = plain_wall / dse["wall_s"]
    say(f"speedup vs plain Optuna ({baseline}): {figures['speedup_vs_plain_optuna']:.2f}x")
    ceiling = parallel_ceiling(search_space(base, work, baseline, 0, args.points, "ceiling-"))
    figures["parallel_ceiling"] = ceiling
    say(
        f"two processes without Dask: {ceiling['ceiling']:.2f}x one "
        f"({1000 * ceiling['one_process_s_per_simulation']:.1f} ms per simulation "
        f"alone, {1000 * ceiling['two_processes_s_per_simulation']:.1f} ms two at once)"
    )


def parse_variant(text: str) -> tuple[str, dict[str, Any]]:
    """``NAME=JSON`` as (name, the search: keys it changes)."""
    name, _, options = text.partition("=")
    found = json.loads(options) if options else None
    if not name or not isinstance(found, dict):
        raise ValueError(f"{text!r} is not NAME={{json object}}")
    return name, found


def row_name(strategy: str, variant: str) -> str:
    return f"{strategy} [{variant}]" if variant else strategy


def summarise(runs: list[dict[str, Any]], errors: list[str]) -> dict[str, Any]:
    if not runs:
        return {
            "points_to_1pct": None,
            "best_total_60": None,
            "wall_s": None,
            "utilisation": None,
            "ask_s": None,
            "ask_ms": None,
            "runs": [],
            "errors": errors,
        }
    bests = [r["best_total"] for r in runs if r["best_total"] is not None]
    utilisations = [r["utilisation"] for r in runs if r["utilisation"] is not None]
    return {
        "points_to_1pct": median_or_none([r["points_to_1pct"] for r in runs]),
        "best_total_60": statistics.median(bests) if bests else None,
        "wall_s": statistics.median(r["wall_s"] for r in runs),
        "cpu_s": statistics.median(r["cpu_s"] for r in runs),
        "utilisation": statistics.median(utilisations) if utilisations else None,
        "ask_s": statistics.median(r["ask_s"] for r in runs),
        "ask_ms": 1000 * sum(r["ask_s"] for r in runs) / max(1, sum(r["asks"] for r in runs)),
        "utilisation_by_seed": utilisations,
        "points_to_1pct_by_seed": [r["points_to_1pct"] for r in runs],
        "best_totals": [r["best_total"] for r in runs],
        "best_of_seeds": min(bests) if bests else None,
        "points_by_seed": [r["points"] for r in runs],
        "runs": runs,
        "errors": errors,
    }


def order_key(summary: dict[str, Any]) -> tuple[float, float]:
    """Fewest points to within 1%, then the lowest best total."""
    reach = summary.get("points_to_1pct")
    best = summary.get("best_total_60")
    return (math.inf if reach is None else reach, math.inf if best is None else best)


def mark(ok: bool) -> str:
    return "✔" if ok else "✘"


def print_table(figures: dict[str, Any]) -> None:
    grid, n = figures["grid"], figures["points"]
    stored = f" ({grid['found_in_store']} tasks found in --work's store)" if grid["found_in_store"] else ""
    print()
    print(
        f"reference: the grid's best total {grid['objective']} "
        f"{grid['best_total']:.4f} at {grid['best_point']}"
    )
    print(
        f"  ({grid['points']} points; within 1%: <= {grid['within_1pct_of']:.4f}); "
        f"grid on 2 workers {grid['wall_s']:.1f} s{stored}"
    )
    print(
        f"{len(figures['seeds'])} seed(s) per strategy, {n} points each, medians over seeds; "
        f"wall_s excludes the cluster's start-up ({figures['cluster_startup_s']:.1f} s, one "
        "cluster for all runs); ask_s: the client's seconds in ask(), ask_ms per asked point"
    )
    for name, options in figures["variants"].items():
        print(f"[{name}]: {json.dumps(options)} merged into search:")
    print()
    width = max(14, *(len(name) for name in figures["strategies"]))
    header = (
        f"{'strategy':<{width}} {'points_to_1pct':>14} {'by seed':>16} {'best_total_' + str(n):>15} "
        f"{'best of seeds':>13} {'wall_s':>7} {'utilisation':>11} {'ask_s':>6} {'ask_ms':>6}"
    )
    print(header)
    print("-" * len(header))
    for name, s in figures["strategies"].items():
        if not s["runs"]:
            print(f"{name:<{width}} failed: {'; '.join(s['errors'])}")
            continue
        reach = "-" if s["points_to_1pct"] is None else f"{s['points_to_1pct']:g}"
        by_seed = ",".join("-" if r is None else str(r) for r in s["points_to_1pct_by_seed"])
        best = "-" if s["best_total_60"] is None else f"{s['best_total_60']:.4f}"
        best_of = "-" if s["best_of_seeds"] is None else f"{s['best_of_seeds']:.4f}"
        util = "-" if s["utilisation"] is None else f"{s['utilisation'] * 100:.0f}%"
        short = "" if all(p >= n for p in s["points_by_seed"]) else f"  (stopped at {s['points_by_seed']})"
        failed = f"  ({len(s['errors'])} seed(s) failed)" if s["errors"] else ""
        print(
            f"{name:<{width}} {reach:>14} {by_seed:>16} {best:>15} {best_of:>13} {s['wall_s']:>7.1f} "
            f"{util:>11} {s['ask_s']:>6.1f} {s['ask_ms']:>6.0f}{short}{failed}"
        )
    print()
    ranked = {k: v for k, v in figures["strategies"].items() if v["runs"]}
    if ranked:
        best_name = figures["best_strategy"]
        reach, target = ranked[best_name]["points_to_1pct"], TARGETS["points_to_1pct"]
        print(
            f"best strategy: {best_name}, within 1% after {reach} points (target <= {target}) "
            f"{mark(reach is not None and reach <= target)}"
        )
        totals = {k: v["best_total_60"] for k, v in ranked.items() if v["best_total_60"] is not None}
        if totals:
            lowest = min(totals, key=totals.get)
            print(
                f"lowest median best total after {n} points: {totals[lowest]:.4f} ({lowest}; target "
                f"below the grid's {grid['best_total']:.4f}) {mark(totals[lowest] < grid['best_total'])}"
            )
        utils = {k: v["utilisation"] for k, v in ranked.items() if v["utilisation"] is not None}
        if utils:
            low = min(utils, key=utils.get)
            print(
                f"lowest median utilisation: {utils[low] * 100:.0f}% "
                f"({low}; target >= {TARGETS['utilisation'] * 100:.0f}% on "
                f"2 workers) {mark(utils[low] >= TARGETS['utilisation'])}"
            )
    plain = figures.get("plain_optuna")
    if plain:
        speedup = figures["speedup_vs_plain_optuna"]
        print(
            f"plain Optuna, {plain['strategy']}, in one process: {plain['wall_s']:.1f} s (best total "
            f"{plain['best_total']:.4f}); dse-runner on 2 workers: {plain['dse_runner_wall_s']:.1f} s"
        )
        print(
            f"speedup_vs_plain_optuna {speedup:.2f}x (target >= {TARGETS['speedup']}) "
            f"{mark(speedup >= TARGETS['speedup'])}"
        )
        ceiling = figures.get("parallel_ceiling")
        if ceiling:
            print(
                "this machine's ceiling for 2 processes (the same "
                f"simulations, no Dask): {ceiling['ceiling']:.2f}x; dse-runner "
                f"reaches {speedup / ceiling['ceiling'] * 100:.0f}% of it"
            )
        ratio = plain["dse_runner_cpu_s"] / plain["cpu_s"]
        print(
            f"CPU seconds: dse-runner {plain['dse_runner_cpu_s']:.1f} s (client, scheduler and workers), "
            f"plain {plain['cpu_s']:.1f} s; ratio {ratio:.2f}, so at most {2 / ratio:.2f}x on 2 cores "
            "(Dask's idle CPU grows with wall time: on a busy machine this bound is pessimistic)"
        )


if __name__ == "__main__":
    main()
