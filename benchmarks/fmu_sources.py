"""A bundled FMU's speed at two versions of its C sources, side by side, and whether they compute the same.

    python benchmarks/fmu_sources.py [--rev HEAD] [--fmu robotti_vehicle_effects] [--repeats 8] [--json]

The FMU is built twice (the ordinary build and cache, simulation/build.py): from the package's
top-level ``fmus/`` as it is in the working tree, and from the same folder at git revision ``--rev``
(``git archive``). Each drives the Robotti multi-model, its vehicle replaced by the FMU, on the bundled
runs with each of a few parameter sets: the calibrated baseline and, for the effects variant, each effect
and a correction block switched on. Every trajectory of one build is compared with the other's byte for
byte. The two builds are timed in turns (``--repeats`` rounds of every run), and the fastest round of
each is printed, with their ratio: on a shared machine the fastest round says the most.
"""

from __future__ import annotations

import argparse
import io
import json
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's dse_runner

from dse_runner import bundled
from dse_runner.simulation.build import build_fmu
from dse_runner.simulation.multimodel import load_multimodel
from dse_runner.simulation.plan import make_plan
from dse_runner.simulation.run import simulate
from dse_runner.simulation.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]

FMUS = "fmus"
FORMERLY = "dse_runner/bundled/fmus"  # where they were before 2026-11-28
RUNS = ("sin1", "turn_ramp2", "speed_step1", "speed_ramp3")
CALIBRATED = {"vehicle.mass": 1000.0, "vehicle.cAlphaF": 38000.0, "vehicle.mu": 0.3}
EFFECTS = [
    {"vehicle.wheel_slip": 0.08},
    {"vehicle.steering_lag": 0.4},
    {"vehicle.speed_lag": 0.8},
    {"vehicle.steering_offset": 0.02},
    {"vehicle.time_offset": 0.4},
    {"vehicle.grade_x": 0.04, "vehicle.grade_y": -0.03},
    {"vehicle.antenna_x": 0.6},
    {"vehicle.corr_steer_v": 0.01, "vehicle.corr_yaw_r": -0.05, "vehicle.corr_acc_1": 0.02},
]


def sources_at(rev: str, into: Path) -> Path:
    """The bundled FMU sources at git revision ``rev``, unpacked under ``into``."""
    folder = (
        FMUS
        if subprocess.run(
            ["git", "-C", str(REPO), "cat-file", "-e", f"{rev}:{FMUS}"], check=False, capture_output=True
        ).returncode
        == 0
        else FORMERLY
    )
    archive = subprocess.run(
        ["git", "-C", str(REPO), "archive", rev, folder], capture_output=True, check=True
    ).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(into, filter="data")
    return into / folder


def cases(fmu: str) -> list[dict[str, float]]:
    """The parameter sets to run: the calibrated baseline, and each effect on top of it for the variant."""
    return [CALIBRATED] + ([{**CALIBRATED, **e} for e in EFFECTS] if fmu.endswith("_effects") else [])


def plan_with(fmu_file: Path):
    multimodel = load_multimodel(bundled.bundled_path("bundled:robotti/multimodel.yaml"))
    return make_plan(multimodel.model_copy(update={"fmus": {**multimodel.fmus, "vehicle": str(fmu_file)}}))


def run_all(plan, scenarios, values_list) -> list[bytes]:
    return [
        simulate(plan, s, v, loop="native").trajectory.values.tobytes()
        for v in values_list
        for s in scenarios
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rev", default="HEAD", help="the git revision to compare the working tree with")
    parser.add_argument("--fmu", default="robotti_vehicle_effects", help="a folder of the top-level fmus/")
    parser.add_argument("--repeats", type=int, default=8)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    scenarios = [load_scenario(REPO / "scenarios" / "robotti" / r) for r in RUNS]
    values_list = cases(args.fmu)
    with tempfile.TemporaryDirectory(prefix="fmu-sources-") as tmp:
        builds = {
            args.rev: build_fmu(sources_at(args.rev, Path(tmp)) / args.fmu),
            "working tree": build_fmu(REPO / FMUS / args.fmu),
        }
        plans = {name: plan_with(path) for name, path in builds.items()}
        outputs = {
            name: run_all(plan, scenarios, values_list) for name, plan in plans.items()
        }  # also a warm-up
        fastest = {name: float("inf") for name in plans}
        for _ in range(args.repeats):
            for name, plan in plans.items():
                started = time.process_time()
                run_all(plan, scenarios, values_list)
                fastest[name] = min(fastest[name], time.process_time() - started)
    runs = len(values_list) * len(scenarios)
    old, new = outputs.values()
    figures = {
        "fmu": args.fmu,
        "runs_per_round": runs,
        "repeats": args.repeats,
        "ms_per_run": {name: round(1000 * s / runs, 3) for name, s in fastest.items()},
        "working_tree_over_rev": round(fastest["working tree"] / fastest[args.rev], 3),
        "identical_runs": sum(a == b for a, b in zip(old, new)),
    }
    if args.json:
        print(json.dumps(figures))
        return
    print(
        f"{args.fmu}: {runs} runs a round ({len(values_list)} parameter sets x {len(scenarios)} runs), "
        f"fastest of {args.repeats} rounds, CPU per run:"
    )
    for name, ms in figures["ms_per_run"].items():
        print(f"  {name:>14}: {ms:.2f} ms")
    print(f"  working tree / {args.rev}: {figures['working_tree_over_rev']:.3f}")
    print(f"  trajectories identical byte for byte: {figures['identical_runs']} of {runs}")


if __name__ == "__main__":
    main()
