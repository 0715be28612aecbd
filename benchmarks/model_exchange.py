"""Model exchange in the native loop (native_me.c) against the Python loop and FMPy, side by side.

    python benchmarks/model_exchange.py [--repeats 20] [--json]

Three cases, each a model-exchange FMU under CVode:

* ``msd_pushed``: the mass-spring-damper (jobs/msd, tolerance 1e-6) pushed by a force log with steps, held
  between samples (each step an input event), 10 s at a 0.025 s step: the shape of the blind diagnosis runs;
* ``ball``: the bouncing ball (tests/fmus/ball): state events (bounces) and a time
  event (a kick), 2 s at 0.01 s;
* ``msd_terms``: ``msd_pushed`` with two derivative terms (x^3 and F·tanh(v/0.1)), as derivative discovery's
  fits run it.

Per case, the median wall time per simulation of:

* ``native``: ``simulate(..., loop="native")``, the plan, scenario and instances made once and reused across
  runs, as a sweep's worker does;
* ``python``: the same master with ``loop="python"``: FMPy's CVodeSolver, its
  right-hand side a Python callback;
* ``simulate_fmu``: FMPy's ``simulate_fmu`` per run as a user would write it, CVode at the same tolerance and
  output interval, the force as an input table (not for the terms, which are ours).

Printed with the ratios python/native and simulate_fmu/native, and whether the native and Python trajectories
are bit-identical (they must be: tests/simulation/test_native_loop.py). ``--json`` prints the figures as JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's dse_runner

from cosim import median_time  # benchmarks/cosim.py: a warm-up, then the median

from dse_runner.simulation.build import build_fmu
from dse_runner.simulation.run import as_plan, simulate
from dse_runner.simulation.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]

MSD = REPO / "jobs" / "msd" / "multimodel.yaml"
BALL = REPO / "tests" / "fmus" / "ball"
FORCE = [(0.0, 0.0), (1.0, 2.0), (3.0, 0.0), (5.0, -1.0), (7.0, 0.0), (8.0, 1.5), (9.0, 0.0)]  # s, N
TERMS = {"derivative_term(msd.der(v), x^3)": -40.0, "derivative_term(msd.der(v), F*tanh(v/0.1))": 0.3}


def pushed_scenario(folder: Path) -> Path:
    (folder / "force.csv").write_text("time,F\n" + "".join(f"{t},{f}\n" for t, f in FORCE))
    scenario = folder / "pushed"
    scenario.mkdir()
    (scenario / "scenario.yaml").write_text(
        "name: pushed\ninputs:\n  msd.F: {csv: ../force.csv, interpolation: hold}\n"
    )
    return scenario


def fmpy_run(
    path: Path, stop: float, step: float, outputs: list[str], values: dict | None = None, force: bool = False
) -> Callable[[], object]:
    from fmpy import simulate_fmu

    signal = None
    if force:  # held: each sample repeated at the next one's time, as FMPy's input table steps
        rows = [
            row
            for (t, f), (t_next, _) in zip(FORCE, [*FORCE[1:], (stop, 0.0)])
            for row in ((t, f), (t_next, f))
        ]
        signal = np.array(rows, dtype=[("time", float), ("F", float)])
    return lambda: simulate_fmu(
        str(path),
        solver="CVode",
        stop_time=stop,
        output_interval=step,
        relative_tolerance=1e-6,
        start_values=values or {},
        input=signal,
        output=outputs,
        record_events=False,
    )


def case(
    model, scenario, values: dict, stop: float, step: float, repeats: int, fmpy: Callable[[], object] | None
) -> dict:
    def ours(loop: str) -> Callable[[], object]:
        return lambda: simulate(model, scenario, values, stop_time=stop, step=step, loop=loop)

    native, python = ours("native")(), ours("python")()
    figures = {"native": median_time(ours("native"), repeats), "python": median_time(ours("python"), repeats)}
    if fmpy is not None:
        figures["simulate_fmu"] = median_time(fmpy, max(3, repeats // 4))
    figures["python_over_native"] = figures["python"] / figures["native"]
    if fmpy is not None:
        figures["simulate_fmu_over_native"] = figures["simulate_fmu"] / figures["native"]
    figures["bit_identical"] = native.trajectory.values.tobytes() == python.trajectory.values.tobytes()
    figures["steps"] = len(native.time) - 1
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as work:
        folder = Path(work)
        pushed = load_scenario(pushed_scenario(folder))
        msd, msd_fmu = as_plan(MSD), build_fmu(REPO / "jobs" / "msd" / "fmus" / "msd")
        ball = folder / "ball.fmu"
        ball.write_bytes(build_fmu(BALL).read_bytes())
        results = {
            "msd_pushed": case(
                msd,
                pushed,
                {"msd.k": 14.0},
                10.0,
                0.025,
                args.repeats,
                fmpy_run(msd_fmu, 10.0, 0.025, ["x"], {"k": 14.0}, force=True),
            ),
            "ball": case(as_plan(ball), None, {}, 2.0, 0.01, args.repeats, fmpy_run(ball, 2.0, 0.01, ["h"])),
            "msd_terms": case(msd, pushed, {"msd.k": 14.0, **TERMS}, 10.0, 0.025, args.repeats, None),
        }
    if args.json:
        print(json.dumps({"cases": results, "repeats": args.repeats}, indent=2))
        return
    print(f"model exchange under CVode, median wall time per simulation ({args.repeats} repeats)")
    print(
        f"{'case':<12} {'steps':>6} {'native':>10} {'python':>10} {'simulate_fmu':>13} {'python/native':>14} "
        f"{'fmpy/native':>12} {'identical':>10}"
    )
    for name, f in results.items():
        fmpy = f"{f['simulate_fmu'] * 1e3:10.2f} ms" if "simulate_fmu" in f else f"{'-':>13}"
        ratio = f"{f['simulate_fmu_over_native']:11.1f}x" if "simulate_fmu" in f else f"{'-':>12}"
        print(
            f"{name:<12} {f['steps']:>6} {f['native'] * 1e3:7.2f} ms {f['python'] * 1e3:7.2f} ms {fmpy} "
            f"{f['python_over_native']:13.1f}x {ratio} {f['bit_identical']!s:>10}"
        )


if __name__ == "__main__":
    main()
