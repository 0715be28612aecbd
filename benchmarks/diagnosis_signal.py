"""Blind diagnosis of any model: the mass-spring-damper's concealed cases, and how long each takes.

Each case of jobs/msd/make_diagnosis_runs.py (four runs of 10 s, a force input, 2 mm of noise on the
position) is recorded into its own folder and diagnosed from the recordings alone by
``diagnose --space`` (signal_library.diagnose_space) on a local cluster; the truth is read only to print
beside the answer. One row per case: what was concealed, what was named with its ~95 % interval,
held-out error before and after (noise floors), the verdict and the wall-clock seconds.

    PYTHONPATH=. python3 benchmarks/diagnosis_signal.py [--cases clean,force-late,sensor-gain-offset]
                                                         [--workers 2] [--out out/diagnosis-signal]
"""

from __future__ import annotations

import argparse
import importlib.util
import time
from pathlib import Path

from dse_runner.analysis.diagnose.signal_library import diagnose_space

REPO = Path(__file__).resolve().parents[1]
HEADER = (
    f"{'case':<20} {'concealed':<44} {'named (95 % interval)':<72} {'before':>7} {'after':>6} "
    f"{'verdict':<11} {'seconds':>7}"
)


def generator():
    spec = importlib.util.spec_from_file_location(
        "make_diagnosis_runs", REPO / "jobs/msd/make_diagnosis_runs.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def end(value: float | None) -> str:
    """An interval's end as the JSON holds it: null where the data do not bound it."""
    return "–" if value is None else f"{value:.4g}"


def named(found: dict) -> str:
    parts = []
    for e in (e for e in found["effects"] if e["id"] != "none"):
        sized = ", ".join(
            f"{value:.4g} [{', '.join(end(x) for x in e['interval'][kind])}]"
            for kind, value in e["parameters"].items()
        )
        parts.append(f"{e['id']}({e.get('target') or ''}) {sized}")
    return "; ".join(parts) or "nothing"


def main() -> None:
    make = generator()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default=",".join(make.CASES))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("out/diagnosis-signal"))
    args = parser.parse_args()
    print(HEADER)
    for case in args.cases.split(","):
        space = make.make(case, (args.out / case).resolve())
        started = time.perf_counter()
        found = diagnose_space(space, n_workers=args.workers).to_json()
        seconds = time.perf_counter() - started
        concealed = ", ".join(f"{k} {v:g}" for k, v in make.CASES[case].items()) or "nothing"
        print(
            f"{case:<20} {concealed:<44} {named(found):<72} {found['held_out_before']:>7.2f} "
            f"{found['held_out_after']:>6.2f} {found['verdict']:<11} {seconds:>7.0f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
