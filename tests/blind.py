"""Recordings from a richer truth model, for blind tests of discrepancy diagnosis.

The truth is the vehicle's effects variant with vehicle parameters the
calibration must find and one effect, two, or none switched on (a :class:`Case`).
It replays the steering logs of the bundled runs, and of synthetic ones
(:func:`synthetic_run`), and records the GPS antenna at 10 Hz with receiver
noise and dropouts, in the field-data format: the diagnosis sees only these
files, never the truth.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations
from pathlib import Path

import numpy as np
import yaml

from dse_runner import bundled
from dse_runner.cases.fielddata import read_info
from dse_runner.simulation.multimodel import parse_multimodel
from dse_runner.simulation.run import as_plan, simulate
from dse_runner.simulation.scenario import INFO_FILE, load_scenario

REPO = Path(__file__).resolve().parents[1]
SOURCES = REPO / "scenarios" / "robotti"
RUNS = ["sin1", "sin2", "speed_step1", "speed_step2", "turn_ramp1", "turn_ramp2"]  # in the tests
BENCHMARK_RUNS = [*RUNS, "speed_ramp1", "speed_ramp2"]  # benchmarks/diagnosis_blind.py
SECONDS = 20.0  # of each run in the tests: a start, speed steps, a full steering swing on the sin runs
BENCHMARK_SECONDS = 40.0  # benchmarks/diagnosis_blind.py: every manoeuvre, braking included
NOISE = 0.02  # m, the receiver's noise per axis
TRUTH_VEHICLE = {"vehicle.mass": 1800.0, "vehicle.cAlphaF": 26000.0}
STEP = 0.05  # s, the steering logs' period, as in the bundled runs

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

# Every pair of library effects concealed together, each at its single size, named "a+b" in library order.
# The issue's case (slip and a steering lag) comes first, so it keeps the seed it had alone.
PAIRS = {f"{a}+{b}": {**EFFECTS[a], **EFFECTS[b]}
         for a, b in combinations([e for e in EFFECTS if e != "none"], 2)}

# Synthetic manoeuvres (synthetic_run): the bundled steering is sines and ramps, on which a delay, a lag and
# a lower gain all look like a phase shift; a step shows a delay as a late jump and a lag as a slow rise.
SYNTHETIC = ("steer_steps",)
PAIR_RUNS = [*RUNS, "steer_steps"]  # what pair cases record


@dataclass(frozen=True)
class Case:
    """A blind case's truth: the library effects concealed, their parameters' values, the runs recorded and
    the seed of the receiver's noise."""
    name: str
    effects: tuple[str, ...]  # library ids; () for noise only
    truth: dict[str, float]  # effect parameters of the truth (variables of the effects variant)
    runs: tuple[str, ...]  # bundled or synthetic run names
    seed: int


def _cases() -> dict[str, Case]:
    """Singles keep the seeds they always had (sorted names); pairs take the next ones, in PAIRS' order."""
    singles = {e: Case(e, (e,) if e != "none" else (), EFFECTS[e], tuple(RUNS), sorted(EFFECTS).index(e))
               for e in EFFECTS}
    pairs = {p: Case(p, tuple(p.split("+")), truth, tuple(PAIR_RUNS), len(EFFECTS) + k)
             for k, (p, truth) in enumerate(PAIRS.items())}
    return singles | pairs


CASES = _cases()


def truth_of(case: str) -> dict[str, float]:
    """The effect parameters a case switches on in the truth: a single effect's, or a pair's."""
    return CASES[case].truth


def seed_of(case: str) -> int:
    """Each case's own noise, so that two cases never share a noise draw."""
    return CASES[case].seed


def synthetic_run(name: str, seconds: float) -> tuple[dict, list[str]]:
    """A manoeuvre no bundled run has, as (scenario.yaml's fields, steering log lines), ``seconds`` long.

    ``steer_steps``: at rest for 1 s, then 1.2 m/s with the steering stepped every 5 s through 0, +0.1, 0,
    -0.1 rad: each step separates a delay (the same jump, late) from a lag (a slow rise) and from an offset
    (straight segments between the steps)."""
    if name != "steer_steps":
        raise ValueError(f"unknown synthetic run {name!r}: there is {', '.join(SYNTHETIC)}")
    times = np.round(np.arange(0.0, seconds + 1e-9, STEP), 2)
    speed = np.where(times >= 1.0, 1.2, 0.0)
    steering = np.array([0.0, 0.1, 0.0, -0.1])[(times // 5.0).astype(int) % 4]
    lines = ["time,velocity,delta_f"] + [f"{t:.2f},{v:.3f},{d:.4f}" for t, v, d in zip(times, speed, steering)]
    info = {"name": name, "group": name, "duration": float(seconds),
            "initial_pose": {"x": 0.0, "y": 0.0, "theta": 0.0}}
    return info, lines


def source(name: str, seconds: float) -> tuple[dict, list[str]]:
    """A run's scenario.yaml fields and steering log lines, cut to ``seconds``: bundled, or synthetic."""
    if name in SYNTHETIC:
        return synthetic_run(name, seconds)
    info = read_info(SOURCES / name / INFO_FILE)
    duration = min(seconds, info.duration)
    lines = (SOURCES / name / "steering_inputs.csv").read_text().splitlines()
    kept = [lines[0]] + [line for line in lines[1:] if float(line.split(",")[0]) <= duration + 1e-9]
    return info.model_dump(mode="json") | {"duration": duration}, kept


def truth_plan():
    data = yaml.safe_load(bundled.bundled_path("bundled:robotti/multimodel.yaml").read_text())
    data["fmus"] = {"controller": "bundled:fmus/replay_controller", "vehicle": "bundled:fmus/robotti_vehicle_effects"}
    return as_plan(parse_multimodel(data, "truth", REPO))


def record(folder: Path, effect: str, runs: list[str] | tuple[str, ...], seconds: float, noise: float = NOISE,
           dropout: float = 0.03, seed: int = 0) -> Path:
    """Write ``runs`` (names of bundled or synthetic runs, cut to ``seconds``) as recorded by the truth with
    ``effect`` (a name of CASES)."""
    rng = np.random.default_rng(seed)
    plan = truth_plan()
    overrides = {**TRUTH_VEHICLE, **{f"vehicle.{k}": v for k, v in truth_of(effect).items()}}
    for name in runs:
        info, lines = source(name, seconds)
        duration = info["duration"]
        target = folder / name
        target.mkdir(parents=True, exist_ok=True)
        (target / "steering_inputs.csv").write_text("\n".join(lines) + "\n")
        (target / INFO_FILE).write_text(yaml.safe_dump(info, sort_keys=False))
        (target / "gps_position.csv").write_text("time,x,y\n0,0,0\n")  # replaced below
        run = simulate(plan, load_scenario(target), overrides, objectives=(), step=STEP)
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
             seed: int = 0, runs: list[str] | tuple[str, ...] | None = None, settings=None):
    """Record case ``effect`` on ``runs`` (default: the case's own) under ``root`` and diagnose it with
    ``settings`` (default: two folds); returns (runs folder, calibration space, Diagnosis). ``seed`` shifts
    every case's noise, to check that a pass is not luck."""
    from dse_runner.analysis.diagnose import Settings, diagnose

    case = CASES[effect]
    runs = record(root / "runs", effect, case.runs if runs is None else runs, seconds, seed=case.seed + seed)
    space = calibration_space(root)
    result = diagnose(runs, space=space, out=root / "out", settings=settings or Settings(folds=2), client=client,
                      address=address)
    return runs, space, result


def benchmark_runs(effect: str) -> list[str]:
    """The benchmark's runs for a case: every bundled manoeuvre (BENCHMARK_RUNS) and the case's synthetic ones."""
    return [*BENCHMARK_RUNS, *(r for r in CASES[effect].runs if r in SYNTHETIC)]


def top_two(result) -> list[str]:
    """The effects a diagnosis names first: its first two, or its one effect and a single-effect runner-up
    (the pairs' target: both concealed effects among these)."""
    named = [e["id"] for e in result.effects if e["id"] != "none"][:2]
    up = result.runner_up
    if len(named) < 2 and up is not None and "+" not in up.other:
        named.append(up.other)
    return named
