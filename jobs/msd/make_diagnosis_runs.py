"""Make recorded runs of the mass-spring-damper with an effect concealed in them, for a blind diagnosis.

Four runs of 10 s, each pushed by a logged force of its own shape (steps, pulses, a sine, a ramp) and
released from a position of its own, as a test rig would record them: the logged force and the measured
position, sampled every 0.05 s, with white noise of sigma 2 mm on the position. The plant is the msd FMU
(fmus/msd, model exchange) at k = 12.5 N/m and c = 0.7 N s/m, between the points of the space's grid.

Each case conceals something the model does not know (CASES):

* ``clean``: nothing; a diagnosis should name nothing;
* ``force-late``: the plant receives the logged force 0.3 s late;
* ``sensor-gain-offset``: the position sensor reads 1.1 x + 0.01 m (a pair);
* ``force-clipped``: the actuator saturates: the plant receives the logged force clipped to ±1.2 N (a hard
  nonlinearity on both sides);
* ``force-deadzone``: the actuator ignores forces under 0.5 N and passes the rest less 0.5 N;
* ``force-rate-limited``: the actuator's force changes by at most 3 N/s (at the log's sampling);
* ``sensor-saturated``: the position sensor reads at most 0.08 m.

The effects are made here, not with the master's signal effects the diagnosis fits: the force's log is shifted
in time or clipped before the plant sees it, and the sensor's gain and offset are applied to the simulated
position, which is solved at a finer step than the diagnosis uses (0.01 s against 0.025 s). Written into the
folder: each run's ``<run>-force.csv`` and ``<run>-x.csv``, and a ``space.yaml`` that calibrates k and c on
them and compares the position (nothing of the truth); with ``--folders``, one scenario folder per run instead
(jobs/quickstart/rig was made so, with ``force-deadzone --seed 7``). Run from the repository:

    PYTHONPATH=. python jobs/msd/make_diagnosis_runs.py sensor-gain-offset --out out/msd-blind
    dse-runner diagnose --space out/msd-blind/space.yaml --json
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import yaml

from dse_runner.simulation.run import simulate
from dse_runner.simulation.scenario import Scenario
from dse_runner.simulation.trajectory import Series

HERE = Path(__file__).resolve().parent
MODEL = HERE / "multimodel.yaml"
PLANT = {"msd.k": 12.5, "msd.c": 0.7}
CASES: dict[str, dict[str, float]] = {
    "clean": {},
    "force-late": {"force_delay": 0.3},
    "sensor-gain-offset": {"sensor_gain": 1.1, "sensor_offset": 0.01},
    "force-clipped": {"force_limit": 1.2},
    "force-deadzone": {"force_deadzone": 0.5},
    "force-rate-limited": {"force_rate": 3.0},
    "sensor-saturated": {"sensor_max": 0.08},
}
DURATION = 10.0  # s
LOG_INTERVAL = 0.05  # s: the force log's and the position recording's sampling
TRUTH_STEP = 0.01  # s: the plant's communication step, finer than the space's
SPACE_STEP = 0.025  # s: divides the log interval, so the master changes a held input where the log does
NOISE = 0.002  # m


def _window(t: np.ndarray, start: float, stop: float) -> np.ndarray:
    return ((t >= start) & (t < stop)).astype(float)


# run: (force [N] at the log's times, released from x0 [m])
RUNS: dict[str, tuple[Callable[[np.ndarray], np.ndarray], float]] = {
    "steps": (lambda t: 2.0 * _window(t, 1.0, 3.0) - 1.0 * _window(t, 5.0, 7.0), 0.05),
    "pulses": (lambda t: 3.0 * (_window(t, 1.0, 1.5) + _window(t, 4.0, 4.5) + _window(t, 7.0, 7.5)), 0.0),
    "sine": (lambda t: 1.5 * np.sin(2 * np.pi * 0.4 * (t - 2.0)) * (t >= 2.0), -0.05),
    "ramp": (lambda t: np.clip((t - 2.0) / 4.0, 0.0, 1.0) * 2.0, 0.1),
}


def record(
    name: str, case: Mapping[str, float], rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One run: the log's times, the logged force, and the position the sensor recorded."""
    shape, x0 = RUNS[name]
    t = np.round(np.arange(0.0, DURATION + 1e-9, LOG_INTERVAL), 10)
    force = shape(t)
    limit, zone = case.get("force_limit", np.inf), case.get("force_deadzone", 0.0)
    applied = np.sign(force) * np.maximum(np.abs(np.clip(force, -limit, limit)) - zone, 0.0)
    if "force_rate" in case:  # the actuator follows the log at most this fast, sample by sample
        step = case["force_rate"] * LOG_INTERVAL
        for k in range(1, applied.size):
            applied[k] = applied[k - 1] + np.clip(applied[k] - applied[k - 1], -step, step)
    received = Series(t + case.get("force_delay", 0.0), applied, "hold")  # held before it starts
    run = simulate(
        MODEL,
        Scenario(name, inputs={"msd.F": received}, stop_time=DURATION, step=TRUTH_STEP),
        {"msd.x0": x0, **PLANT},
    )
    x = np.interp(t, run.time, run.outputs["msd.x"])
    sensed = (
        case.get("sensor_gain", 1.0) * x + case.get("sensor_offset", 0.0) + rng.normal(0.0, NOISE, t.size)
    )
    measured = np.minimum(
        sensed, case.get("sensor_max", np.inf)
    )  # a saturated reading is flat: its noise too
    return t, force, measured


def space(folder: Path) -> dict:
    """The study a user would write: the runs, a grid over k and c, the position compared."""
    scenarios = [
        {
            "name": name,
            "inputs": {"msd.F": {"csv": f"{name}-force.csv", "interpolation": "hold"}},
            "parameters": {"msd.x0": x0},
            "recorded": f"{name}-x.csv",
        }
        for name, (_, x0) in RUNS.items()
    ]
    return {
        "name": "msd-blind",
        "multimodel": os.path.relpath(MODEL, folder),
        "experiment": {"stop_time": DURATION, "step": SPACE_STEP},
        "scenarios": scenarios,
        "parameters": {"msd.k": {"start": 8, "stop": 16, "step": 2}, "msd.c": [0.4, 0.8, 1.2]},
        "objectives": {"position": {"signal": "msd.x", "recorded": "x", "metric": "rmse"}},
        "output": "out",
        "cluster": {"n_workers": 2},
    }


def make(case: str, folder: Path, seed: int = 1) -> Path:
    """Write the case's runs and space into ``folder``; the space's path."""
    if case not in CASES:
        raise SystemExit(f"no case {case!r}; there are {', '.join(CASES)}")
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    for name in RUNS:
        t, force, x = record(name, CASES[case], rng)
        np.savetxt(
            folder / f"{name}-force.csv",
            np.column_stack([t, force]),
            delimiter=",",
            header="time,F",
            comments="",
            fmt="%.6g",
        )
        np.savetxt(
            folder / f"{name}-x.csv",
            np.column_stack([t, x]),
            delimiter=",",
            header="time,x",
            comments="",
            fmt="%.6g",
        )
    path = folder / "space.yaml"
    path.write_text(yaml.safe_dump(space(folder), sort_keys=False))
    return path


def make_folders(case: str, folder: Path, seed: int = 1) -> list[Path]:
    """Write the case's runs as scenario folders (``folder/<run>/``: scenario.yaml, force.csv, position.csv),
    the layout a rig's own logs would have; the folders."""
    if case not in CASES:
        raise SystemExit(f"no case {case!r}; there are {', '.join(CASES)}")
    rng = np.random.default_rng(seed)
    made = []
    for name, (_, x0) in RUNS.items():
        t, force, x = record(name, CASES[case], rng)
        run = folder / name
        run.mkdir(parents=True, exist_ok=True)
        np.savetxt(
            run / "force.csv",
            np.column_stack([t, force]),
            delimiter=",",
            header="time,F",
            comments="",
            fmt="%.6g",
        )
        np.savetxt(
            run / "position.csv",
            np.column_stack([t, x]),
            delimiter=",",
            header="time,x",
            comments="",
            fmt="%.6g",
        )
        (run / "scenario.yaml").write_text(
            yaml.safe_dump(
                {
                    "name": name,
                    "inputs": {"msd.F": {"csv": "force.csv", "interpolation": "hold"}},
                    "parameters": {"msd.x0": x0},
                    "recorded": "position.csv",
                    "stop_time": DURATION,
                },
                sort_keys=False,
            )
        )
        made.append(run)
    return made


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", choices=list(CASES))
    parser.add_argument("--out", type=Path, default=None, help="folder (default out/msd-blind/CASE)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--folders", action="store_true", help="one scenario folder per run, and no space.yaml"
    )
    args = parser.parse_args()
    folder = (args.out or Path("out") / "msd-blind" / args.case).resolve()
    if args.folders:
        print(f"wrote {', '.join(str(p) for p in make_folders(args.case, folder, args.seed))}")
        return
    path = make(args.case, folder, args.seed)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
