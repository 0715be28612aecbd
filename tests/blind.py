"""Recordings from a richer truth model, for blind tests of discrepancy diagnosis.

The truth is the vehicle's effects variant with vehicle parameters the
calibration must find and one effect (or none) switched on. It replays the
steering logs of the bundled runs and records the GPS antenna at 10 Hz with
receiver noise and dropouts, in the field-data format: the diagnosis sees
only these files, never the truth.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from dse_runner import bundled
from dse_runner.cases.fielddata import read_info
from dse_runner.simulation.multimodel import parse_multimodel
from dse_runner.simulation.scenario import INFO_FILE, load_scenario
from dse_runner.simulation.run import as_plan, simulate

REPO = Path(__file__).resolve().parents[1]
SOURCES = REPO / "scenarios" / "robotti"
RUNS = ["sin1", "sin2", "speed_step1", "speed_step2", "turn_ramp1", "turn_ramp2"]  # in the tests
BENCHMARK_RUNS = [*RUNS, "speed_ramp1", "speed_ramp2"]  # benchmarks/diagnosis_blind.py
SECONDS = 20.0  # of each run in the tests: a start, speed steps, a full steering swing on the sin runs
BENCHMARK_SECONDS = 40.0  # benchmarks/diagnosis_blind.py: every manoeuvre, braking included
NOISE = 0.02  # m, the receiver's noise per axis
TRUTH_VEHICLE = {"vehicle.mass": 1800.0, "vehicle.cAlphaF": 26000.0}

# Each library effect at a size a field engineer would care about.
EFFECTS = {
    "wheel_slip": {"wheel_slip": 0.08},
    "steering_lag": {"steering_lag": 0.4},
    "speed_lag": {"speed_lag": 0.8},
    "steering_offset": {"steering_offset": 0.02},
    "time_offset": {"time_offset": 0.4},
    "antenna_offset": {"antenna_x": 0.6, "antenna_y": -0.3},
    "terrain_slope": {"grade_x": 0.04, "grade_y": -0.03},
    "none": {},
}

# Effects concealed together, each at its single size: a pair is named "a+b". The issue's case (slip and a
# steering lag) comes first; the other pairs follow in the plan's later steps.
PAIRS = {
    "wheel_slip+steering_lag": {**EFFECTS["wheel_slip"], **EFFECTS["steering_lag"]},
}


def truth_of(case: str) -> dict[str, float]:
    """The effect parameters a case switches on in the truth: a single effect's, or a pair's."""
    return EFFECTS[case] if case in EFFECTS else PAIRS[case]


def seed_of(case: str) -> int:
    """Each case's own noise: singles keep the seeds they always had, pairs take the next ones."""
    return sorted(EFFECTS).index(case) if case in EFFECTS else len(EFFECTS) + sorted(PAIRS).index(case)


def truth_plan():
    data = yaml.safe_load(bundled.bundled_path("bundled:robotti/multimodel.yaml").read_text())
    data["fmus"] = {"controller": "bundled:fmus/replay_controller", "vehicle": "bundled:fmus/robotti_vehicle_effects"}
    return as_plan(parse_multimodel(data, "truth", REPO))


def record(folder: Path, effect: str, runs: list[str], seconds: float, noise: float = NOISE,
           dropout: float = 0.03, seed: int = 0) -> Path:
    """Write ``runs`` (names of bundled runs, cut to ``seconds``) as recorded by the truth with ``effect``
    (a key of EFFECTS or PAIRS)."""
    rng = np.random.default_rng(seed)
    plan = truth_plan()
    overrides = {**TRUTH_VEHICLE, **{f"vehicle.{k}": v for k, v in truth_of(effect).items()}}
    for name in runs:
        info = read_info(SOURCES / name / INFO_FILE)
        target = folder / name
        target.mkdir(parents=True, exist_ok=True)
        duration = min(seconds, info.duration)
        lines = (SOURCES / name / "steering_inputs.csv").read_text().splitlines()
        kept = [lines[0]] + [line for line in lines[1:] if float(line.split(",")[0]) <= duration + 1e-9]
        (target / "steering_inputs.csv").write_text("\n".join(kept) + "\n")
        (target / INFO_FILE).write_text(yaml.safe_dump(info.model_dump(mode="json") | {"duration": duration},
                                                       sort_keys=False))
        (target / "gps_position.csv").write_text("time,x,y\n0,0,0\n")  # replaced below
        run = simulate(plan, load_scenario(target), overrides, objectives=(), step=0.05)
        fixes = np.round(np.arange(0.0, duration + 1e-9, 0.1), 2)
        x, y = run.trajectory.column("vehicle.gps_x"), run.trajectory.column("vehicle.gps_y")  # the antenna
        gx = np.interp(fixes, run.trajectory.time, x) + rng.normal(0, noise, fixes.size)
        gy = np.interp(fixes, run.trajectory.time, y) + rng.normal(0, noise, fixes.size)
        keep = rng.random(fixes.size) >= dropout
        start = rng.integers(fixes.size // 4, fixes.size // 2)  # and one outage of 2 s
        keep[start:start + 20] = False
        keep[0] = True
        rows = [f"{t:.2f},{a:.4f},{b:.4f}" for t, a, b in zip(fixes[keep], gx[keep], gy[keep])]
        (target / "gps_position.csv").write_text("time,x,y\n" + "\n".join(rows) + "\n")
    return folder


def calibration_space(folder: Path) -> Path:
    """The paper's design space, coarser: cAlphaF x mass, 4 x 3 points (the truth lies between them)."""
    path = folder / "calibration.yaml"
    path.write_text(yaml.safe_dump({
        "name": "blind-calibration", "multimodel": "bundled:robotti/multimodel.yaml",
        "scenarios": [str(SOURCES / "sin1")],  # replaced by the recordings under test
        "parameters": {"vehicle.cAlphaF": {"start": 20000, "stop": 38000, "step": 6000},
                       "vehicle.mass": {"start": 1000, "stop": 3000, "step": 1000}},
        "objectives": ["cross_track_error"],
    }))
    return path


def run_case(effect: str, root: Path, client=None, address: str | None = None, seconds: float = SECONDS,
             seed: int = 0, runs: list[str] = RUNS):
    """Record ``effect`` on ``runs`` under ``root`` and diagnose it; returns (runs folder, calibration space,
    Diagnosis). ``seed`` shifts every case's noise, to check that a pass is not luck."""
    from dse_runner.analysis.diagnose import Settings, diagnose

    runs = record(root / "runs", effect, runs, seconds, seed=seed_of(effect) + seed)
    space = calibration_space(root)
    result = diagnose(runs, space=space, out=root / "out", settings=Settings(folds=2), client=client,
                      address=address)
    return runs, space, result
