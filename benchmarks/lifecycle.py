"""What the safe lifecycle costs per run: the same simulations with one instance reset between runs, and
with a fresh process per run (lifecycle.py, isolation.py), side by side.

    python benchmarks/lifecycle.py [--repeats 20] [--json]

Cases:

* ``cheap``: the vanderpol FMU alone (benchmarks/fmus/vanderpol), 0..20 s by 1e-2 s: the FMU costs
  almost nothing, so the difference is the lifecycle's own cost;
* ``robotti``: one Robotti scenario (sin1), controller and vehicle, calibrated values;
* ``three_tank``: INTO-CPS's three-tank multi-model (../shared/fmus-wild, Non-3D, 0..30 s by 0.05 s), whose
  20-sim and Overture FMUs declare one instance per process: fresh processes only (reset is not safe).

Each figure is the median wall time per run, in seconds, in one process, after a warm-up run (which starts
the thread's zygote). ``fork_round_trip`` is a fresh process that runs nothing (isolation.run of a no-op):
the floor of the safe lifecycle. Nothing is asserted; the ratios are printed beside the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's dse_runner

from dse_runner import bundled
from dse_runner.simulation import isolation
from dse_runner.simulation.build import build_fmu
from dse_runner.simulation.multimodel import MultiModel, load_multimodel, single_fmu
from dse_runner.simulation.run import as_plan, simulate
from dse_runner.simulation.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]

WILD = REPO.parent / "shared" / "fmus-wild"
THREE_TANK = WILD / "three_tank_watertank" / "Multi-models" / "Non-3D" / "Non-3D.mm.json"
CALIBRATED = {"vehicle.mass": 1000.0, "vehicle.cAlphaF": 38000.0, "vehicle.mu": 0.3}


def median_time(run: Callable[[], object], repeats: int) -> float:
    run()  # warm-up: extraction, the verdict, the zygote
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def in_fresh_processes(multimodel: MultiModel) -> MultiModel:
    """The same multi-model with every instance asking for a fresh process per run."""
    return multimodel.model_copy(
        update={
            "instances": {
                name: multimodel.settings(name).model_copy(update={"lifecycle": "process"})
                for name in multimodel.fmus
            }
        }
    )


def both(multimodel: MultiModel, run: Callable, repeats: int) -> dict[str, float]:
    reset, fresh = as_plan(multimodel), as_plan(in_fresh_processes(multimodel))
    figures = {
        "reset": median_time(lambda: run(reset), repeats),
        "process": median_time(lambda: run(fresh), repeats),
    }
    assert not run(reset).fresh_process and run(fresh).fresh_process  # each ran the way it says
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    repeats = args.repeats
    results: dict[str, dict[str, float]] = {}
    results["fork_round_trip"] = {"process": median_time(lambda: isolation.run(os.getpid), repeats)}
    cheap = single_fmu(build_fmu(REPO / "benchmarks" / "fmus" / "vanderpol"))
    results["cheap"] = both(cheap, lambda plan: simulate(plan, values={"mu": 1.5}), repeats)
    robotti = load_multimodel(bundled.bundled_path("bundled:robotti/multimodel.yaml"))
    sin1 = load_scenario(REPO / "scenarios" / "robotti" / "sin1")
    results["robotti"] = both(robotti, lambda plan: simulate(plan, sin1, CALIBRATED), repeats)
    if THREE_TANK.is_file():
        plan = as_plan(THREE_TANK)
        results["three_tank"] = {
            "process": median_time(lambda: simulate(plan, stop_time=30, step=0.05), repeats)
        }
    for case in results.values():
        if "reset" in case:
            case["added_per_run"] = case["process"] - case["reset"]
            case["process_over_reset"] = case["process"] / case["reset"]
    if args.json:
        print(json.dumps(results, indent=2))
        return
    print(f"milliseconds per run, median of {repeats}, one process (a worker's view)")
    print(f"  {'case':<16}{'reset':>10}{'process':>10}{'added':>10}{'ratio':>9}")
    for name, case in results.items():
        reset = f"{case['reset'] * 1e3:10.3f}" if "reset" in case else f"{'-':>10}"
        added = (
            f"{case['added_per_run'] * 1e3:10.3f}{case['process_over_reset']:8.1f}x"
            if "reset" in case
            else ""
        )
        print(f"  {name:<16}{reset}{case['process'] * 1e3:10.3f}{added}")


if __name__ == "__main__":
    main()
