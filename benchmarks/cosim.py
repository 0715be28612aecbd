"""Per-simulation wall time of five FMI masters on two cases, side by side: what our master costs.

    python benchmarks/cosim.py [--scenario sin1] [--repeats 15] [--json] [--profile]

Two cases (issue 16):

* ``robotti``: one Robotti scenario (default sin1), the replay controller and the
  vehicle FMU, calibrated values: a realistic run, where the FMUs' own work counts;
* ``cheap``: the vanderpol FMU (benchmarks/fmus/vanderpol, the shape of the Reference
  FMU VanDerPol) alone, 0..20 s at its 1e-2 s step (2000 steps, as the Reference FMU's
  default experiment), mu set per run, x0 and x1 recorded every step: the FMU costs
  almost nothing, so what is left is the master's overhead per step.

Each case times, per simulation:

* ``dse_runner``: our master with its native C step loop (``simulate(..., loop="native")``),
  the plan and FMU instances reused across runs as in a sweep;
* ``python_loop``: the same master with its Python reference loop (``loop="python"``);
* ``simulate_fmu``: FMPy's ``simulate_fmu`` per run, as a user would write it (Robotti: the
  vehicle FMU fed the recorded inputs as an input table);
* ``libcosim``: the Open Simulation Platform's libcosim through libcosimpy;
* ``c_floor``: a minimal C program driving the same FMUs through their C API with the same
  step (cosim_floor.c for Robotti, cosim_floor_single.c for the cheap case): the floor for
  FMI co-simulation on this machine.

Each figure is the median over the repeats (the cheap case's native and C-floor runs, well under
a millisecond each, 20 times as many), in seconds per simulation in the JSON
(``--json``: ``{"robotti": {master: s}, "cheap": {...}, "ratios": {...}, "steps": {...},
"repeats": n, ...}``). Targets, reported beside the measured ratios (not asserted):
Robotti native within 1.15x of the C floor; cheap native within 2x of the C floor and at
least 10x faster than the Python loop. The cheap case's ratio to the floor is given twice: by
medians, and by each master's fastest run (``dse_runner_over_c_floor_fastest``; the floor's from
the fastest of 3 processes), since two sub-millisecond medians timed one after the other move
with whatever else a shared machine runs. The final x (Robotti) / x0 (cheap) of the C floor
and of our master are printed side by side as a check that they computed the same thing.
The cheap case is also run 10 times longer by ours (native) and the C floor, which splits each
one's time into a fixed cost per simulation and a marginal cost per step (``split`` in the JSON),
from the fastest of the repeats at each length (a median is too noisy for a difference of two
sub-millisecond figures on a shared machine): where the remaining time goes. ``--profile`` prints
a cProfile breakdown of our master on the cheap case instead.
"""

from __future__ import annotations

import argparse
import json
import operator
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's dse_runner

from dse_runner import bundled
from dse_runner.simulation.build import build_fmu, fmi_headers_dir
from dse_runner.simulation.crosscheck import run_libcosim
from dse_runner.simulation.fmu import describe
from dse_runner.simulation.plan import Plan
from dse_runner.simulation.run import SimulationResult, as_plan, simulate
from dse_runner.simulation.scenario import Scenario, load_scenario

REPO = Path(__file__).resolve().parents[1]

CALIBRATED = {"vehicle.mass": 1000.0, "vehicle.cAlphaF": 38000.0, "vehicle.mu": 0.3}
CHEAP_FMU = REPO / "benchmarks" / "fmus" / "vanderpol"
CHEAP_VALUES = {"mu": 1.5}  # set per run, so every run pays for a parameter as a sweep's does
MASTERS = ("dse_runner", "python_loop", "simulate_fmu", "libcosim", "c_floor")
# (case, ratio, comparison, bound): what issue 16 asks of the native loop
TARGETS = (
    ("robotti", "dse_runner_over_c_floor", "<=", 1.15),
    ("cheap", "dse_runner_over_c_floor", "<=", 2.0),
    ("cheap", "dse_runner_over_c_floor_fastest", "<=", 2.0),
    ("cheap", "python_loop_over_dse_runner", ">=", 10.0),
)
COMPARE = {"<=": operator.le, ">=": operator.ge}


@dataclass(frozen=True)
class Case:
    """One case's figures (seconds per simulation) and the check that the masters agree."""

    figures: dict[str, float]
    steps: int
    step: float
    signal: str  # the output whose final value is compared
    final: dict[str, float]  # master -> that output's final value
    split: dict[str, dict[str, float]] | None = None  # master -> fixed and per-step cost (cost_split)
    fastest: dict[str, float] | None = None  # master -> its fastest run of ``steps`` steps


def times_of(run: Callable[[], object], repeats: int) -> list[float]:
    run()  # warm-up: builds, extraction, first instantiation
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        samples.append(time.perf_counter() - start)
    return samples


def median_time(run: Callable[[], object], repeats: int) -> float:
    return statistics.median(times_of(run, repeats))


def fastest_time(run: Callable[[], object], repeats: int) -> float:
    """The fastest run: what a run costs with the least interference from a shared machine."""
    return min(times_of(run, repeats))


def final_value(result: SimulationResult, suffix: str) -> float:
    """The last sample of the recorded output ``<instance>.<suffix>``."""
    (name,) = [n for n in result.outputs if n.endswith(f".{suffix}")]
    return float(result.outputs[name][-1])


# ---- the C floors ---------------------------------------------------------------------------------------


def compile_floor(source: str, work: Path) -> Path:
    """A floor program compiled with the system C compiler against FMPy's FMI headers."""
    work.mkdir(parents=True, exist_ok=True)
    binary = work / Path(source).stem
    subprocess.run(
        [
            "cc",
            "-O2",
            "-std=c11",
            f"-I{fmi_headers_dir()}",
            "-o",
            str(binary),
            str(REPO / "benchmarks" / source),
            "-ldl",
            "-lm",
        ],
        check=True,
    )
    return binary


def extract_library(path: Path, work: Path, name: str) -> tuple[Path, str]:
    """An FMU's Linux shared library, unzipped for dlopen, and its GUID."""
    description = describe(path)
    identifier = description.coSimulation.modelIdentifier
    with zipfile.ZipFile(path) as fmu:
        fmu.extract(f"binaries/linux64/{identifier}.so", work / name)
    return work / name / "binaries" / "linux64" / f"{identifier}.so", description.guid


def real_sets(plan: Plan, values: dict, instance: str) -> str:
    """The real values set on ``instance``, as the floors take them: "vr=value,..."."""
    return ",".join(
        f"{plan.variable(ref, 'set').vr}={float(v)!r}"
        for ref, v in values.items()
        if ref.startswith(f"{instance}.")
    )


def time_c_floor(
    plan: Plan, scenario: Scenario, values: dict, step: float, repeats: int, work: Path
) -> tuple[float, float]:
    """Robotti through cosim_floor.c: (median seconds, final vehicle x)."""
    binary = compile_floor("cosim_floor.c", work)
    libraries = {name: extract_library(path, work, name) for name, path in plan.fmu_paths.items()}
    c2v = ",".join(f"{s.vr}:{t.vr}" for s, t in plan.connections if s.instance == "controller")
    v2c = ",".join(f"{s.vr}:{t.vr}" for s, t in plan.connections if s.instance == "vehicle")
    file_vr = plan.variable("controller.file", "set").vr
    done = subprocess.run(
        [
            str(binary),
            str(libraries["vehicle"][0]),
            libraries["vehicle"][1],
            str(libraries["controller"][0]),
            libraries["controller"][1],
            repr(scenario.stop_time),
            repr(step),
            str(repeats),
            str(file_vr),
            str(scenario.files["steering_inputs"]),
            c2v,
            v2c,
            real_sets(plan, values, "vehicle"),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    seconds, last_x = map(float, done.stdout.split())
    return seconds, last_x


def time_c_floor_single(
    plan: Plan, values: dict, stop: float, step: float, repeats: int, work: Path
) -> tuple[float, float, float]:
    """One FMU through cosim_floor_single.c, recording every output: (median seconds, final first output,
    fastest seconds)."""
    binary = compile_floor("cosim_floor_single.c", work)
    ((instance, path),) = plan.fmu_paths.items()
    library, guid = extract_library(path, work, instance)
    outputs = ",".join(str(v.vr) for v in plan.outputs[instance])
    done = subprocess.run(
        [
            str(binary),
            str(library),
            guid,
            repr(stop),
            repr(step),
            str(repeats),
            outputs,
            real_sets(plan, values, instance),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    seconds, last, fastest = map(float, done.stdout.split())
    return seconds, last, fastest


# ---- FMPy's simulate_fmu --------------------------------------------------------------------------------


def time_simulate_fmu(plan: Plan, scenario: Scenario, values: dict, step: float, repeats: int) -> float:
    """Robotti's vehicle alone, fed the recorded inputs as FMPy's input table."""
    from fmpy import simulate_fmu

    log = np.loadtxt(scenario.files["steering_inputs"], delimiter=",", skiprows=1)
    signals = np.array(
        [tuple(row) for row in log], dtype=[("time", float), ("velocity", float), ("delta_f", float)]
    )
    start_values = {ref.split(".", 1)[1]: v for ref, v in values.items() if ref.startswith("vehicle.")}

    def run():
        simulate_fmu(
            str(plan.fmu_paths["vehicle"]),
            stop_time=scenario.stop_time,
            step_size=step,
            output_interval=step,
            start_values=start_values,
            input=signals,
            output=["x", "y"],
        )

    return median_time(run, repeats)


def time_simulate_fmu_single(
    path: Path, values: dict, stop: float, step: float, outputs: list[str], repeats: int
) -> float:
    """One FMU, its outputs recorded every step, as a user would call simulate_fmu."""
    from fmpy import simulate_fmu

    def run():
        simulate_fmu(
            str(path),
            stop_time=stop,
            step_size=step,
            output_interval=step,
            start_values=values,
            output=outputs,
        )

    return median_time(run, repeats)


# ---- the cases ------------------------------------------------------------------------------------------


def robotti_case(scenario_name: str, repeats: int, work: Path) -> Case:
    plan = as_plan(bundled.bundled_path("bundled:robotti/multimodel.yaml"))
    scenario = load_scenario(REPO / "scenarios" / "robotti" / scenario_name)
    reference = simulate(plan, scenario, CALIBRATED, loop="native")
    python = simulate(plan, scenario, CALIBRATED, loop="python")
    values, step = reference.values, reference.step
    c_floor, c_last_x = time_c_floor(plan, scenario, values, step, repeats, work)
    figures = {
        "dse_runner": median_time(lambda: simulate(plan, scenario, CALIBRATED, loop="native"), repeats),
        "python_loop": median_time(lambda: simulate(plan, scenario, CALIBRATED, loop="python"), repeats),
        "simulate_fmu": time_simulate_fmu(plan, scenario, values, step, repeats),
        "libcosim": median_time(lambda: run_libcosim(plan, values, scenario.stop_time, step), repeats),
        "c_floor": c_floor,
    }
    final = {
        "dse_runner": final_value(reference, "x"),
        "python_loop": final_value(python, "x"),
        "c_floor": c_last_x,
    }
    return Case(figures, len(reference.time) - 1, step, "x", final)


FAST_REPEATS = 20  # the cheap case's native and C-floor runs are repeated this many times more


def cheap_case(repeats: int, work: Path) -> Case:
    path = build_fmu(CHEAP_FMU)
    plan = as_plan(path)
    reference = simulate(plan, values=CHEAP_VALUES, loop="native")  # its default experiment: 0..20 s by 1e-2
    python = simulate(plan, values=CHEAP_VALUES, loop="python")
    values, times = reference.values, reference.times
    outputs = [v.name for vs in plan.outputs.values() for v in vs]
    fast = repeats * FAST_REPEATS  # runs of well under a millisecond: more of them for a steady median
    c_floor, c_last_x0, _ = time_c_floor_single(plan, values, times.stop, times.step, fast, work)

    def ours(loop: str) -> Callable[[], object]:
        return lambda: simulate(plan, values=CHEAP_VALUES, stop_time=times.stop, step=times.step, loop=loop)

    def ours_at(stop: float) -> Callable[[], object]:
        return lambda: simulate(plan, values=CHEAP_VALUES, stop_time=stop, step=times.step, loop="native")

    figures = {
        "dse_runner": median_time(ours("native"), fast),
        "python_loop": median_time(ours("python"), repeats),
        "simulate_fmu": time_simulate_fmu_single(
            path, CHEAP_VALUES, times.stop, times.step, outputs, repeats
        ),
        "libcosim": median_time(lambda: run_libcosim(plan, values, times.stop, times.step), repeats),
        "c_floor": c_floor,
    }
    final = {
        "dse_runner": final_value(reference, "x0"),
        "python_loop": final_value(python, "x0"),
        "c_floor": c_last_x0,
    }
    long_stop = times.start + LONGER * (times.stop - times.start)
    fastest = {
        "dse_runner": [fastest_time(ours_at(stop), fast) for stop in (times.stop, long_stop)],
        "c_floor": [
            min(
                time_c_floor_single(plan, values, stop, times.step, fast, work)[2]
                for _ in range(FLOOR_PROCESSES)
            )
            for stop in (times.stop, long_stop)
        ],
    }
    steps = len(reference.time) - 1
    split = {master: cost_split(*fastest[master], steps, LONGER * steps) for master in fastest}
    return Case(
        figures, steps, times.step, "x0", final, split, {master: runs[0] for master, runs in fastest.items()}
    )


LONGER = 10  # the cheap case is also run this many times longer, to split fixed from per-step cost
FLOOR_PROCESSES = (
    3  # a whole floor process can land on a slow moment of a shared machine: the fastest of these
)


def cost_split(short: float, long: float, short_steps: int, long_steps: int) -> dict[str, float]:
    """A master's fixed cost per simulation and marginal cost per step, from
    its fastest runs of two lengths."""
    per_step = (long - short) / (long_steps - short_steps)
    return {"fixed_seconds": short - per_step * short_steps, "seconds_per_step": per_step}


# ---- the report -----------------------------------------------------------------------------------------


def ratios(case: Case) -> dict[str, float]:
    """Ours against the floor, and the other masters against ours (> 1: ours is faster). Where the
    fastest runs were kept, also ours against the floor by those: sub-millisecond medians of two
    programs timed one after the other move with whatever else the machine runs, fastest runs far less."""
    figures = case.figures
    ours = figures["dse_runner"]
    found = {
        "dse_runner_over_c_floor": ours / figures["c_floor"],
        "python_loop_over_dse_runner": figures["python_loop"] / ours,
        "libcosim_over_dse_runner": figures["libcosim"] / ours,
        "simulate_fmu_over_dse_runner": figures["simulate_fmu"] / ours,
    }
    if case.fastest:
        found["dse_runner_over_c_floor_fastest"] = case.fastest["dse_runner"] / case.fastest["c_floor"]
    return found


def targets(all_ratios: dict[str, dict[str, float]]) -> list[dict]:
    """Each target with the measured ratio and whether it is met."""
    return [
        {
            "case": case,
            "ratio": name,
            "target": f"{comparison} {bound:g}",
            "measured": all_ratios[case][name],
            "met": COMPARE[comparison](all_ratios[case][name], bound),
        }
        for case, name, comparison, bound in TARGETS
    ]


def duration(seconds: float) -> str:
    """ms from a millisecond up, µs below."""
    return f"{seconds * 1e3:9.2f} ms" if seconds >= 1e-3 else f"{seconds * 1e6:9.1f} µs"


def print_case(name: str, case: Case, case_ratios: dict[str, float], title: str) -> None:
    print(f"{name}: {title}: {case.steps} steps of {case.step:g} s")
    for master, seconds in case.figures.items():
        per_step = seconds / case.steps * 1e6
        print(f"  {master:<14} {duration(seconds)} per simulation  {per_step:8.3f} µs per step")
    for ratio, value in case_ratios.items():
        print(f"  {ratio:<30} {value:7.2f}x")
    ours = case.final["dse_runner"]
    floor, python = (abs(case.final[master] - ours) for master in ("c_floor", "python_loop"))
    print(
        f"  final {case.signal}: dse_runner {ours:.12g}; the C floor differs by {floor:.2e},"
        f" the Python loop by {python:.2e}"
    )
    for master, cost in (case.split or {}).items():
        print(
            f"  {master:<14} fixed {cost['fixed_seconds'] * 1e6:7.1f} µs "
            f"per simulation, {cost['seconds_per_step'] * 1e9:6.1f} ns per "
            f"step (runs of {case.steps} and {LONGER * case.steps} steps)"
        )


PROFILED_RUNS = 3000


def profile_cheap() -> None:
    """cProfile of our master on the cheap case: where the time around the C loop goes (the C loop itself
    is the one call native.step_loop makes; cProfile slows the Python around it, not the loop)."""
    import cProfile
    import pstats

    plan = as_plan(build_fmu(CHEAP_FMU))
    times = simulate(plan, values=CHEAP_VALUES, loop="native").times

    def run() -> SimulationResult:
        return simulate(plan, values=CHEAP_VALUES, stop_time=times.stop, step=times.step, loop="native")

    for _ in range(200):
        run()
    profiler = cProfile.Profile()
    profiler.enable()
    for _ in range(PROFILED_RUNS):
        run()
    profiler.disable()
    print(f"cProfile of {PROFILED_RUNS} cheap simulations (native loop), by own time:")
    pstats.Stats(profiler).sort_stats("tottime").print_stats(15)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="sin1")
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--profile", action="store_true", help="print a cProfile breakdown of the cheap case only"
    )
    args = parser.parse_args()
    if args.profile:
        profile_cheap()
        return

    with tempfile.TemporaryDirectory() as tmp:
        cases = {
            "robotti": robotti_case(args.scenario, args.repeats, Path(tmp) / "robotti"),
            "cheap": cheap_case(args.repeats, Path(tmp) / "cheap"),
        }
    all_ratios = {name: ratios(case) for name, case in cases.items()}
    checked = targets(all_ratios)
    if args.json:
        print(
            json.dumps(
                {
                    **{name: case.figures for name, case in cases.items()},
                    "ratios": all_ratios,
                    "steps": {name: case.steps for name, case in cases.items()},
                    "repeats": args.repeats,
                    "scenario": args.scenario,
                    "targets": checked,
                    "final": {name: {"signal": case.signal, **case.final} for name, case in cases.items()},
                    "split": {name: case.split for name, case in cases.items() if case.split},
                },
                indent=2,
                allow_nan=False,
            )
        )
        return
    print(f"median of {args.repeats} runs per master")
    titles = {
        "robotti": f"Robotti scenario {args.scenario}, controller + vehicle",
        "cheap": f"vanderpol alone, mu = {CHEAP_VALUES['mu']:g}, x0 and x1 recorded",
    }
    for name, case in cases.items():
        print_case(name, case, all_ratios[name], titles[name])
    print("targets (native loop):")
    for t in checked:
        mark = "✔" if t["met"] else "✘"
        print(f"  {t['case']:<8} {t['ratio']:<30} {t['target']:>7}: {t['measured']:7.2f}x {mark}")


if __name__ == "__main__":
    main()
