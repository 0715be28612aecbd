"""Blind diagnosis figures: every library effect concealed in truth recordings, and noise only.

Runs the same cases as tests/test_diagnose.py on the embedded local cluster and prints, per
case, what the diagnosis named, its size against the truth, and the held-out mean
cross-track error before and after.

    python3 benchmarks/diagnosis_blind.py [--workers 2] [--out out/diagnosis-blind]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import blind  # noqa: E402

from dse_runner.sweeps.cluster import connect  # noqa: E402
from dse_runner.analysis.diagnose.hypotheses import LIBRARY  # noqa: E402
from dse_runner.sweeps.spec import Cluster  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("out/diagnosis-blind"))
    args = parser.parse_args()
    print(f"{'concealed':<16} {'truth':>8} {'named first':<16} {'estimate':>9} {'error':>7} "
          f"{'before [m]':>10} {'after [m]':>10} {'after/before':>12} {'seconds':>8}")
    with connect(Cluster(n_workers=args.workers)) as client:
        for effect in blind.EFFECTS:
            started = time.perf_counter()
            _, _, result = blind.run_case(effect, (args.out / effect).resolve(), client,
                                          seconds=blind.BENCHMARK_SECONDS, runs=blind.BENCHMARK_RUNS)
            seconds = time.perf_counter() - started
            first = result.effects[0]
            truth = LIBRARY[effect].magnitude(blind.EFFECTS[effect])
            estimate = first.get("magnitude", 0.0)
            error = f"{(estimate / truth - 1) * 100:+.1f}%" if truth else "-"
            ratio = result.cross_track_after / result.cross_track_before
            print(f"{effect:<16} {truth:>8.4g} {first['id']:<16} {estimate:>9.4g} {error:>7} "
                  f"{result.cross_track_before:>10.3f} {result.cross_track_after:>10.3f} {ratio:>12.3f} "
                  f"{seconds:>8.1f}", flush=True)


if __name__ == "__main__":
    main()
