"""A diagnosis' client with its BLAS libraries as they come (a thread per core) against one thread each.

analysis/diagnose/one_thread.py limits the client's linear algebra to one BLAS thread while a diagnosis
runs. This prints, side by side in one run:

* the small problems a diagnosis solves thousands of times (a least-squares solve, PySINDy's STLSQ, a
  bounded least squares), each timed both ways: wall ms and CPU ms per call (spinning threads burn CPU
  that the cluster's workers need), alone and with ``--busy`` processes keeping the cores busy as a
  diagnosis' workers and a test suite do;
* with ``--cases``, blind diagnosis cases of tests/support/blind.py (the test suite's form), both ways on
  one local cluster in stores of their own: wall, the client's CPU, the workers', and whether the two
  answers are the same to the last digit.

    python3 benchmarks/blas_threads.py [--busy 2] [--cases rolling_resistance,wheel_slip+speed_lag]
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fit_schedule import run  # benchmarks/ is not a package: found on the path set above

from dse_runner.analysis.diagnose import one_thread
from dse_runner.analysis.diagnose.sparse_regression import stlsq
from dse_runner.sweeps.cluster import connect
from dse_runner.sweeps.makers import Cluster

ROWS, COLUMNS, CALLS = 3000, 12, 100  # a channel's equation-error rows by its candidate terms


def problems() -> dict[str, callable]:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(ROWS, COLUMNS))
    y = 0.5 * x[:, 0] + 0.2 * x[:, 3] + 0.1 * rng.normal(size=ROWS)
    bound = np.full(COLUMNS, 1.0)
    return {
        "lstsq": lambda: np.linalg.lstsq(x, y, rcond=None),
        "stlsq": lambda: stlsq(x, y, 0.05, unbias=False),
        "lsq_linear": lambda: lsq_linear(x, y, bounds=(-bound, bound), method="trf", lsmr_tol="auto"),
    }


def timed(call) -> tuple[float, float]:
    """Wall and CPU milliseconds per call (this process, every thread)."""
    call()
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(CALLS):
        call()
    return (time.perf_counter() - wall) / CALLS * 1e3, (time.process_time() - cpu) / CALLS * 1e3


def spin(seconds: float) -> None:
    end = time.time() + seconds
    while time.time() < end:
        pass


def micro(busy: int) -> None:
    label = f"{busy} busy processes" if busy else "alone"
    for name, call in problems().items():
        default = timed(call)
        with threadpool_limits(limits=1, user_api="blas"):
            single = timed(call)
        print(
            f"{label:<18} {name:<11} threads as they come: {default[0]:7.2f} ms wall "
            f"{default[1]:7.2f} ms CPU; one thread: {single[0]:6.2f} ms wall {single[1]:6.2f} ms CPU; "
            f"ratio wall {default[0] / single[0]:5.1f}, CPU {default[1] / single[1]:5.1f}"
        )


def cases(names: list[str], out: Path) -> None:
    with connect(Cluster(n_workers=2)) as client:
        run("none", out / "warm-up", client)  # builds the FMUs, warms the workers
        for case in names:
            rows = {}
            for label, threads in (("as they come", None), ("one thread", 1)):
                one_thread.BLAS_THREADS = threads
                try:
                    rows[label] = run(case, out / case / label.replace(" ", "-"), client)
                finally:
                    one_thread.BLAS_THREADS = 1
            for label, row in rows.items():
                print(
                    f"{case:<22} {label:<13} wall {row['wall']:6.1f} s, client CPU {row['client']:5.1f} s, "
                    f"workers CPU {row['cluster']:5.1f} s; named {', '.join(row['named'])}"
                )
            a, b = rows.values()
            same = "the same answer to the last digit" if a["answer"] == b["answer"] else "DIFFERENT answers"
            print(
                f"{case:<22} one/as they come: client CPU {b['client'] / a['client']:.2f}, "
                f"wall {b['wall'] / a['wall']:.2f}; {same}"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--busy", type=int, default=2, help="spinning processes for the busy half")
    parser.add_argument("--cases", default="", help="blind cases to diagnose both ways, comma-separated")
    parser.add_argument("--out", type=Path, default=Path("out/blas-threads"))
    args = parser.parse_args()
    micro(0)
    if args.busy:
        spinners = [multiprocessing.Process(target=spin, args=(600,)) for _ in range(args.busy)]
        for p in spinners:
            p.start()
        try:
            micro(args.busy)
        finally:
            for p in spinners:
                p.terminate()
    if args.cases:
        cases(args.cases.split(","), args.out.resolve())


if __name__ == "__main__":
    main()
