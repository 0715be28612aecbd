"""Sweep throughput, overhead and client memory, measured side by side in one run.

    python benchmarks/sweep.py [--json] [--cheap-tasks 100000]

1. The paper's 1500-run sweep (jobs/robotti/space.yaml) on a local cluster of 1 and of 2
   workers: ``speedup_2_workers`` (target >= 1.8).
2. The same 1500 simulations in a plain Python loop in one process, against the 1-worker
   sweep: ``overhead_vs_plain_loop`` = sweep / loop - 1 (target <= 0.10).
   ``dask_overhead_fraction``: the 2-worker sweep's wall time x workers not spent inside a
   chunk, over the time spent inside chunks (target < 0.05).
3. A sweep of ``--cheap-tasks`` tasks on a cheap model (1 s of sin1, RK4 step = communication
   step) on 2 workers: ``per_task_overhead_ms`` = (wall time x workers - plain-loop time of the
   same tasks) / tasks, and the client's resident memory sampled during the sweep
   (``client_rss_mb``: start, peak, end).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import psutil

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dse_runner.sweeps.cluster import connect  # noqa: E402
from dse_runner.sweeps.expand import expand  # noqa: E402
from dse_runner.simulation.run import simulate  # noqa: E402
from dse_runner.sweeps.spec import Cluster, Space, load_space  # noqa: E402
from dse_runner.sweeps.sweep import submit  # noqa: E402


def fresh(space: Space, output: Path) -> Space:
    shutil.rmtree(output, ignore_errors=True)
    return Space(space.spec.model_copy(update={"output": str(output), "keep_trajectories": 0}),
                 space.path, space.plan, space.scenarios)


def timed_sweep(space: Space, workers: int, on_progress=None) -> tuple[float, object]:
    with connect(Cluster(n_workers=workers)) as client:  # the cluster `submit` makes by default
        client.run(lambda: None)  # workers up and connected before the clock starts
        start = time.perf_counter()
        report = submit(space, progress=on_progress, client=client)
        return time.perf_counter() - start, report


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


def cheap_space(folder: Path, n_tasks: int) -> Space:
    """One second of sin1 with one RK4 step per communication step: a ~0.3 ms simulation."""
    source = REPO / "scenarios" / "robotti" / "sin1"
    scenario = folder / "cheap"
    scenario.mkdir(parents=True)
    for name in ("steering_inputs.csv", "gps_position.csv"):
        lines = (source / name).read_text().splitlines()
        kept = [lines[0]] + [line for line in lines[1:] if float(line.split(",")[0]) <= 1.0]
        (scenario / name).write_text("\n".join(kept) + "\n")
    (scenario / "scenario.yaml").write_text(
        "name: cheap\ngroup: cheap\nduration: 1.0\ninitial_pose: {x: 0, y: 0, theta: 0}\n")
    side = max(1, round((n_tasks / 10) ** 0.5))
    spec = folder / "cheap.yaml"
    spec.write_text(json.dumps({
        "name": "cheap", "multimodel": "bundled:robotti/multimodel.yaml",
        "scenarios": [str(scenario)],
        "parameters": {"vehicle.mass": {"start": 1000, "stop": 3000, "num": side},
                       "vehicle.cAlphaF": {"start": 20000, "stop": 38000, "num": side},
                       "vehicle.mu": {"start": 0.3, "stop": 0.7, "num": 10},
                       "vehicle.rk4_step": [0.05]},
        "objectives": ["cross_track_error"], "output": str(folder / "cheap-out"), "keep_trajectories": 0,
    }))
    return load_space(spec)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--cheap-tasks", type=int, default=100_000)
    args = parser.parse_args()
    say = (lambda *a: None) if args.json else print

    work = Path(tempfile.mkdtemp(prefix="dse-bench-"))
    paper = load_space(REPO / "jobs" / "robotti" / "space.yaml")
    loop_seconds, loop_tasks = plain_loop(paper)
    say(f"plain loop: {loop_tasks} simulations in {loop_seconds:.2f} s")
    one, report_one = timed_sweep(fresh(paper, work / "w1"), 1)
    say(f"sweep, 1 worker:  {one:.2f} s ({report_one.ok} ok, chunk size {report_one.chunk_size})")
    two, report_two = timed_sweep(fresh(paper, work / "w2"), 2)
    say(f"sweep, 2 workers: {two:.2f} s ({report_two.ok} ok, chunk size {report_two.chunk_size})")

    cheap = cheap_space(work, args.cheap_tasks)
    cheap_loop, cheap_loop_tasks = plain_loop(cheap, limit=5000)
    per_task_loop = cheap_loop / cheap_loop_tasks
    process = psutil.Process()
    rss = [process.memory_info().rss]

    def sample(report) -> None:
        rss.append(process.memory_info().rss)

    cheap_wall, cheap_report = timed_sweep(cheap, 2, on_progress=sample)
    rss.append(process.memory_info().rss)
    per_task_overhead = (cheap_wall * 2 - per_task_loop * cheap_report.ran) / cheap_report.ran
    say(f"cheap sweep: {cheap_report.ran} tasks in {cheap_wall:.2f} s on 2 workers "
        f"(plain loop {per_task_loop * 1e3:.3f} ms per task; chunk size {cheap_report.chunk_size})")

    figures = {
        "plain_loop_seconds": loop_seconds,
        "sweep_1_worker_seconds": one,
        "sweep_2_workers_seconds": two,
        "speedup_2_workers": one / two,
        # Wall time the 2 workers were not inside a chunk (Dask scheduling, transfers, idle at
        # the end), against the time they were: what chunking must keep under 5%.
        "dask_overhead_fraction": (two * 2 - report_two.simulation_seconds) / report_two.simulation_seconds,
        "overhead_vs_plain_loop": one / loop_seconds - 1,
        "cheap_tasks": cheap_report.ran,
        "cheap_sweep_seconds": cheap_wall,
        "cheap_plain_loop_ms_per_task": per_task_loop * 1e3,
        "per_task_overhead_ms": per_task_overhead * 1e3,
        "client_rss_mb": {"start": rss[0] / 2**20, "peak": max(rss) / 2**20, "end": rss[-1] / 2**20,
                          "samples": len(rss)},
    }
    shutil.rmtree(work, ignore_errors=True)
    if args.json:
        print(json.dumps(figures, indent=2))
        return
    print(f"speedup_2_workers       {figures['speedup_2_workers']:.2f}x   (target >= 1.8)")
    print(f"overhead_vs_plain_loop  {figures['overhead_vs_plain_loop'] * 100:+.1f}%   (target <= 10%)")
    print(f"dask_overhead_fraction  {figures['dask_overhead_fraction'] * 100:.1f}%   (target < 5%; 2 workers, "
          "time outside chunks incl. the end of the sweep)")
    print(f"per_task_overhead_ms    {figures['per_task_overhead_ms']:.3f} ms")
    m = figures["client_rss_mb"]
    print(f"client RSS              start {m['start']:.0f} MB, peak {m['peak']:.0f} MB, end {m['end']:.0f} MB "
          f"({m['samples']} samples)")


if __name__ == "__main__":
    main()
