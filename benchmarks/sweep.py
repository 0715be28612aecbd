"""Sweep throughput, overhead and client memory, measured side by side in one run.

    python benchmarks/sweep.py [--json] [--skip-paper] [--cheap-tasks 100000] [--cheap-loop-tasks 5000]

Simulations use the native step loop (the default; DSE_RUNNER_LOOP=python measures the old one):
``loop`` says which ran.
``--skip-paper`` leaves out parts 1 and 2 (about a minute); ``--json`` prints every figure as
strict JSON instead of the table.

1. The paper's 1500-run sweep (jobs/robotti/space.yaml) on a local cluster of 1 and of 2
   workers: ``speedup_2_workers`` (target >= 1.8).
2. The same 1500 simulations in a plain Python loop in one process, against the 1-worker
   sweep: ``overhead_vs_plain_loop`` = sweep / loop - 1 (target <= 0.10).
   ``dask_overhead_fraction``: Dask's share, the 2-worker sweep's wall time x workers spent outside
   chunks (scheduling, transfers, waiting for the next chunk, the start and the end), over the time
   spent in chunks (target < 0.05); ``overhead_fraction``: all of the workers' time not simulating
   (Dask's share and our own work inside chunks: rows, Parquet) over the time simulating.
3. A sweep of ``--cheap-tasks`` tasks on the cheap vanderpol FMU (benchmarks/fmus/vanderpol:
   20 s at 1e-2 s, 2000 steps, ~0.2-0.5 ms a simulation; one parameter, mu, with that many
   values; objective x0_max) on 2 workers, where the fixed cost per task shows:

   - ``cheap_tasks``, ``cheap_sweep_seconds`` (wall time, workers already up) and
     ``cheap_tasks_per_second`` = tasks / wall time;
   - ``cheap_plain_loop_ms_per_task``: the same model in a plain loop in one process, over the
     first ``--cheap-loop-tasks`` of the same tasks;
   - ``per_task_overhead_ms`` = (wall time x workers - plain-loop time of the same tasks) / tasks:
     everything a task costs on top of its simulation (Dask, chunking, Parquet, the worker's
     Python around each simulation, the client expanding the space);
   - ``cheap_worker_ms_per_task``: simulation time per task on the workers (the chunks' loop
     around each simulation included), against the plain loop's;
   - ``cheap_chunk_size``, ``cheap_chunks`` and ``cheap_chunk_simulation_seconds`` (simulation time per
     chunk): what the sweep's adaptive chunking chose (the largest chunk), against ``chunk_seconds`` (2 s);
   - ``cheap_dask_overhead_fraction`` and ``cheap_overhead_fraction``: as ``dask_overhead_fraction``
     (target < 0.05) and ``overhead_fraction``;
   - ``cheap_in_chunk_fraction``: the workers' time inside chunks but not simulating (unpacking,
     building rows, writing Parquet; SweepReport.chunk_seconds - simulation_seconds), over the time
     simulating: our own per-task cost, which chunking cannot shrink;
   - ``client_cpu_seconds``: CPU time of the client process during the sweep, not counting the
     cluster's start (expanding and hashing
     tasks, and the local scheduler, which runs in the same process): on a 2-core machine it is
     taken from the workers;
   - ``client_rss_mb``: the client's resident memory sampled during the sweep (start, peak, end).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import psutil

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's dse_runner

from dse_runner.simulation import native
from dse_runner.simulation.run import simulate
from dse_runner.sweeps.cluster import connect
from dse_runner.sweeps.expand import expand
from dse_runner.sweeps.makers import Cluster
from dse_runner.sweeps.spec import Space, load_space
from dse_runner.sweeps.sweep import SweepReport, submit

REPO = Path(__file__).resolve().parents[1]

VANDERPOL = REPO / "benchmarks" / "fmus" / "vanderpol"
WORKERS = 2  # of the cheap sweep and of the paper's second sweep
MAX_DASK_SHARE = 0.05

Figures = dict[str, Any]


def fresh(space: Space, output: Path) -> Space:
    shutil.rmtree(output, ignore_errors=True)
    return Space(
        space.spec.model_copy(update={"output": str(output), "keep_trajectories": 0}),
        space.path,
        space.plan,
        space.scenarios,
    )


def cpu_seconds() -> float:
    """User and system CPU time of this process (the client, and a local cluster's scheduler)."""
    return sum(psutil.Process().cpu_times()[:2])


def timed_sweep(space: Space, workers: int, on_progress=None) -> tuple[float, SweepReport, float]:
    """Wall time of the sweep, its report, and the client's CPU time during it
    (not while the cluster starts)."""
    with connect(Cluster(n_workers=workers)) as client:  # the cluster `submit` makes by default
        client.run(lambda: None)  # workers up and connected before the clock starts
        start, cpu = time.perf_counter(), cpu_seconds()
        report = submit(space, progress=on_progress, client=client)
        return time.perf_counter() - start, report, cpu_seconds() - cpu


def plain_loop(space: Space, limit: int | None = None) -> tuple[float, int]:
    """What a user's own loop would do: simulate every task in one process."""
    plan = space.plan
    scenarios = {s.name: s for s in space.scenarios}
    tasks = list(expand(space))[:limit]
    settings = {"objectives": space.objectives, "experiment": space.experiment}  # as the sweep's workers do
    simulate(plan, scenarios[tasks[0].scenario], dict(tasks[0].point), **settings)  # warm-up
    start = time.perf_counter()
    for task in tasks:
        simulate(plan, scenarios[task.scenario], dict(task.point), **settings)
    return time.perf_counter() - start, len(tasks)


def loop_in_use() -> str:
    """The step loop simulations run with here and on the local workers (they inherit the environment):
    native unless DSE_RUNNER_LOOP says python or the C loop cannot be built."""
    asked = os.environ.get("DSE_RUNNER_LOOP") or "native"
    return "native" if asked == "native" and native.library() is not None else "python"


def dask_share(wall: float, workers: int, report: SweepReport) -> float:
    """Workers' wall time outside chunks (Dask scheduling and transfers, waiting for the next chunk, idle
    at the start and end) over their time in chunks: what chunking must keep under 5%."""
    return (wall * workers - report.chunk_seconds) / report.chunk_seconds


def overhead(wall: float, workers: int, report: SweepReport) -> float:
    """Workers' wall time not simulating (Dask's share and our own work in
    chunks) over the time simulating."""
    return (wall * workers - report.simulation_seconds) / report.simulation_seconds


def vanderpol_space(folder: Path, n_tasks: int) -> Space:
    """The cheap FMU alone, built from source on first use: the sweep's cost with almost no simulation."""
    spec = folder / "space.yaml"
    spec.write_text(
        json.dumps(
            {  # JSON is YAML
                "name": "vanderpol",
                "multimodel": {"fmus": {"vanderpol": str(VANDERPOL)}},
                "experiment": {"stop_time": 20, "step": 0.01},
                "parameters": {"vanderpol.mu": {"start": 0.5, "stop": 2.5, "num": n_tasks}},
                "objectives": {"x0_max": {"signal": "vanderpol.x0", "reduce": "max"}},
                "output": str(folder / "vanderpol-out"),
                "keep_trajectories": 0,
            }
        )
    )
    return load_space(spec)


def paper_figures(work: Path, say: Callable[..., None]) -> Figures:
    """Parts 1 and 2: the paper's sweep on 1 and 2 workers, and in a plain loop."""
    paper = load_space(REPO / "jobs" / "robotti" / "space.yaml")
    loop_seconds, loop_tasks = plain_loop(paper)
    say(f"plain loop: {loop_tasks} simulations in {loop_seconds:.2f} s")
    one, report_one, _ = timed_sweep(fresh(paper, work / "w1"), 1)
    say(
        f"sweep, 1 worker:  {one:.2f} s ({report_one.ok} ok, largest chunk {report_one.chunk_size}, "
        f"{report_one.chunks} chunks)"
    )
    two, report_two, _ = timed_sweep(fresh(paper, work / "w2"), WORKERS)
    say(
        f"sweep, 2 workers: {two:.2f} s ({report_two.ok} ok, largest chunk {report_two.chunk_size}, "
        f"{report_two.chunks} chunks)"
    )
    return {
        "plain_loop_seconds": loop_seconds,
        "sweep_1_worker_seconds": one,
        "sweep_2_workers_seconds": two,
        "speedup_2_workers": one / two,
        "dask_overhead_fraction": dask_share(two, WORKERS, report_two),
        "overhead_fraction": overhead(two, WORKERS, report_two),
        "overhead_vs_plain_loop": one / loop_seconds - 1,
    }


def cheap_figures(work: Path, n_tasks: int, loop_tasks: int, say: Callable[..., None]) -> Figures:
    """Part 3: many short tasks, where Dask's, the chunks' and the worker's fixed costs show."""
    cheap = vanderpol_space(work, n_tasks)
    loop_seconds, looped = plain_loop(cheap, limit=loop_tasks)
    per_task_loop = loop_seconds / looped
    say(f"cheap plain loop: {looped} simulations in {loop_seconds:.2f} s ({per_task_loop * 1e3:.3f} ms each)")
    process = psutil.Process()
    rss = [process.memory_info().rss]

    def sample(report: SweepReport) -> None:
        rss.append(process.memory_info().rss)

    wall, report, client_cpu = timed_sweep(cheap, WORKERS, on_progress=sample)  # the native loop: the default
    rss.append(process.memory_info().rss)
    ran = report.ran
    say(
        f"cheap sweep: {ran} tasks ({report.ok} ok) in {wall:.2f} s on {WORKERS} workers; largest chunk "
        f"{report.chunk_size}, {report.chunks} chunks; {report.simulation_seconds:.2f} s simulating "
        f"({report.simulation_seconds / ran * 1e3:.3f} ms a task on the workers)"
    )
    return {
        "loop": loop_in_use(),
        "cheap_tasks": ran,
        "cheap_sweep_seconds": wall,
        "cheap_tasks_per_second": ran / wall,
        "cheap_plain_loop_ms_per_task": per_task_loop * 1e3,
        "cheap_worker_ms_per_task": report.simulation_seconds / ran * 1e3,
        "per_task_overhead_ms": (wall * WORKERS - per_task_loop * ran) / ran * 1e3,
        "cheap_chunk_size": report.chunk_size,
        "chunk_seconds": cheap.spec.chunk_seconds,
        "cheap_chunks": report.chunks,
        "cheap_chunk_simulation_seconds": report.simulation_seconds / report.chunks,
        "cheap_dask_overhead_fraction": dask_share(wall, WORKERS, report),
        "cheap_overhead_fraction": overhead(wall, WORKERS, report),
        "cheap_in_chunk_fraction": (report.chunk_seconds - report.simulation_seconds)
        / report.simulation_seconds,
        "client_cpu_seconds": client_cpu,
        "client_rss_mb": {
            "start": rss[0] / 2**20,
            "peak": max(rss) / 2**20,
            "end": rss[-1] / 2**20,
            "samples": len(rss),
        },
    }


def line(name: str, value: str, note: str = "", ok: bool | None = None) -> None:
    """One figure: its value, then its target or what it means, then ✔/✘ if it has a target."""
    print(f"{name:<32}{value:<12}{note}{'' if ok is None else ' ✔' if ok else ' ✘'}".rstrip())


def print_table(figures: Figures) -> None:
    """Each figure with its target and whether it is met, where it has one."""
    f = figures
    if "speedup_2_workers" in f:
        line(
            "speedup_2_workers",
            f"{f['speedup_2_workers']:.2f}x",
            "(target >= 1.8)",
            f["speedup_2_workers"] >= 1.8,
        )
        line(
            "overhead_vs_plain_loop",
            f"{f['overhead_vs_plain_loop'] * 100:+.1f}%",
            "(target <= 10%)",
            f["overhead_vs_plain_loop"] <= 0.10,
        )
        line(
            "dask_overhead_fraction",
            f"{f['dask_overhead_fraction'] * 100:.1f}%",
            "(target < 5%; 2 workers, time outside chunks incl. the start and end of the sweep)",
            f["dask_overhead_fraction"] < MAX_DASK_SHARE,
        )
        line("overhead_fraction", f"{f['overhead_fraction'] * 100:.1f}%", "(all time not simulating)")
    line("loop", f["loop"])
    line("cheap_tasks", str(f["cheap_tasks"]))
    line("cheap_sweep_seconds", f"{f['cheap_sweep_seconds']:.2f} s", f"({WORKERS} workers)")
    line("cheap_tasks_per_second", f"{f['cheap_tasks_per_second']:.0f}")
    line("cheap_plain_loop_ms_per_task", f"{f['cheap_plain_loop_ms_per_task']:.3f} ms")
    line(
        "cheap_worker_ms_per_task",
        f"{f['cheap_worker_ms_per_task']:.3f} ms",
        "(simulation time on the workers)",
    )
    line(
        "per_task_overhead_ms",
        f"{f['per_task_overhead_ms']:.3f} ms",
        f"(wall x {WORKERS} workers - plain loop, per task)",
    )
    line("cheap_chunk_size", str(f["cheap_chunk_size"]), f"(the largest; {f['cheap_chunks']} chunks)")
    line(
        "cheap_chunk_simulation_seconds",
        f"{f['cheap_chunk_simulation_seconds']:.3f} s",
        f"(chunk_seconds: {f['chunk_seconds']:g} s)",
    )
    line(
        "cheap_dask_overhead_fraction",
        f"{f['cheap_dask_overhead_fraction'] * 100:.1f}%",
        "(target < 5%; time outside chunks / time in chunks)",
        f["cheap_dask_overhead_fraction"] < MAX_DASK_SHARE,
    )
    line(
        "cheap_in_chunk_fraction",
        f"{f['cheap_in_chunk_fraction'] * 100:.1f}%",
        "(inside chunks, not simulating: rows and Parquet, ours)",
    )
    line(
        "cheap_overhead_fraction",
        f"{f['cheap_overhead_fraction'] * 100:.1f}%",
        "(all time not simulating / time simulating)",
    )
    line(
        "client_cpu_seconds",
        f"{f['client_cpu_seconds']:.2f} s",
        "(client and scheduler during the cheap sweep: "
        f"{f['client_cpu_seconds'] / f['cheap_sweep_seconds'] * 100:.0f}% "
        "of a core, taken from the workers' 2 cores here)",
    )
    m = f["client_rss_mb"]
    line(
        "client_rss_mb",
        f"{m['peak']:.0f} MB",
        f"(peak; start {m['start']:.0f} MB, end {m['end']:.0f} MB, {m['samples']} samples)",
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print every figure as strict JSON")
    parser.add_argument("--skip-paper", action="store_true", help="skip parts 1-2, the paper's sweeps")
    parser.add_argument("--cheap-tasks", type=int, default=100_000)
    parser.add_argument("--cheap-loop-tasks", type=int, default=5000, help="tasks of the cheap plain loop")
    args = parser.parse_args()
    say = (lambda *a: None) if args.json else print

    work = Path(tempfile.mkdtemp(prefix="dse-bench-"))
    try:
        figures = {} if args.skip_paper else paper_figures(work, say)
        figures |= cheap_figures(work, args.cheap_tasks, args.cheap_loop_tasks, say)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if args.json:
        print(json.dumps(figures, indent=2, allow_nan=False))
    else:
        print_table(figures)


if __name__ == "__main__":
    main()
