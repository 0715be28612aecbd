"""Physics inside the model: each case diagnosed from its recordings, then its held-back record predicted.

Runs ``diagnose --space`` (signal_library.diagnose_space) on each case into a fresh folder on a local cluster
of ``--workers`` workers, as a user would, and prints per case: the wall-clock seconds, what was named (terms
inside the model in the user's words, effects outside it), what was dropped or decided against a
look-alike, the held-out error before and after (noise floors), and the error on the case's held-back test
record, simulated from its input alone with the diagnosed values (free-running from the fitted initial
state): the position, and for the generated cases the velocity against the generator's noise-free truth,
which no diagnosis reads.

The cases: the generated mass-spring-dampers of ``jobs/msd/physics`` (make_physics_runs.py: position only,
quantised, coloured noise, an unknown initial state, drift): ``hardening`` (a cubic spring), ``friction``
(a stage with dry friction and no spring), ``plain`` (nothing missing); and the real Cascaded Tanks'
estimation record (its test record is held back from this project: only the held-out blocks are shown).

    PYTHONPATH=. python3 benchmarks/diagnosis_physics.py [CASE ...] [--workers 2] [--out DIR]
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from dse_runner.analysis.diagnose.signal_library import diagnose_space
from dse_runner.simulation.run import simulate

REPO = Path(__file__).resolve().parents[1]
CASES = {
    "hardening": REPO / "jobs" / "msd" / "physics" / "hardening",
    "friction": REPO / "jobs" / "msd" / "physics" / "friction",
    "plain": REPO / "jobs" / "msd" / "physics" / "plain",
    "tanks": REPO / "jobs" / "cascaded_tanks",
}


def named(found: dict) -> list[str]:
    """Each named effect or term as one line: a term as its formula and meaning."""
    lines = []
    for e in (e for e in found["effects"] if e["id"] != "none"):
        if e.get("readable"):
            low, high = e["interval"]["coefficient"]
            lines.append(f"{e['readable'][0]} (coefficient 95 % {low:.4g} to {high:.4g})")
            continue
        into = f" into {e['into']}" if e.get("into") else ""
        values = ", ".join(f"{k} {v:.4g}" for k, v in e["parameters"].items())
        lines.append(f"{e['id']}({e['target']}){into}: {values}")
    return lines or ["nothing"]


def predicted(folder: Path, values: dict) -> dict[str, float]:
    """The diagnosed model on the held-back record ``folder/test``: its position error (the recording's
    column) and, where the generator wrote it, its velocity error against the truth."""
    test = folder / "test"
    if not test.is_dir():
        return {}
    run = simulate(REPO / "jobs" / "msd" / "multimodel.yaml", test, values)
    found = {name: float(v) for name, v in run.objectives.items() if isinstance(v, float)}
    truth = test / "velocity.csv"
    if truth.is_file():
        t, v = np.loadtxt(truth, delimiter=",", skiprows=1, unpack=True)
        simulated = np.interp(t, run.trajectory.time, run.outputs["msd.v"])
        found["v_rmse"] = float(np.sqrt(np.mean((simulated - v) ** 2)))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", metavar="CASE", help=f"of {', '.join(CASES)} (default: all)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("out/diagnosis-physics"))
    parser.add_argument("--verbose", action="store_true", help="the diagnosis' progress on stderr")
    args = parser.parse_args()
    unknown = [c for c in args.cases if c not in CASES]
    if unknown:
        parser.error(f"unknown case {', '.join(unknown)}: the cases are {', '.join(CASES)}")
    for case in args.cases or list(CASES):
        out = (args.out / case).resolve()
        shutil.rmtree(out, ignore_errors=True)  # a fresh store: the time is the whole diagnosis's
        started = time.perf_counter()

        def say(message: str, started: float = started) -> None:
            print(f"  [{time.perf_counter() - started:5.0f} s] {message}", file=sys.stderr, flush=True)

        found = diagnose_space(
            CASES[case] / "space.yaml", out=out, n_workers=args.workers, say=say if args.verbose else None
        ).to_json()
        seconds = time.perf_counter() - started
        noise = found["case"]["compared"][0]["noise"]
        before = predicted(CASES[case], found["calibrated"]["parameters"])
        after = predicted(CASES[case], found["fitted"]["parameters"])
        print(f"== {case}: {seconds:.0f} s on {args.workers} workers; noise floor {noise:.3g}")
        print("  named: " + "\n         ".join(named(found)))
        for d in found["dropped"]:
            print(f"  not claimed: {d['id']} ({d['rule']})")
        for d in found["case"]["decided"]:
            print(f"  decided: {d['winner']} over its look-alike {d['lookalike']}, held-out {d['held_out']}")
        if found["fitted"]["at_bound"]:
            print(f"  at a bound, not an estimate: {', '.join(found['fitted']['at_bound'])}")
        if found["proof"]:
            proof = found["proof"]
            print(
                f"  proof: {proof['agree']} of {len(proof['folds'])} folds chose the terms again among "
                f"{proof['offered']}; each fold's own choice {proof['folds']}"
            )
        print(
            f"  held-out: {found['held_out_before']:.3g} -> {found['held_out_after']:.3g} noise floors "
            f"({found['held_out_before'] / found['held_out_after']:.1f}x); verdict {found['verdict']}"
        )
        for name in after:
            was = before.get(name, math.nan)
            print(f"  test record {name}: {was:.4g} plain calibrated -> {after[name]:.4g} diagnosed")


if __name__ == "__main__":
    main()
