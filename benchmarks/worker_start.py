"""What starting a local cluster's workers costs the command line: spawned, or forked from a forkserver.

``dse-runner`` forks its local cluster's workers from a forkserver that imported Dask, pandas, pyarrow, FMPy
and dse-runner once (sweeps/start_method.py, ``fork_local_workers``); spawned, each worker imports them
itself. This submits the same small sweep (3 points of the Robotti on 2 recorded runs) both ways, in turns,
with 2 and with 4 workers, and prints per run the wall time and the CPU seconds of the command and every
process it started (a cpuacct control group per command, as root), then the mean of each and their ratio.
Spawn is chosen with ``DASK_DISTRIBUTED__WORKER__MULTIPROCESSING_METHOD``, which the command then leaves
alone (with that variable at ``forkserver`` it would use Dask's own server, which imports less); the
forkserver is the command's default.

    python3 benchmarks/worker_start.py [--rounds 4] [--workers 2,4] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from test_suite import close_group, own_group  # benchmarks/, this script's folder, is on sys.path

from dse_runner.sweeps.start_method import START_METHOD_VARIABLE as VARIABLE

REPO = Path(__file__).resolve().parents[1]
METHODS = ("spawn", "forkserver")


def space(folder: Path, workers: int) -> Path:
    """A sweep of 3 points × 2 recorded runs on a local cluster of ``workers``."""
    runs = [str(REPO / "scenarios" / "robotti" / name) for name in ("sin1", "sin2")]
    path = folder / f"space-{workers}.yaml"
    path.write_text(
        json.dumps(
            {
                "name": "worker-start",
                "multimodel": "bundled:robotti/multimodel.yaml",
                "scenarios": runs,
                "parameters": {"vehicle.mass": [1000, 2000, 3000]},
                "objectives": ["cross_track_error"],
                "output": str(folder / f"out-{workers}"),
                "cluster": {"n_workers": workers},
            }
        )
    )
    return path


def measured(command: list[str], env: dict[str, str], label: str) -> tuple[float, float | None]:
    """(wall s, CPU s of the command and its descendants, or None without a control group)."""
    group = own_group(f"dse-worker-start-{label}")
    started = time.perf_counter()
    join = (lambda: (group / "tasks").write_text(str(os.getpid()))) if group else None  # run in the child
    done = subprocess.run(command, check=False, env=env, capture_output=True, text=True, preexec_fn=join)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"{' '.join(command)} failed:\n{done.stderr}")
    return wall, close_group(group)  # once the forkserver, which may outlive the command a moment, has ended


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--workers", default="2,4", help="comma-separated cluster sizes")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    dse_runner = shutil.which("dse-runner", path=str(Path(sys.executable).parent)) or "dse-runner"
    folder = Path(tempfile.mkdtemp(prefix="worker-start-"))
    rows = []
    try:
        for workers in map(int, args.workers.split(",")):
            spec = space(folder, workers)
            for k in range(args.rounds):
                for method in METHODS:  # in turns: the machine's drift falls on both alike
                    shutil.rmtree(folder / f"out-{workers}", ignore_errors=True)
                    env = {key: value for key, value in os.environ.items() if key != VARIABLE}
                    wall, cpu = measured(
                        [dse_runner, "submit", str(spec)],
                        {**env, VARIABLE: method} if method == "spawn" else env,
                        f"{workers}-{method}-{k}",
                    )
                    rows.append(
                        {
                            "workers": workers,
                            "method": method,
                            "wall_s": round(wall, 2),
                            "cpu_s": None if cpu is None else round(cpu, 2),
                        }
                    )
                    if not args.json:
                        print(
                            f"{workers} workers, {method:10s}: {wall:5.2f} s wall, "
                            f"{'-' if cpu is None else f'{cpu:.2f}'} CPU s",
                            flush=True,
                        )
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    summary = []
    for workers in sorted({r["workers"] for r in rows}):
        mean = {
            m: {
                key: _mean([r[key] for r in rows if r["workers"] == workers and r["method"] == m])
                for key in ("wall_s", "cpu_s")
            }
            for m in METHODS
        }
        ratio = {
            key: round(mean["forkserver"][key] / mean["spawn"][key], 2) if mean["spawn"][key] else None
            for key in ("wall_s", "cpu_s")
        }
        summary.append(
            {
                "workers": workers,
                "spawn": mean["spawn"],
                "forkserver": mean["forkserver"],
                "forkserver/spawn": ratio,
            }
        )
    if args.json:
        print(json.dumps({"runs": rows, "summary": summary}))
        return
    for s in summary:
        spawn, fork, ratio = s["spawn"], s["forkserver"], s["forkserver/spawn"]
        print(
            f"{s['workers']} workers: spawn {spawn['wall_s']} s wall, {spawn['cpu_s']} CPU s; "
            f"forkserver {fork['wall_s']} s, {fork['cpu_s']} CPU s; "
            f"forkserver/spawn: wall {ratio['wall_s']}, CPU {ratio['cpu_s']}"
        )


def _mean(values: list[float | None]) -> float | None:
    return None if None in values else round(statistics.mean(values), 2)


if __name__ == "__main__":
    main()
