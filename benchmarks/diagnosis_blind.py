"""Blind diagnosis figures: library effects concealed in truth recordings, alone, in pairs, and noise only.

Runs the cases of tests/blind.py on the embedded local cluster and prints one table per kind:

* singles (each library effect, and noise only): what the diagnosis named first, its size against the
  truth, and the held-out mean cross-track error before and after;
* pairs (every pair of library effects): what it named (the chosen set and the runner-up), whether both
  concealed effects are in its top two (the target), held-out error before and after, the noise floor,
  the verdict.

    python3 benchmarks/diagnosis_blind.py [--cases singles|pairs|all] [--form benchmark|tests]
                                          [--workers 2] [--out out/diagnosis-blind]

``--form benchmark`` (the default) records 40 s of every bundled manoeuvre; ``--form tests`` records the
test suite's form (20 s of six runs, and the pairs' synthetic steering steps), so each row is what
tests/test_diagnose.py would see for that case.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import blind  # noqa: E402

from dse_runner.analysis.diagnose.hypotheses import LIBRARY  # noqa: E402
from dse_runner.sweeps.cluster import connect  # noqa: E402
from dse_runner.sweeps.spec import Cluster  # noqa: E402

SINGLES_HEADER = (f"{'concealed':<16} {'truth':>8} {'named first':<16} {'estimate':>9} {'error':>7} "
                  f"{'before [m]':>10} {'after [m]':>10} {'after/before':>12} {'seconds':>8}")
PAIRS_HEADER = (f"{'concealed':<32} {'chosen':<32} {'runner-up':<40} {'top two':>7} {'before [m]':>10} "
                f"{'after [m]':>10} {'floor [m]':>9} {'verdict':<11} {'seconds':>8}")


def run(case: str, args: argparse.Namespace, client):
    """Record and diagnose ``case`` in the chosen form; returns (Diagnosis, seconds)."""
    started = time.perf_counter()
    if args.form == "tests":
        _, _, result = blind.run_case(case, (args.out / case).resolve(), client)
    else:
        _, _, result = blind.run_case(case, (args.out / case).resolve(), client, seconds=blind.BENCHMARK_SECONDS,
                                      runs=blind.benchmark_runs(case))
    return result, time.perf_counter() - started


def single_row(effect: str, result, seconds: float) -> str:
    first = result.effects[0]
    truth = LIBRARY[effect].magnitude(blind.EFFECTS[effect])
    estimate = first.get("magnitude", 0.0)
    error = f"{(estimate / truth - 1) * 100:+.1f}%" if truth else "-"
    ratio = result.cross_track_after / result.cross_track_before
    return (f"{effect:<16} {truth:>8.4g} {first['id']:<16} {estimate:>9.4g} {error:>7} "
            f"{result.cross_track_before:>10.3f} {result.cross_track_after:>10.3f} {ratio:>12.3f} {seconds:>8.1f}")


def pair_row(pair: str, result, seconds: float) -> tuple[str, bool]:
    """The pair's row, and whether both concealed effects are in the top two."""
    chosen = "+".join(e["id"] for e in result.effects)
    up = result.runner_up
    passed = set(blind.CASES[pair].effects) <= set(blind.top_two(result))
    floor = f"{result.floor.cross_track:>9.3f}" if result.floor.available else f"{'-':>9}"
    return (f"{pair:<32} {chosen:<32} {up.other if up else '-':<40} {'yes' if passed else 'NO':>7} "
            f"{result.cross_track_before:>10.3f} {result.cross_track_after:>10.3f} {floor} {result.verdict:<11} "
            f"{seconds:>8.1f}"), passed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", choices=("singles", "pairs", "all"), default="singles")
    parser.add_argument("--form", choices=("benchmark", "tests"), default="benchmark")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("out/diagnosis-blind"))
    args = parser.parse_args()
    with connect(Cluster(n_workers=args.workers)) as client:
        if args.cases in ("singles", "all"):
            print(SINGLES_HEADER, flush=True)
            for effect in blind.EFFECTS:
                print(single_row(effect, *run(effect, args, client)), flush=True)
        if args.cases in ("pairs", "all"):
            print(PAIRS_HEADER, flush=True)
            passed = 0
            for pair in blind.PAIRS:
                row, ok = pair_row(pair, *run(pair, args, client))
                passed += ok
                print(row, flush=True)
            print(f"both effects in the top two: {passed}/{len(blind.PAIRS)}", flush=True)


if __name__ == "__main__":
    main()
