"""Per-simulation wall time of one Robotti scenario with four FMI masters, side by side.

    python benchmarks/cosim.py [--scenario sin1] [--repeats 15] [--json]

* ``dse_runner``: our master, instances reused across runs as in a sweep;
* ``libcosim``: the Open Simulation Platform's libcosim through libcosimpy;
* ``simulate_fmu``: FMPy's ``simulate_fmu`` per run, as a user would write it
  (the vehicle FMU fed the recorded inputs as an input table);
* ``c_floor``: a minimal C program (cosim_floor.c) driving the same two FMUs
  through their C API with the same step: the floor for FMI co-simulation here.

Each figure is the median over the repeats. Targets: dse_runner within 2x of
c_floor, and faster than libcosim and simulate_fmu.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from dse_runner import bundled  # noqa: E402
from dse_runner.simulation.build import fmi_headers_dir  # noqa: E402
from dse_runner.simulation.crosscheck import run_libcosim  # noqa: E402
from dse_runner.simulation.fmu import describe  # noqa: E402
from dse_runner.simulation.scenario import load_scenario  # noqa: E402
from dse_runner.simulation.run import as_plan, simulate  # noqa: E402

CALIBRATED = {"vehicle.mass": 1000.0, "vehicle.cAlphaF": 38000.0, "vehicle.mu": 0.3}


def median_time(run, repeats: int) -> float:
    run()  # warm-up: builds, extraction, first instantiation
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def time_simulate_fmu(plan, scenario, values, step: float, repeats: int) -> float:
    from fmpy import simulate_fmu

    log = np.loadtxt(scenario.files["steering_inputs"], delimiter=",", skiprows=1)
    signals = np.array([tuple(row) for row in log],
                       dtype=[("time", float), ("velocity", float), ("delta_f", float)])
    start_values = {ref.split(".", 1)[1]: v for ref, v in values.items() if ref.startswith("vehicle.")}

    def run():
        simulate_fmu(str(plan.fmu_paths["vehicle"]), stop_time=scenario.stop_time, step_size=step,
                     output_interval=step, start_values=start_values, input=signals, output=["x", "y"])

    return median_time(run, repeats)


def time_c_floor(plan, scenario, values, step: float, repeats: int, work: Path) -> tuple[float, float]:
    binary = work / "cosim_floor"
    subprocess.run(["cc", "-O2", "-std=c11", f"-I{fmi_headers_dir()}", "-o", str(binary),
                    str(REPO / "benchmarks" / "cosim_floor.c"), "-ldl", "-lm"], check=True)
    libraries, guids = {}, {}
    for name, path in plan.fmu_paths.items():
        description = describe(path)
        identifier = description.coSimulation.modelIdentifier
        with zipfile.ZipFile(path) as fmu:
            fmu.extract(f"binaries/linux64/{identifier}.so", work / name)
        libraries[name] = work / name / "binaries" / "linux64" / f"{identifier}.so"
        guids[name] = description.guid
    c2v = ",".join(f"{s.vr}:{t.vr}" for s, t in plan.connections if s.instance == "controller")
    v2c = ",".join(f"{s.vr}:{t.vr}" for s, t in plan.connections if s.instance == "vehicle")
    sets = ",".join(f"{plan.variable(ref, 'set').vr}={float(v)!r}"
                    for ref, v in values.items() if ref.startswith("vehicle."))
    file_vr = plan.variable("controller.file", "set").vr
    done = subprocess.run(
        [str(binary), str(libraries["vehicle"]), guids["vehicle"], str(libraries["controller"]),
         guids["controller"], repr(scenario.stop_time), repr(step), str(repeats), str(file_vr),
         str(scenario.files["steering_inputs"]), c2v, v2c, sets],
        capture_output=True, text=True, check=True)
    seconds, last_x = map(float, done.stdout.split())
    return seconds, last_x


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="sin1")
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    plan = as_plan(bundled.bundled_path("bundled:robotti/multimodel.yaml"))
    scenario = load_scenario(REPO / "scenarios" / "robotti" / args.scenario)
    reference = simulate(plan, scenario, CALIBRATED)
    values, step = reference.values, reference.step

    with tempfile.TemporaryDirectory() as tmp:
        c_floor, c_last_x = time_c_floor(plan, scenario, values, step, args.repeats, Path(tmp))
    figures = {
        "dse_runner": median_time(lambda: simulate(plan, scenario, CALIBRATED), args.repeats),
        "libcosim": median_time(lambda: run_libcosim(plan, values, scenario.stop_time, step), args.repeats),
        "simulate_fmu": time_simulate_fmu(plan, scenario, values, step, args.repeats),
        "c_floor": c_floor,
    }
    ours_last_x = float(reference.trajectory.column("vehicle.x")[-1])
    ratios = {
        "dse_runner_over_c_floor": figures["dse_runner"] / figures["c_floor"],
        "libcosim_over_dse_runner": figures["libcosim"] / figures["dse_runner"],
        "simulate_fmu_over_dse_runner": figures["simulate_fmu"] / figures["dse_runner"],
    }
    if args.json:
        print(json.dumps({**figures, "ratios": ratios, "scenario": args.scenario, "repeats": args.repeats,
                          "c_floor_final_x_minus_ours": c_last_x - ours_last_x}, indent=2))
        return
    print(f"scenario {args.scenario}: {len(reference.trajectory.time) - 1} steps of {step:g} s, "
          f"median of {args.repeats} runs")
    for name, seconds in figures.items():
        print(f"  {name:<14} {seconds * 1e3:9.2f} ms")
    for name, ratio in ratios.items():
        print(f"  {name:<30} {ratio:6.2f}x")
    print(f"  (C floor and dse_runner end at x differing by {abs(c_last_x - ours_last_x):.2e} m)")


if __name__ == "__main__":
    main()
