"""What compiling the checkout's modules once saves each process that imports dse-runner.

An editable install (`.ci/install`) leaves dse_runner/ as source, and where ``PYTHONDONTWRITEBYTECODE`` is
set no process writes the bytecode it compiles: every Dask worker and every command compiles again what it
imports. `.ci/install` therefore compiles them once (``compileall``), as pip does for an installed wheel.
This runs the same commands both ways, in turns: a small ``submit`` (3 points of the Robotti on 2 recorded
runs, a local cluster of 2 workers, spawned and forked from the forkserver) and a ``simulate``, each in a
cpuacct control group of its own (as root), and prints the mean CPU seconds of each and their ratio. It
leaves dse_runner/ compiled, as `.ci/install` does.

    python3 benchmarks/bytecode.py [--rounds 4] [--json]
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
from pathlib import Path

from worker_start import VARIABLE, measured, space  # benchmarks/, this script's folder, is on sys.path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "dse_runner"
STATES = ("source", "compiled")


def set_bytecode(compiled: bool) -> None:
    """dse_runner/ with no bytecode at all, or compiled the way `.ci/install` compiles it."""
    for cache in list(PACKAGE.rglob("__pycache__")):
        shutil.rmtree(cache)
    if compiled:
        subprocess.run(
            [sys.executable, "-m", "compileall", "-q", str(PACKAGE)], check=True, stdout=subprocess.DEVNULL
        )


def commands(dse_runner: str, spec: Path) -> dict[str, tuple[list[str], dict[str, str]]]:
    """Each measured command, by label, with its environment (``PYTHONDONTWRITEBYTECODE`` set)."""
    env = {key: value for key, value in os.environ.items() if key != VARIABLE}
    env["PYTHONDONTWRITEBYTECODE"] = (
        "1"  # as on this machine; without it the first run would write the bytecode
    )
    submit = [dse_runner, "submit", str(spec)]
    simulate = [
        dse_runner,
        "simulate",
        "bundled:robotti/multimodel.yaml",
        "--scenario",
        str(REPO / "scenarios" / "robotti" / "sin1"),
    ]
    return {
        "submit, spawned workers": (submit, {**env, VARIABLE: "spawn"}),
        "submit, forked workers": (submit, env),
        "simulate": (simulate, env),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    dse_runner = shutil.which("dse-runner", path=str(Path(sys.executable).parent)) or "dse-runner"
    folder = Path(tempfile.mkdtemp(prefix="bytecode-"))
    cpu: dict[tuple[str, str], list[float]] = {}
    try:
        measures = commands(dse_runner, space(folder, 2))
        for k in range(args.rounds):
            for state in STATES:  # in turns: the machine's drift falls on both alike
                set_bytecode(state == "compiled")
                for label, (command, env) in measures.items():
                    shutil.rmtree(folder / "out-2", ignore_errors=True)
                    _, seconds = measured(command, env, f"{state}-{k}")
                    if seconds is None:
                        sys.exit("no cpuacct control group could be made (run as root)")
                    cpu.setdefault((label, state), []).append(round(seconds, 2))
                    if not args.json:
                        print(f"{label:24s} {state:8s}: {seconds:.2f} CPU s", flush=True)
    finally:
        set_bytecode(True)
        shutil.rmtree(folder, ignore_errors=True)
    summary = {
        label: {state: round(statistics.mean(cpu[label, state]), 2) for state in STATES} for label, _ in cpu
    }
    for figures in summary.values():
        figures["compiled/source"] = round(figures["compiled"] / figures["source"], 2)
    if args.json:
        print(
            json.dumps(
                {
                    "runs": {f"{label}, {state}": values for (label, state), values in cpu.items()},
                    "summary": summary,
                }
            )
        )
        return
    for label, figures in summary.items():
        print(
            f"{label}: source {figures['source']} CPU s, compiled {figures['compiled']} CPU s, "
            f"compiled/source {figures['compiled/source']}"
        )


if __name__ == "__main__":
    main()
