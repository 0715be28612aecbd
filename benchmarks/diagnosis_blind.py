"""Blind diagnosis figures: concealed effects alone, in pairs, outside the library, and noise only.

Runs the cases of tests/support/blind.py on the embedded local cluster and prints one table per kind:

* singles (each library effect, and noise only): what the diagnosis named first, its size against the
  truth, and the held-out mean cross-track error before and after;
* pairs (every pair of library effects): what it named (the chosen set and the runner-up), whether both
  concealed effects are in its top two (the target), held-out error before and after, the noise floor,
  the verdict;
* outside the library (tests/fmus/robotti_truth: a tyre relaxation length, a steering gain falling with
  speed, a payload lowered mid-run, a leaning antenna mast, rolling resistance on soft soil, and, the
  benchmark's only, slip growing with the pull and a steering rate limit): what it named, the verdict,
  whether the effects are flagged partial, any discovered terms, held-out error before and after, the noise
  floor;
* noise only (heavier: 5 cm, 10 % dropouts, two 5 s outages; coloured): what it named, the estimated noise
  against the truth's, held-out error before and after, the verdict.

    python3 benchmarks/diagnosis_blind.py [--cases singles,pairs,ool,noise|all] [--only NAME,...]
                                          [--form benchmark|tests] [--workers 2] [--out out/diagnosis-blind]

``--form benchmark`` (the default) records 40 s of every bundled manoeuvre; ``--form tests`` records the
test suite's form (20 s of six runs, and each case's synthetic runs), so each row is what
tests/cases/test_diagnose.py would see for that case. ``--only`` keeps the named cases of the chosen kinds.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from support import blind

from dse_runner.cases.robotti_diagnosis.hypotheses import LIBRARY
from dse_runner.sweeps.cluster import connect
from dse_runner.sweeps.makers import Cluster

SINGLES_HEADER = (
    f"{'concealed':<16} {'truth':>8} {'named first':<16} {'estimate':>9} {'error':>7} "
    f"{'before [m]':>10} {'after [m]':>10} {'after/before':>12} {'seconds':>8}"
)
PAIRS_HEADER = (
    f"{'concealed':<32} {'chosen':<32} {'runner-up':<40} {'top two':>7} {'before [m]':>10} "
    f"{'after [m]':>10} {'floor [m]':>9} {'verdict':<11} {'seconds':>8}"
)
OUTSIDE_HEADER = (
    f"{'concealed':<17} {'truth':<48} {'named':<40} {'verdict':<11} {'partial':>7} "
    f"{'before [m]':>10} {'library [m]':>11} {'after [m]':>10} {'floor [m]':>9} {'pass':>4} "
    f"{'seconds':>8}  discovered terms | resembles"
)
NOISE_HEADER = (
    f"{'case':<15} {'receiver':<36} {'named':<24} {'sigma [m]':>9} {'estimate':>9} "
    f"{'before [m]':>10} {'after [m]':>10} {'floor [m]':>9} {'verdict':<11} {'pass':>4} {'seconds':>8}"
)


def run(case: str, args: argparse.Namespace, client):
    """Record and diagnose ``case`` in the chosen form; returns (Diagnosis, seconds)."""
    started = time.perf_counter()
    if args.form == "tests":
        _, _, result = blind.run_case(case, (args.out / case).resolve(), client)
    else:
        _, _, result = blind.run_case(
            case,
            (args.out / case).resolve(),
            client,
            seconds=blind.BENCHMARK_SECONDS,
            runs=blind.benchmark_runs(case),
        )
    return result, time.perf_counter() - started


def single_row(effect: str, result, seconds: float) -> str:
    first = result.effects[0]
    truth = LIBRARY[effect].magnitude(blind.EFFECTS[effect])
    estimate = first.get("magnitude", 0.0)
    error = f"{(estimate / truth - 1) * 100:+.1f}%" if truth else "-"
    ratio = result.held_out_after / result.held_out_before
    return (
        f"{effect:<16} {truth:>8.4g} {first['id']:<16} {estimate:>9.4g} {error:>7} "
        f"{result.held_out_before:>10.3f} {result.held_out_after:>10.3f} {ratio:>12.3f} {seconds:>8.1f}"
    )


def pair_row(pair: str, result, seconds: float) -> tuple[str, bool]:
    """The pair's row, and whether both concealed effects are in the top two."""
    chosen = "+".join(e["id"] for e in result.effects)
    up = result.runner_up
    passed = set(blind.CASES[pair].effects) <= set(blind.top_two(result))
    floor = f"{result.floor.cross_track:>9.3f}" if result.floor.available else f"{'-':>9}"
    return (
        f"{pair:<32} {chosen:<32} {up.other if up else '-':<40} {'yes' if passed else 'NO':>7} "
        f"{result.held_out_before:>10.3f} {result.held_out_after:>10.3f} {floor} {result.verdict:<11} "
        f"{seconds:>8.1f}"
    ), passed


def floor_of(result) -> str:
    return f"{result.floor.cross_track:>9.3f}" if result.floor.available else f"{'-':>9}"


def discovered(result) -> str:
    """The discovered terms' readable text, or '-' (none yet: discovery is a later step of issue 18)."""
    terms = [
        t.get("text", "?") for e in result.effects if e["id"] == "discovered" for t in e.get("terms", [])
    ]
    return "; ".join(terms) or "-"


def outside_row(name: str, result, seconds: float) -> str:
    """What the diagnosis made of an effect outside its library: the effects it named (the chosen set, then
    the runner-up), the verdict, whether every library effect named is partial, held-out error of the
    calibrated model (before), of the library's best and of the chosen model (after), whether the issue's
    target is met (blind.outside_target), then the discovered terms and what they resemble."""
    truth = ", ".join(f"{k}={v:g}" for k, v in blind.CASES[name].truth.items())
    up = result.runner_up.other if result.runner_up else "-"
    named = "+".join(e["id"] for e in result.effects) + f" ({up})"
    library = [e for e in result.effects if e["id"] not in ("none", "discovered")]
    partial = "-" if not library else "yes" if all(e.get("partial") for e in library) else "NO"
    found = blind.discovered_entry(result)
    best = found["held_out_without"] if found else result.held_out_after
    resembles = found["resembles"]["text"] if found and found.get("resembles") else "-"
    return (
        f"{name:<17} {truth:<48} {named:<40} {result.verdict:<11} {partial:>7} "
        f"{result.held_out_before:>10.3f} {best:>11.3f} {result.held_out_after:>10.3f} "
        f"{floor_of(result)} {'yes' if blind.outside_target(result) else 'no':>4} "
        f"{seconds:>8.1f}  {discovered(result)} | {resembles}"
    )


def noise_row(name: str, result, seconds: float) -> str:
    """Noise only: the named effects (the target is none), the estimated noise against the truth's."""
    case = blind.CASES[name]
    receiver = (
        f"{case.noise * 100:g} cm, {case.dropout * 100:g} % drops, {case.outages}x{case.outage_s:g} s"
        + (f", rho {case.colour:g}" if case.colour else "")
    )
    named = "+".join(e["id"] for e in result.effects) + ("+discovered" if discovered(result) != "-" else "")
    estimate = f"{result.floor.sigma:>9.4f}" if result.floor.available else f"{'-':>9}"
    return (
        f"{name:<15} {receiver:<36} {named:<24} {case.noise:>9.4f} {estimate} "
        f"{result.held_out_before:>10.3f} {result.held_out_after:>10.3f} {floor_of(result)} "
        f"{result.verdict:<11} {'yes' if blind.noise_target(result, case.noise) else 'no':>4} {seconds:>8.1f}"
    )


def chosen(names, only: set[str] | None) -> list[str]:
    return [n for n in names if only is None or n in only]


KINDS = ("singles", "pairs", "ool", "noise")


def kinds(text: str) -> set[str]:
    """``--cases``: comma-separated kinds, ``all`` for every one."""
    chosen = set(text.split(","))
    if "all" in chosen:
        return set(KINDS)
    if not chosen <= set(KINDS):
        raise argparse.ArgumentTypeError(
            f"unknown kinds {', '.join(sorted(chosen - set(KINDS)))}: there is {', '.join(KINDS)} and all"
        )
    return chosen


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cases",
        type=kinds,
        default={"singles"},
        help="comma-separated kinds: singles, pairs, ool, noise, or all",
    )
    parser.add_argument(
        "--only",
        type=lambda text: set(text.split(",")),
        default=None,
        help="comma-separated case names to keep, of the chosen kinds",
    )
    parser.add_argument("--form", choices=("benchmark", "tests"), default="benchmark")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("out/diagnosis-blind"))
    args = parser.parse_args()
    tables = {  # kind: header, its cases, a row of one
        "singles": (SINGLES_HEADER, blind.EFFECTS, single_row),
        "ool": (OUTSIDE_HEADER, blind.OUTSIDE, outside_row),
        "noise": (NOISE_HEADER, ["none", *blind.NOISE_CASES], noise_row),
    }
    with connect(Cluster(n_workers=args.workers)) as client:
        for kind in KINDS:
            if kind not in args.cases:
                continue
            if kind == "pairs":  # rows that also count the cases passed
                print(PAIRS_HEADER, flush=True)
                passed, pairs = 0, chosen(blind.PAIRS, args.only)
                for pair in pairs:
                    row, ok = pair_row(pair, *run(pair, args, client))
                    passed += ok
                    print(row, flush=True)
                print(f"both effects in the top two: {passed}/{len(pairs)}", flush=True)
                continue
            header, names, row_of = tables[kind]
            print(header, flush=True)
            for name in chosen(names, args.only):
                print(row_of(name, *run(name, args, client)), flush=True)


if __name__ == "__main__":
    main()
