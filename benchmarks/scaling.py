"""Scaling: throughput against workers, the scheduler's cost per task, the shipment, and a
projection to 100 and 1,000 workers, measured side by side in one run.

    python3 benchmarks/scaling.py [--json] [--repeats 3] [--noop-tasks 10000] [--batch 1000]

1. A real sweep (jobs/robotti/space.yaml restricted to vehicle.mu in {0.3, 0.5}: 50 points x 12
   scenarios = 600 tasks) on the embedded local cluster with 1 and with 2 workers, each into a
   fresh folder (median of --repeats runs): tasks/s, speedup, and the workers' summed simulation
   seconds against wall x workers. The 2-worker sweep again with chunk_seconds 0.5 and 0.1 gives
   the overhead against chunk size here, and the marginal cost of one more chunk (slope).
2. A real `dask scheduler` and two `dask worker --nthreads 1` processes started by their command
   lines on loopback; the scheduler process's CPU seconds (psutil, before and after):
   - per task for --noop-tasks no-op tasks sent with client.map in batches, and the tasks/s;
   - per task for no-op tasks submitted one per completion, the way the sweep submits chunks;
   - per real chunk task: the 600-task sweep on this cluster with chunk_seconds 0.05 (chunks of
     one task) and 2.0; the difference over the difference in chunks (the client's CPU likewise);
   - per worker heartbeat: the idle scheduler with 2 and with 10 workers.
   The worker-side overhead per chunk o comes from step 1's 2-worker sweep:
   (wall x workers - simulation seconds) / chunks.
3. The shipment every worker receives once through the scheduler (ship.pack, pickled).
4. A projection to 2, 100 and 1,000 workers from these figures; the 100 and 1,000 rows are
   projections from a 2-core machine, not measurements.
5. The chunk size that keeps the overhead under 5% here, against what dse-runner chooses.
"""

from __future__ import annotations

import argparse
import atexit
import json
import math
import os
import pickle
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import zlib
from collections import deque
from pathlib import Path

import psutil

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's dse_runner

from distributed.protocol.pickle import dumps as dask_dumps
from distributed.scheduler import heartbeat_interval

from dse_runner import ship, store
from dse_runner.sweeps.cluster import connect
from dse_runner.sweeps.expand import expand
from dse_runner.sweeps.spec import Space, load_space
from dse_runner.sweeps.sweep import _jobs, chunk_size, submit

REPO = Path(__file__).resolve().parents[1]

MU = [0.3, 0.5]  # of the paper's five: 5 x 5 x 2 points x 12 scenarios = 600 tasks
OVERHEAD_TARGET = 0.05  # worker-side overhead, as a fraction of simulation time
SCHEDULER_MAX = 0.5  # scheduler utilisation allowed in the projection: headroom for bursts
PROJECTED_WORKERS = (2, 100, 1000)


# --- step 1: the real sweep on the embedded local cluster ---------------------------------------


def subset(paper: Space, output: Path, workers: int, chunk_seconds: float = 2.0) -> Space:
    """The paper's space with fewer mu values, no kept tracks, into a fresh folder."""
    shutil.rmtree(output, ignore_errors=True)
    parameters = {**paper.spec.parameters, "vehicle.mu": MU}
    spec = paper.spec.model_copy(
        update={"parameters": parameters, "keep_trajectories": 0, "chunk_seconds": chunk_seconds}
    )
    return Space(spec, paper.path, paper.plan, paper.scenarios).with_overrides(
        output=output, n_workers=workers
    )


def parquet_files(space: Space) -> int:
    return sum(1 for _ in (Path(space.output) / "results").rglob("part-*.parquet"))


def measured(space: Space, client, sample=None) -> dict:
    """Run ``submit`` on a connected client; the figures of one sweep."""
    first: list[float] = []

    def progress(report) -> None:
        if not first:  # called right after the first chunks are launched
            first.append(time.perf_counter())
            if sample:
                sample("chunks_start")

    start = time.perf_counter()
    report = submit(space, progress=progress, client=client)
    wall = time.perf_counter() - start
    w = report.workers
    outside = wall * w - report.simulation_seconds  # worker time not spent simulating
    startup = first[0] - start if first else 0.0
    files = parquet_files(space)
    return {
        "workers": w,
        "ran": report.ran,
        "failed": report.failed,
        "chunks": report.chunks,
        "chunk_size": report.chunk_size,
        "chunk_seconds": space.spec.chunk_seconds,
        "wall_s": wall,
        "tasks_per_s": report.ran / wall,
        "simulation_s": report.simulation_seconds,
        "wall_x_workers_s": wall * w,
        "busy_fraction": report.simulation_seconds / (wall * w),
        "seconds_per_simulation": report.simulation_seconds / report.ran,
        "overhead_fraction": outside / report.simulation_seconds,
        "per_chunk_overhead_s": outside / report.chunks,
        "startup_s": startup,  # expand, store scan, probe, shipment: until the first chunks launch
        "per_chunk_overhead_after_startup_s": (outside - startup * w) / report.chunks,
        "parquet_files": files,
        "files_per_chunk": files / report.chunks,
    }


def local_sweep(paper: Space, output: Path, workers: int, chunk_seconds: float, repeats: int) -> dict:
    """The run with the median wall time of ``repeats`` runs, each into a fresh folder on a fresh cluster."""
    runs = sorted(
        (one_local_sweep(subset(paper, output, workers, chunk_seconds)) for _ in range(repeats)),
        key=lambda r: r["wall_s"],
    )
    return runs[len(runs) // 2] | {
        "repeats_wall_s": [r["wall_s"] for r in runs],
        "repeats_overhead_fraction": [r["overhead_fraction"] for r in runs],
    }


def one_local_sweep(space: Space) -> dict:
    started = time.perf_counter()
    with connect(space.spec.cluster, space.path.parent) as client:
        client.run(lambda: None)  # workers up and connected before the clock starts
        cluster_start = time.perf_counter() - started
        figures = measured(space, client)
    figures["cluster_start_s"] = cluster_start
    return figures


# --- step 2: a CLI-started scheduler and workers -------------------------------------------------


def noop(x):
    return None


class CliCluster:
    """`dask scheduler` and `dask worker --nthreads 1` processes on loopback (as tests/support/cluster.py)."""

    def __init__(self, folder: Path, workers: int):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        self.folder, self.address = folder, f"tcp://127.0.0.1:{port}"
        self.procs: list[subprocess.Popen] = []
        self.scheduler = self._start(
            [
                sys.executable,
                "-m",
                "distributed.cli.dask_scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
                "--dashboard-address",
                "127.0.0.1:0",
            ],
            "scheduler.log",
        )
        deadline = time.time() + 60
        while socket.socket().connect_ex(("127.0.0.1", port)) != 0:
            if time.time() > deadline:
                raise RuntimeError(f"dask scheduler did not start; see {folder / 'scheduler.log'}")
            time.sleep(0.1)
        for i in range(workers):
            self.start_worker(i)
        self.cpu = psutil.Process(self.scheduler.pid)

    def start_worker(self, i: int) -> None:
        self._start(
            [
                sys.executable,
                "-m",
                "distributed.cli.dask_worker",
                self.address,
                "--nthreads",
                "1",
                "--name",
                f"worker-{i}",
                "--no-dashboard",
            ],
            f"worker-{i}.log",
        )

    def _start(self, command: list[str], log: str) -> subprocess.Popen:
        with open(self.folder / log, "ab") as out:
            proc = subprocess.Popen(command, cwd=self.folder, stdout=out, stderr=subprocess.STDOUT)
        self.procs.append(proc)
        return proc

    def scheduler_cpu(self) -> float:
        t = self.cpu.cpu_times()
        return t.user + t.system

    def close(self) -> None:
        for proc in reversed(self.procs):  # workers first, then the scheduler
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for proc in self.procs:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()


def own_cpu() -> float:
    t = psutil.Process().cpu_times()
    return t.user + t.system


def settle(client) -> None:
    """Wait until the scheduler has forgotten every task (released futures are processed)."""
    deadline = time.time() + 30
    while (
        client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks)) and time.time() < deadline
    ):
        time.sleep(0.05)


def noop_tasks(cluster: CliCluster, client, n: int, batch: int) -> dict:
    """n no-op tasks in batches of ``batch`` (one client.map each), two batches in flight."""
    from distributed import wait

    def run(count: int) -> None:
        in_flight: deque = deque()
        for first in range(0, count, batch):
            in_flight.append(client.map(noop, range(first, min(count, first + batch)), pure=False))
            if len(in_flight) > 1:
                wait(in_flight.popleft())
        while in_flight:
            wait(in_flight.popleft())

    run(min(n, 1000))  # warm-up: function pickled and cached, connections open
    return scheduler_cost(cluster, client, n, lambda: run(n)) | {"batch": batch}


def noop_one_by_one(cluster: CliCluster, client, n: int, in_flight: int) -> dict:
    """n no-op tasks submitted the way the sweep submits chunks: ``in_flight`` at first, then one
    client.submit per completed task, its result fetched."""
    from distributed import as_completed

    def run() -> None:
        futures = as_completed([client.submit(noop, i, pure=False) for i in range(in_flight)])
        submitted = in_flight
        for future in futures:
            future.result()
            if submitted < n:
                futures.add(client.submit(noop, submitted, pure=False))
                submitted += 1

    return scheduler_cost(cluster, client, n, run) | {"in_flight": in_flight}


def scheduler_cost(cluster: CliCluster, client, n: int, run) -> dict:
    settle(client)
    cpu0, client0, t0 = cluster.scheduler_cpu(), own_cpu(), time.perf_counter()
    run()
    wall = time.perf_counter() - t0
    settle(client)
    cpu = cluster.scheduler_cpu() - cpu0
    return {
        "tasks": n,
        "wall_s": wall,
        "tasks_per_s": n / wall,
        "scheduler_cpu_s": cpu,
        "scheduler_cpu_per_task_ms": cpu / n * 1e3,
        "scheduler_busy_fraction": cpu / wall,
        "client_cpu_per_task_ms": (own_cpu() - client0) / n * 1e3,
    }


def idle_scheduler(cluster: CliCluster, seconds: float = 8.0) -> float:
    """CPU fraction the scheduler uses with its workers and one client connected and no tasks."""
    time.sleep(2.0)  # let joins and registrations settle
    cpu0, t0 = cluster.scheduler_cpu(), time.perf_counter()
    time.sleep(seconds)
    return (cluster.scheduler_cpu() - cpu0) / (time.perf_counter() - t0)


def cli_sweep(cluster: CliCluster, client, space: Space) -> dict:
    marks: dict[str, tuple[float, float]] = {}

    def sample(name: str) -> None:
        marks[name] = (cluster.scheduler_cpu(), own_cpu())

    sample("start")
    figures = measured(space, client, sample)
    settle(client)
    sample("end")
    figures["scheduler_cpu_s"] = marks["end"][0] - marks["start"][0]
    figures["scheduler_cpu_chunk_phase_s"] = marks["end"][0] - marks["chunks_start"][0]
    figures["client_cpu_s"] = marks["end"][1] - marks["start"][1]
    return figures


# --- step 3 and the client's own per-task work ---------------------------------------------------


def shipment_size(space: Space) -> dict:
    shipment = ship.pack(space.plan, space.scenarios)
    return {
        "pickle_bytes": len(pickle.dumps(shipment)),
        "distributed_dumps_bytes": len(dask_dumps(shipment)),
        "plugin_bytes": len(dask_dumps(ship.ShipmentPlugin(shipment))),
        "zlib_bytes": len(zlib.compress(pickle.dumps(shipment))),
        "fmu_bytes": sum(len(b) for b in shipment.fmus.values()),
        "recording_bytes": sum(len(b) for b in shipment.files.values()),  # the files FMUs read by path
        "scenarios_bytes": len(pickle.dumps(shipment.scenarios)),
    }  # checked scenarios, their recordings inside


def client_per_task(space: Space, repeats: int = 5) -> tuple[float, float]:
    """Client CPU seconds per task for what submit does per task: the counting pass of expand before
    any chunk runs, and the pass that builds chunk jobs (expand again, TaskBatch) while chunks run."""
    key = ship.pack(space.plan, space.scenarios).key
    count = jobs = math.inf
    for _ in range(repeats):
        t0 = time.process_time()
        n = sum(1 for _ in expand(space))
        t1 = time.process_time()
        sum(1 for _ in _jobs(space, key, set(), 100, None))
        t2 = time.process_time()
        count, jobs = min(count, (t1 - t0) / n), min(jobs, (t2 - t1) / n)
    return count, jobs


# --- step 4: the projection ----------------------------------------------------------------------


def project(
    w: int,
    t: float,
    o: float,
    s: float,
    heartbeat_s: float,
    client_task: float,
    client_chunk: float,
    files_per_chunk: float,
    shipment: int,
    s_batched: float,
) -> dict:
    """Smallest chunk size c with worker-side overhead o/(c t) <= 5% and scheduler utilisation
    W s/(c t) + heartbeats <= SCHEDULER_MAX; throughput W/t / (1 + o/(c t))."""
    heartbeats = w / heartbeat_interval(w) * heartbeat_s  # the scheduler's CPU fraction for heartbeats
    room = SCHEDULER_MAX - heartbeats
    by_overhead = o / (OVERHEAD_TARGET * t)
    by_scheduler = w * s / (room * t) if room > 0 else None  # None: heartbeats alone saturate it
    p = {
        "workers": w,
        "heartbeat_utilisation": heartbeats,
        "chunk_size_for_overhead": by_overhead,
        "chunk_size_for_scheduler": by_scheduler,
        "chunk_size_if_batched": max(1, math.ceil(max(by_overhead, w * s_batched / (room * t))))
        if room > 0
        else None,
        "default_chunk_size_paper_sweep": chunk_size(t, 2.0, 1500, w),
        "default_chunk_size_1M_task_sweep": chunk_size(t, 2.0, 1_000_000, w),
        "shipment_bytes_from_scheduler": w * shipment,
    }
    if room <= 0:
        return p | {"chunk_size": None}
    c = max(1, math.ceil(max(by_overhead, by_scheduler)))
    overhead = o / (c * t)
    throughput = w / t / (1 + overhead)
    chunks_per_s = throughput / c
    return p | {
        "chunk_size": c,
        "chunk_wall_s": c * t,
        "worker_overhead_fraction": overhead,
        "scheduler_utilisation": chunks_per_s * s + heartbeats,
        "chunk_tasks_per_s": chunks_per_s,
        "tasks_per_s": throughput,
        "ideal_tasks_per_s": w / t,
        "client_utilisation": throughput * client_task + chunks_per_s * client_chunk,
        "parquet_files_per_s": chunks_per_s * files_per_chunk,
        "min_tasks_for_4_chunks_per_worker": 4 * w * c,
    }


def slope(xs: list[float], ys: list[float]) -> float:
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def machine_speed(space: Space, repeats: int = 20) -> float:
    """Milliseconds of one sin1 simulation in this process: to see whether the machine's speed moved
    during the run (on a shared virtual machine it does)."""
    from dse_runner.simulation.run import simulate

    sin1 = next(s for s in space.scenarios if s.name == "sin1")
    simulate(space.plan, sin1, {}, objectives=space.objectives, experiment=space.experiment)
    start = time.perf_counter()
    for _ in range(repeats):
        simulate(space.plan, sin1, {}, objectives=space.objectives, experiment=space.experiment)
    return (time.perf_counter() - start) / repeats * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--noop-tasks", type=int, default=10_000)
    parser.add_argument("--batch", type=int, default=1000)
    parser.add_argument("--one-by-one-tasks", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3, help="runs of each local sweep; the median is kept")
    args = parser.parse_args()
    say = (lambda *a: None) if args.json else (lambda *a: print(*a, flush=True))

    work = Path(tempfile.mkdtemp(prefix="dse-scaling-"))
    atexit.register(shutil.rmtree, work, ignore_errors=True)  # also when a step fails
    paper = load_space(REPO / "jobs" / "robotti" / "space.yaml")
    f: dict = {
        "machine": {
            "cores": os.cpu_count(),
            "memory_gib": round(psutil.virtual_memory().total / 2**30, 1),
            "python": sys.version.split()[0],
        }
    }
    f["sin1_ms_at_start"] = machine_speed(paper)

    # 1. throughput against workers, and overhead against chunk size
    say(
        "1. real sweep (600 tasks: the paper's space with mu in {0.3, 0.5}), embedded local cluster; "
        f"median of {args.repeats} runs each"
    )
    runs = {}
    for w in (1, 2):
        runs[w] = r = local_sweep(paper, work / f"local-{w}", w, 2.0, args.repeats)
        say(
            f"   {w} worker{'s' if w > 1 else ' '}: {r['ran']} tasks in "
            f"{r['wall_s']:.2f} s = {r['tasks_per_s']:.1f} tasks/s; simulation "
            f"{r['simulation_s']:.2f} s vs wall x workers {r['wall_x_workers_s']:.2f} s "
            f"(busy {r['busy_fraction']:.1%}); {r['chunks']} chunks of {r['chunk_size']}"
        )
    r2 = runs[2]
    f["local"] = {str(w): r for w, r in runs.items()}
    f["speedup_2_workers"] = r2["tasks_per_s"] / runs[1]["tasks_per_s"]
    say(f"   speedup 2 workers / 1: {f['speedup_2_workers']:.2f}x")
    say("   the 2-worker sweep again with smaller chunks:")
    by_chunk = {2.0: r2}
    for cs in (0.5, 0.1):
        by_chunk[cs] = local_sweep(paper, work / f"local-2-{cs}", 2, cs, args.repeats)
    for cs, r in sorted(by_chunk.items()):
        chunk_wall = r["chunk_size"] * r["seconds_per_simulation"]
        say(
            f"   chunk_seconds {cs}: {r['chunks']:>3} chunks of {r['chunk_size']:>2} "
            f"({chunk_wall:.2f} s), {r['wall_s']:.2f} s, overhead (wall x workers - "
            f"simulation) / simulation = {r['overhead_fraction']:.1%} (runs: "
            f"{', '.join(f'{x:.1%}' for x in r['repeats_overhead_fraction'])})"
        )
    f["local_2_workers_by_chunk_seconds"] = {str(k): v for k, v in sorted(by_chunk.items())}
    outside = [r["wall_x_workers_s"] - r["simulation_s"] for r in by_chunk.values()]
    f["marginal_overhead_per_chunk_s"] = marginal = slope([r["chunks"] for r in by_chunk.values()], outside)

    # 2. the scheduler's cost per task
    say("2. CLI-started `dask scheduler` + 2 `dask worker --nthreads 1` on loopback")
    cluster = CliCluster(work, 2)
    try:
        from distributed import Client

        with Client(cluster.address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=120)
            f["scheduler_idle_cpu_fraction_2_workers"] = idle2 = idle_scheduler(cluster)
            say(f"   idle scheduler (2 workers, 1 client): {idle2:.2%} of a core")
            f["noop_batched"] = n = noop_tasks(cluster, client, args.noop_tasks, args.batch)
            say(
                f"   {n['tasks']} no-op tasks, client.map in batches of {n['batch']}: {n['wall_s']:.2f} "
                f"s = {n['tasks_per_s']:.0f} tasks/s; scheduler CPU {n['scheduler_cpu_per_task_ms']:.3f} "
                f"ms per task (scheduler busy {n['scheduler_busy_fraction']:.0%} of a core)"
            )
            f["noop_one_by_one"] = m = noop_one_by_one(cluster, client, args.one_by_one_tasks, 6)
            say(
                f"   {m['tasks']} no-op tasks, one client.submit per completion "
                f"(as the sweep submits chunks): {m['tasks_per_s']:.0f} tasks/s; "
                f"scheduler CPU {m['scheduler_cpu_per_task_ms']:.3f} ms per task"
            )
            cli = {}
            for cs in (0.05, 2.0):
                cli[cs] = r = cli_sweep(cluster, client, subset(paper, work / f"cli-{cs}", 2, cs))
                say(
                    f"   real sweep, chunk_seconds {cs}: {r['chunks']} chunks of {r['chunk_size']} in "
                    f"{r['wall_s']:.2f} s; scheduler CPU {r['scheduler_cpu_s']:.2f} s, client CPU "
                    f"{r['client_cpu_s']:.2f} s"
                )
            f["cli_sweeps"] = {str(k): v for k, v in cli.items()}
            for i in range(2, 10):
                cluster.start_worker(i)
            client.wait_for_workers(10, timeout=180)
            f["scheduler_idle_cpu_fraction_10_workers"] = idle10 = idle_scheduler(cluster)
    finally:
        cluster.close()
    small, big = cli[0.05], cli[2.0]
    extra_chunks = small["chunks"] - big["chunks"]
    s_chunk = (small["scheduler_cpu_s"] - big["scheduler_cpu_s"]) / extra_chunks
    client_chunk = max(0.0, (small["client_cpu_s"] - big["client_cpu_s"]) / extra_chunks)
    heartbeat_s = max(0.0, (idle10 - idle2) / (8 * 2 / heartbeat_interval(10)))
    f["scheduler_cpu_per_chunk_task_ms"] = s_chunk * 1e3
    f["client_cpu_per_chunk_ms"] = client_chunk * 1e3
    f["scheduler_cpu_per_heartbeat_ms"] = heartbeat_s * 1e3
    say(
        f"   real chunk tasks, from the difference of the two sweeps ({small['chunks']} "
        f"- {big['chunks']} chunks): scheduler CPU {s_chunk * 1e3:.3f} ms per chunk, "
        f"client CPU {client_chunk * 1e3:.3f} ms per chunk"
    )
    say(
        f"   idle scheduler with 10 workers: {idle10:.2%} of a core, so "
        f"{heartbeat_s * 1e3:.3f} ms per worker heartbeat (2 a second each at <= 10 workers)"
    )
    t0 = time.perf_counter()
    read_ids = len(store.finished_task_ids(work / "cli-0.05", paper.name))
    f["read_back"] = {
        "files": small["parquet_files"],
        "task_ids": read_ids,
        "seconds": time.perf_counter() - t0,
    }
    say(
        f"   reading the task ids back from the {small['parquet_files']} Parquet files of the "
        f"chunk-of-1 sweep (what a resume does), local disk: {f['read_back']['seconds']:.2f} s"
    )
    o = r2["per_chunk_overhead_s"]
    say(
        "   worker side, 2-worker sweep of step 1: o = (wall x workers - simulation) / chunks = "
        f"({r2['wall_x_workers_s']:.2f} - {r2['simulation_s']:.2f}) / {r2['chunks']} = {o * 1e3:.0f} ms per "
        f"chunk ({r2['per_chunk_overhead_after_startup_s'] * 1e3:.0f} ms without the {r2['startup_s']:.2f} "
        f"s start-up); marginal cost of one more chunk across the three chunk sizes: {marginal * 1e3:.1f} ms"
    )

    # 3. the shipment
    f["shipment"] = sh = shipment_size(paper)
    say(
        "3. shipment (ship.pack of the Robotti space), sent once to every worker through the scheduler: "
        f"{sh['pickle_bytes']:,} bytes pickled ({sh['distributed_dumps_bytes']:,} with distributed's dumps, "
        f"{sh['plugin_bytes']:,} as the plugin, {sh['zlib_bytes']:,} zlib-compressed; FMUs "
        f"{sh['fmu_bytes']:,}, recorded files {sh['recording_bytes']:,}, scenarios {sh['scenarios_bytes']:,})"
    )

    # 4. projection
    t = r2["seconds_per_simulation"]
    s = max(s_chunk, n["scheduler_cpu_per_task_ms"] / 1e3)
    s_batched = n["scheduler_cpu_per_task_ms"] / 1e3
    client_count, client_task = client_per_task(paper)
    f["client_cpu_per_task_ms"] = {
        "counting_pass_before_the_sweep": client_count * 1e3,
        "chunk_building_while_it_runs": client_task * 1e3,
    }
    f["inputs"] = {
        "t_s": t,
        "o_s": o,
        "s_s": s,
        "s_batched_s": s_batched,
        "heartbeat_cpu_s": heartbeat_s,
        "files_per_chunk": r2["files_per_chunk"],
        "client_cpu_per_task_s": client_task,
        "client_cpu_per_chunk_s": client_chunk,
        "shipment_bytes": sh["pickle_bytes"],
        "overhead_target": OVERHEAD_TARGET,
        "scheduler_max": SCHEDULER_MAX,
    }
    f["projection"] = proj = [
        project(
            w,
            t,
            o,
            s,
            heartbeat_s,
            client_task,
            client_chunk,
            r2["files_per_chunk"],
            sh["pickle_bytes"],
            s_batched,
        )
        for w in PROJECTED_WORKERS
    ]
    here = proj[0]
    f["chunk_size_for_5pct_here"] = here["chunk_size"]
    f["chunk_size_for_5pct_here_marginal"] = (
        math.ceil(marginal / (OVERHEAD_TARGET * t)) if marginal > 0 else 1
    )
    f["default_chunk_size_here"] = {
        "this_600_task_sweep": r2["chunk_size"],
        "paper_1500_task_sweep": chunk_size(t, 2.0, 1500, 2),
    }
    f["sin1_ms_at_end"] = machine_speed(paper)
    if args.json:
        print(json.dumps(f, indent=2))
        return

    print(
        f"4. PROJECTION, not a measurement: no sweep ran on 100 or 1,000 workers; every input below was "
        f"measured on this {os.cpu_count()}-core machine (2 working workers; 10 idle ones for the heartbeat)"
    )
    print(
        f"   inputs: t = {t * 1e3:.1f} ms per simulation; o = {o * 1e3:.0f} ms worker-side "
        f"overhead per chunk; s = {s * 1e3:.2f} ms scheduler CPU per chunk task;"
    )
    print(
        f"   heartbeat {heartbeat_s * 1e3:.3f} ms scheduler CPU each (W / "
        f"heartbeat_interval(W) a second); client {client_task * 1e3:.3f} ms CPU per task + "
        f"{client_chunk * 1e3:.2f} ms per chunk while chunks run (and {client_count * 1e3:.3f} "
        f"ms per task before: {client_count * 1e6:.0f} s for 1M tasks);"
    )
    print(
        f"   {r2['files_per_chunk']:.2f} Parquet files per chunk; "
        f"shipment {sh['pickle_bytes'] / 1e6:.2f} MB per worker"
    )
    print(
        f"   c = smallest chunk with o/(c t) <= {OVERHEAD_TARGET:.0%} and scheduler u "
        f"= W s/(c t) + heartbeats <= {SCHEDULER_MAX}; tasks/s = W/t / (1 + o/(c t))"
    )
    print(
        f"   {'workers':>7} {'c':>5} {'c*t s':>6} {'overh.':>6} {'sched u':>7} {'client u':>8} "
        f"{'tasks/s':>8} {'chunks/s':>8} {'files/s':>7} {'ship MB':>8} {'c (batched)':>11}"
    )
    for p in proj:
        if p["chunk_size"] is None:
            print(
                f"   {p['workers']:>7}  heartbeats alone use "
                f"{p['heartbeat_utilisation']:.2f} of the scheduler"
            )
            continue
        print(
            f"   {p['workers']:>7} {p['chunk_size']:>5} {p['chunk_wall_s']:>6.2f} "
            f"{p['worker_overhead_fraction']:>6.1%} "
            f"{p['scheduler_utilisation']:>7.2f} {p['client_utilisation']:>8.2f} {p['tasks_per_s']:>8.0f} "
            f"{p['chunk_tasks_per_s']:>8.1f} {p['parquet_files_per_s']:>7.1f} "
            f"{p['shipment_bytes_from_scheduler'] / 1e6:>8.1f} {p['chunk_size_if_batched']:>11}"
        )
    print(
        "   (c (batched): the chunk size if chunks were submitted in batches "
        "at the batched no-op cost; client u: the client process, which tops "
        f"out near {1 / client_task:,.0f} tasks/s on task building alone)"
    )
    for p in proj:
        if p["chunk_size"] is not None:
            print(
                f"   W={p['workers']}: {p['min_tasks_for_4_chunks_per_worker']:,} tasks give "
                f"every worker 4 chunks of {p['chunk_size']}; dse-runner's default "
                f"(chunk_seconds 2.0) would choose {p['default_chunk_size_paper_sweep']} for "
                f"the paper's 1500 tasks, {p['default_chunk_size_1M_task_sweep']} for 1M tasks"
            )
    print(
        f"5. this machine: o/(c t) <= 5% needs c >= {here['chunk_size']} tasks ({here['chunk_wall_s']:.2f} "
        f"s) with o = {o * 1e3:.0f} ms, or c >= {f['chunk_size_for_5pct_here_marginal']} with the marginal "
        f"{marginal * 1e3:.1f} ms; measured above: "
        + ", ".join(
            f"chunk {v['chunk_size']}: {v['overhead_fraction']:.1%}" for _, v in sorted(by_chunk.items())
        )
    )
    print(
        f"   dse-runner chose {r2['chunk_size']} for this 600-task sweep (chunk_seconds "
        "2.0 over the probe's time, capped at pending / (4 x threads)); it would choose "
        f"{chunk_size(t, 2.0, 1500, 2)} for the paper's 1500 at t = {t * 1e3:.1f} ms"
    )
    print(
        f"machine speed: one sin1 simulation took {f['sin1_ms_at_start']:.1f} ms "
        f"at the start of this run and {f['sin1_ms_at_end']:.1f} ms at the end"
    )


if __name__ == "__main__":
    main()
