"""Recordings from a richer truth model, for blind tests of discrepancy diagnosis.

The truth has vehicle parameters the calibration must find and one effect, two,
or none switched on (a :class:`Case`). For library effects it is the vehicle's
effects variant; for effects outside the library it is tests/fmus/robotti_truth,
a vehicle with its own right-hand side that also carries the library's effects.
It replays the steering logs of the bundled runs, and of synthetic ones
(:func:`synthetic_run`), and records the GPS antenna at 10 Hz with receiver
noise, dropouts and outages, in the field-data format: the diagnosis sees only
these files, never the truth.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import combinations
from pathlib import Path

import numpy as np
import yaml

from dse_runner import bundled
from dse_runner.cases.fielddata import read_info
from dse_runner.simulation.multimodel import parse_multimodel
from dse_runner.simulation.run import as_plan, simulate
from dse_runner.simulation.scenario import INFO_FILE, load_scenario

REPO = Path(__file__).resolve().parents[2]
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
PAIRS = {
    f"{a}+{b}": {**EFFECTS[a], **EFFECTS[b]} for a, b in combinations([e for e in EFFECTS if e != "none"], 2)
}

# Synthetic manoeuvres (synthetic_run): the bundled steering is sines and ramps, on which a delay, a lag and
# a lower gain all look like a phase shift; a step shows a delay as a late jump and a lag as a slow rise.
# The slaloms are one steering sine at two speeds (what changes with speed); the loops turn through every
# heading, one each way: runs of one group (the loops) are spread over the folds (explain.folds), so every
# fold's training runs see every heading.
SYNTHETIC = ("steer_steps", "slalom_slow", "slalom_fast", "loop", "loop_left")
LOOPS = {"loop": 1.0, "loop_left": -1.0}  # the sign of LOOP_STEERING: to the right, to the left
PAIR_RUNS = [*RUNS, "steer_steps"]  # what pair cases record
SLALOM = {"slalom_slow": 0.8, "slalom_fast": 2.0}  # m/s
SLALOM_AMPLITUDE, SLALOM_PERIOD = 0.2, 8.0  # rad, s: as the bundled sines' swing, 2.5 times as fast
LOOP_SPEED, LOOP_STEERING, LOOP_TURNING = 1.6, 0.25, 30.0  # m/s, rad, s: about 6.7 rad of heading

# Effects outside the library, in tests/fmus/robotti_truth (variables of that FMU, as the library's are of
# the effects variant), at a size a field engineer would care about, with the synthetic runs that expose
# each form.
# slip_pull's constant part is the library's wheel_slip; it grows with the drive force.
OUTSIDE = {
    "relaxation": ({"relaxation": 0.8}, ("steer_steps", "slalom_slow", "slalom_fast")),
    "steer_gain_speed": ({"steer_gain_speed": 0.12}, ("slalom_slow", "slalom_fast")),
    "payload": ({"payload": 400.0, "payload_time": 10.0, "payload_draft": 0.06}, ()),
    "mast_roll": ({"mast_roll": 0.2, "mast_roll_heading": 0.7}, ("loop", "loop_left")),
    "slip_pull": ({"wheel_slip": 0.03, "slip_pull": 0.3}, ()),  # the benchmark's only
    # the benchmark's only; a limit shows only where the steering moves faster than it, and held-out error can
    # prove only what each fold's training runs show: the steps, the slaloms (peak rate 0.16 rad/s) and the
    # loops' turn-in (a 0.25 rad step), one loop in each fold (with the slaloms and steps alone, one fold
    # trained on a single run that shows the limit and proposed no term)
    "steer_rate_limit": (
        {"steer_rate_limit": 0.08},
        ("steer_steps", "slalom_slow", "slalom_fast", "loop", "loop_left"),
    ),
    # one manoeuvre at two speeds: a constant resisting force slows both by the same, wheel slip in proportion
    "rolling_resistance": ({"rolling_resistance": 0.05}, ("slalom_slow", "slalom_fast")),
}
OUTSIDE_BENCHMARK = ("slip_pull", "steer_rate_limit")  # not meant for CI: one more look-alike of each kind
OUTSIDE_BEFORE_NOISE = (
    6  # the first cases of OUTSIDE, which came before the noise cases (their seeds: _cases)
)

# Noise only, heavier than the singles' "none": a worse receiver, or a coloured one (multipath wanders).
NOISE_CASES = {
    "noise_heavy": {"noise": 0.05, "dropout": 0.10, "outages": 2, "outage_s": 5.0},
    "noise_coloured": {"colour": 0.9},  # the benchmark's only
}
FIX_PERIOD = 0.1  # s, the receiver's
VEHICLES = {
    "effects": "bundled:fmus/robotti_vehicle_effects",
    "truth": str(REPO / "tests" / "fmus" / "robotti_truth"),
}


@dataclass(frozen=True)
class Case:
    """A blind case's truth: the library effects concealed, their parameters' values, the vehicle that
    records them, the runs recorded, and the receiver (its noise, its seed, its dropouts and outages)."""

    name: str
    effects: tuple[str, ...]  # library ids; () for noise only and for effects outside the library
    truth: dict[str, float]  # effect parameters of the truth (variables of the vehicle below)
    runs: tuple[str, ...]  # bundled or synthetic run names
    seed: int
    vehicle: str = "effects"  # a key of VEHICLES: "truth" for effects outside the library
    noise: float = NOISE  # m, per axis
    dropout: float = 0.03  # probability that a fix is missing
    outages: int = 1  # per run, each in its own part of the run
    outage_s: float = 2.0  # s, each
    colour: float = 0.0  # lag-1 correlation of the noise from fix to fix (AR(1)); 0 = white
    benchmark_only: bool = False


def _cases() -> dict[str, Case]:
    """Singles keep the seeds they always had (sorted names); pairs take the next ones, in PAIRS' order,
    then the effects outside the library and the noise cases, then the effects outside the library added
    since (after OUTSIDE_BEFORE_NOISE): adding a case never moves an older case's noise."""
    singles = {
        e: Case(e, (e,) if e != "none" else (), EFFECTS[e], tuple(RUNS), sorted(EFFECTS).index(e))
        for e in EFFECTS
    }
    pairs = {
        p: Case(p, tuple(p.split("+")), truth, tuple(PAIR_RUNS), len(EFFECTS) + k)
        for k, (p, truth) in enumerate(PAIRS.items())
    }
    later = list(OUTSIDE)[:OUTSIDE_BEFORE_NOISE] + list(NOISE_CASES) + list(OUTSIDE)[OUTSIDE_BEFORE_NOISE:]
    seed = {name: len(singles) + len(pairs) + k for k, name in enumerate(later)}
    outside = {
        o: Case(
            o, (), truth, (*RUNS, *synthetic), seed[o], vehicle="truth", benchmark_only=o in OUTSIDE_BENCHMARK
        )
        for o, (truth, synthetic) in OUTSIDE.items()
    }
    noise = {
        n: Case(n, (), {}, tuple(RUNS), seed[n], benchmark_only=n == "noise_coloured", **receiver)
        for n, receiver in NOISE_CASES.items()
    }
    return singles | pairs | outside | noise


CASES = _cases()


def truth_of(case: str) -> dict[str, float]:
    """The effect parameters a case switches on in the truth: a single effect's, a pair's, or one outside the
    library (variables of tests/fmus/robotti_truth)."""
    return CASES[case].truth


def seed_of(case: str) -> int:
    """Each case's own noise, so that two cases never share a noise draw."""
    return CASES[case].seed


def synthetic_length(name: str, seconds: float) -> float:
    """How long a synthetic run lasts when runs are cut to ``seconds``: the loop never less than its whole
    turn (1 s at rest, 1 s to start, LOOP_TURNING s turning), since a part of a circle leaves headings out."""
    return max(seconds, 2.0 + LOOP_TURNING) if name in LOOPS else seconds


def synthetic_commands(name: str, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Commanded speed [m/s] and steering [rad, positive = right] of a synthetic run at ``times``.

    ``steer_steps``: at rest for 1 s, then 1.2 m/s with the steering stepped every 5 s through 0, +0.1, 0,
    -0.1 rad: each step separates a delay (the same jump, late) from a lag (a slow rise) and from an offset
    (straight segments between the steps).
    ``slalom_slow``, ``slalom_fast``: at rest for 1 s, then 0.8 or 2.0 m/s, and from 2 s a steering sine of
    0.2 rad and 8 s: the same steering at two speeds, so an effect that grows or fades with speed (a tyre's
    relaxation length, a steering gain) cannot pass for a constant one.
    ``loop``: at rest for 1 s, then 1.6 m/s, and from 2 s a steady 0.25 rad to the right: about 6.7 rad of
    heading in 30 s, so an error that depends on the heading (a leaning antenna mast) shows at every
    heading; ``loop_left`` is the same turn to the left."""
    moving = times >= 1.0
    if name == "steer_steps":
        return np.where(moving, 1.2, 0.0), np.array([0.0, 0.1, 0.0, -0.1])[(times // 5.0).astype(int) % 4]
    if name in SLALOM:
        sine = SLALOM_AMPLITUDE * np.sin(2 * np.pi * (times - 2.0) / SLALOM_PERIOD)
        return np.where(moving, SLALOM[name], 0.0), np.where(times >= 2.0, sine, 0.0)
    if name in LOOPS:
        return np.where(moving, LOOP_SPEED, 0.0), np.where(times >= 2.0, LOOPS[name] * LOOP_STEERING, 0.0)
    raise ValueError(f"unknown synthetic run {name!r}: there is {', '.join(SYNTHETIC)}")


def synthetic_run(name: str, seconds: float) -> tuple[dict, list[str]]:
    """A manoeuvre no bundled run has, as (scenario.yaml's fields, steering log lines), ``seconds`` long
    (the loop at least its whole turn: :func:`synthetic_length`); the manoeuvres are
    :func:`synthetic_commands`'."""
    duration = synthetic_length(name, seconds)
    times = np.round(np.arange(0.0, duration + 1e-9, STEP), 2)
    speed, steering = synthetic_commands(name, times)
    lines = ["time,velocity,delta_f"] + [
        f"{t:.2f},{v:.3f},{d:.4f}" for t, v, d in zip(times, speed, steering)
    ]
    info = {
        "name": name,
        "group": "loop" if name in LOOPS else name,
        "duration": float(duration),
        "initial_pose": {"x": 0.0, "y": 0.0, "theta": 0.0},
    }
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


def truth_plan(vehicle: str = "effects"):
    """The bundled multi-model with the replay controller driving the truth's vehicle (a key of VEHICLES)."""
    data = yaml.safe_load(bundled.bundled_path("bundled:robotti/multimodel.yaml").read_text())
    data["fmus"] = {"controller": "bundled:fmus/replay_controller", "vehicle": VEHICLES[vehicle]}
    return as_plan(parse_multimodel(data, "truth", REPO))


def truth_values(case: Case) -> dict[str, float]:
    """What the truth's vehicle is set to for a case: the vehicle the calibration must find, and the
    effects."""
    return {**TRUTH_VEHICLE, **{f"vehicle.{k}": v for k, v in case.truth.items()}}


def receiver(case: Case, fixes: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The receiver's errors (x, y) [m] and which fixes it keeps, for ``fixes`` fixes of one run.

    The draws come in the order they always did (noise x, noise y, dropouts, first outage), so a white-noise,
    one-outage case records the very files it did before cases had receivers. Coloured noise is the same
    draws through an AR(1) filter that keeps their variance; each outage starts in the second quarter of its
    share of the run, so two never overlap while each is shorter than half a share."""
    ex, ey = rng.normal(0, case.noise, fixes), rng.normal(0, case.noise, fixes)
    if case.colour:
        ex, ey = ar1(ex, case.colour), ar1(ey, case.colour)
    keep = rng.random(fixes) >= case.dropout
    share, length = fixes // max(case.outages, 1), round(case.outage_s / FIX_PERIOD)
    for k in range(case.outages):
        start = k * share + rng.integers(share // 4, share // 2)
        keep[start : start + length] = False
    keep[0] = True
    return ex, ey, keep


def ar1(white: np.ndarray, rho: float) -> np.ndarray:
    """White noise coloured by e[k] = rho e[k-1] + sqrt(1 - rho^2) w[k], from a stationary start: the same
    standard deviation, correlated from fix to fix."""
    out = np.empty_like(white)
    out[0] = white[0]
    gain = np.sqrt(1.0 - rho * rho)
    for k in range(1, white.size):
        out[k] = rho * out[k - 1] + gain * white[k]
    return out


def record(
    folder: Path,
    effect: str | Case,
    runs: list[str] | tuple[str, ...],
    seconds: float,
    noise: float | None = None,
    dropout: float | None = None,
    seed: int = 0,
) -> Path:
    """Write ``runs`` (names of bundled or synthetic runs, cut to ``seconds``) as recorded by the truth with
    ``effect`` (a name of CASES, or a Case), on its receiver; ``noise`` and ``dropout`` override the
    case's."""
    case = effect if isinstance(effect, Case) else CASES[effect]
    case = replace(
        case,
        noise=case.noise if noise is None else noise,
        dropout=case.dropout if dropout is None else dropout,
    )
    rng = np.random.default_rng(seed)
    plan = truth_plan(case.vehicle)
    overrides = truth_values(case)
    for name in runs:
        info, lines = source(name, seconds)
        duration = info["duration"]
        target = folder / name
        target.mkdir(parents=True, exist_ok=True)
        (target / "steering_inputs.csv").write_text("\n".join(lines) + "\n")
        (target / INFO_FILE).write_text(yaml.safe_dump(info, sort_keys=False))
        (target / "gps_position.csv").write_text("time,x,y\n0,0,0\n")  # replaced below
        run = simulate(plan, load_scenario(target), overrides, objectives=(), step=STEP)
        fixes = np.round(np.arange(0.0, duration + 1e-9, FIX_PERIOD), 2)
        x, y = run.trajectory.column("vehicle.gps_x"), run.trajectory.column("vehicle.gps_y")  # the antenna
        ex, ey, keep = receiver(case, fixes.size, rng)
        gx = np.interp(fixes, run.trajectory.time, x) + ex
        gy = np.interp(fixes, run.trajectory.time, y) + ey
        rows = [f"{t:.2f},{a:.4f},{b:.4f}" for t, a, b in zip(fixes[keep], gx[keep], gy[keep])]
        (target / "gps_position.csv").write_text("time,x,y\n" + "\n".join(rows) + "\n")
    return folder


def calibration_space(folder: Path) -> Path:
    """The paper's design space, coarser: cAlphaF x mass, 4 x 3 points (the truth lies between them)."""
    path = folder / "calibration.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": "blind-calibration",
                "multimodel": "bundled:robotti/multimodel.yaml",
                "scenarios": [str(SOURCES / "sin1")],  # replaced by the recordings under test
                "parameters": {
                    "vehicle.cAlphaF": {"start": 20000, "stop": 38000, "step": 6000},
                    "vehicle.mass": {"start": 1000, "stop": 3000, "step": 1000},
                },
                "objectives": ["cross_track_error"],
            }
        )
    )
    return path


def run_case(
    effect: str,
    root: Path,
    client=None,
    address: str | None = None,
    seconds: float = SECONDS,
    seed: int = 0,
    runs: list[str] | tuple[str, ...] | None = None,
    settings=None,
):
    """Record case ``effect`` on ``runs`` (default: the case's own) under ``root`` and diagnose it with
    ``settings`` (default: two folds); returns (runs folder, calibration space, Diagnosis). ``seed`` shifts
    every case's noise, to check that a pass is not luck."""
    from dse_runner.cases.robotti_diagnosis import DiagnosisSettings, diagnose

    case = CASES[effect]
    runs = record(root / "runs", effect, case.runs if runs is None else runs, seconds, seed=case.seed + seed)
    space = calibration_space(root)
    result = diagnose(
        runs,
        space=space,
        out=root / "out",
        settings=settings or DiagnosisSettings(folds=2),
        client=client,
        address=address,
    )
    return runs, space, result


def benchmark_runs(effect: str) -> list[str]:
    """The benchmark's runs for a case: every bundled manoeuvre (BENCHMARK_RUNS)
    and the case's synthetic ones."""
    return [*BENCHMARK_RUNS, *(r for r in CASES[effect].runs if r in SYNTHETIC)]


def top_two(result) -> list[str]:
    """The effects a diagnosis names first: its first two, or its one effect and a single-effect runner-up
    (the pairs' target: both concealed effects among these)."""
    named = [e["id"] for e in result.effects if e["id"] != "none"][:2]
    up = result.runner_up
    if len(named) < 2 and up is not None and "+" not in up.other:
        named.append(up.other)
    return named


def discovered_entry(result) -> dict | None:
    """The diagnosis' discovered correction among its effects, or None."""
    return next((e for e in result.effects if e["id"] == "discovered"), None)


def outside_target(result) -> bool:
    """The issue's target for an effect outside the library: no library effect claimed as the cause without
    the "partial" qualifier, and a discovered correction that at least halves the held-out cross-track error
    of the library's best."""
    found = discovered_entry(result)
    honest = all(e["partial"] for e in result.effects if e["id"] not in ("none", "discovered"))
    return honest and found is not None and found["held_out_with"] <= 0.5 * found["held_out_without"]


def noise_target(result, sigma: float) -> bool:
    """The issue's target on noise only: nothing named or discovered, and the noise, estimated from the files
    alone, within 20 % of the receiver's ``sigma``."""
    return (
        [e["id"] for e in result.effects] == ["none"]
        and discovered_entry(result) is None
        and result.floor.available
        and abs(result.floor.sigma / sigma - 1.0) <= 0.20
    )
