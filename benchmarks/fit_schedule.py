"""When a fit asks for a candidate's perturbations: with the candidate, or once it is accepted.

sweeps/fit_rounds.py's ``fit_all`` asks for a candidate's perturbations (its Jacobian) with it only when the
cluster has a free thread for every simulation of the round; otherwise a round later, once the candidate is
accepted, so a rejected candidate costs one point instead of one per parameter more. This runs blind diagnosis
cases of tests/support/blind.py (the test suite's form) both ways, side by side, each in a store of its own on
the same local cluster, and prints per case and schedule: the simulations run, the wall time, the CPU seconds
of this process (the diagnosis' client, and the local cluster's scheduler, which runs in it) and of the worker
processes, and whether the diagnosis came out the same to the last digit.

    python3 benchmarks/fit_schedule.py [--cases rolling_resistance,steering_offset,wheel_slip+speed_lag]
                                       [--workers 2] [--out out/fit-schedule]

"eager" makes every round look small enough to ask everything at once (what fit_all did before);
"as shipped" is fit_all's own choice, which on 2 single-threaded workers is to wait for acceptance.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from contextlib import contextmanager, nullcontext
from pathlib import Path

import psutil

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from support import blind

from dse_runner.sweeps import fit_rounds, store
from dse_runner.sweeps.cluster import connect
from dse_runner.sweeps.makers import Cluster


def cluster_cpu() -> float:
    """CPU seconds of this process's children so far: the local cluster's workers and their nannies."""
    total = 0.0
    for child in psutil.Process().children(recursive=True):
        try:
            times = child.cpu_times()
            total += times.user + times.system
        except psutil.Error:
            pass
    return total


@contextmanager
def eager():
    """fit_all as if the cluster had a thread for every simulation of every round."""
    real = fit_rounds.total_threads
    fit_rounds.total_threads = lambda client: sys.maxsize
    try:
        yield
    finally:
        fit_rounds.total_threads = real


def simulations(out: Path) -> int:
    """Rows in the case's store: every simulation its calibration and fits ran."""
    return sum(len(store.read_results(out, sweep, columns=[])) for sweep in store.sweeps(out))


def run(case: str, folder: Path, client) -> dict:
    shutil.rmtree(folder, ignore_errors=True)
    cpu0, client0, started = cluster_cpu(), time.process_time(), time.perf_counter()
    _, _, result = blind.run_case(case, folder.resolve(), client)
    return {
        "wall": time.perf_counter() - started,
        "client": time.process_time() - client0,
        "cluster": cluster_cpu() - cpu0,
        "simulations": simulations(folder / "out"),
        "answer": json.dumps(result.to_json(), sort_keys=True, default=str).replace(
            str(folder.resolve()), "<out>"
        ),
        "named": [e["id"] for e in result.effects],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="rolling_resistance,steering_offset,wheel_slip+speed_lag")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("out/fit-schedule"))
    args = parser.parse_args()
    print(
        f"{'case':<22} {'schedule':<11} {'simulations':>11} {'wall s':>7} {'client CPU s':>12} "
        f"{'workers CPU s':>13} {'total CPU s':>11}  named"
    )
    with connect(Cluster(n_workers=args.workers)) as client:
        blind.run_case("none", (args.out / "warm-up").resolve(), client)  # builds the FMUs, warms the workers
        for case in args.cases.split(","):
            rows = {}
            for schedule in ("eager", "as shipped"):
                with eager() if schedule == "eager" else nullcontext():
                    rows[schedule] = run(case, args.out / case / schedule.replace(" ", "-"), client)
            for schedule, row in rows.items():
                print(
                    f"{case:<22} {schedule:<11} {row['simulations']:>11} "
                    f"{row['wall']:>7.1f} {row['client']:>12.1f} {row['cluster']:>13.1f} "
                    f"{row['client'] + row['cluster']:>11.1f}  {', '.join(row['named'])}"
                )
            first, second = rows.values()
            same = (
                "the same diagnosis to the last digit"
                if first["answer"] == second["answer"]
                else "DIFFERENT answers"
            )
            print(
                f"{case:<22} shipped/eager: simulations {second['simulations'] / first['simulations']:.2f}, "
                f"CPU {(second['client'] + second['cluster']) / (first['client'] + first['cluster']):.2f}, "
                f"wall {second['wall'] / first['wall']:.2f}; {same}"
            )


if __name__ == "__main__":
    main()
