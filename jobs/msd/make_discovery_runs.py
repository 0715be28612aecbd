"""Make recordings of a mass-spring-damper whose truth has physics the msd FMU lacks: discovery/CASE/.

Why: diagnosis (dse_runner/analysis/diagnose/term_hypotheses.py) should find a term missing
from a model-exchange FMU's equations from recordings alone. Here the truth is

    m x'' = F − k x − c x' + (concealed)

with m = 1 kg, k = 12 N/m, c = 0.6 N s/m and, per case, the concealed term:

* ``cubic``: a hardening spring, −k3 x³ with k3 = 60 N/m³ (der(v) gains −60·x³);
* ``coulomb``: a Coulomb-like friction, −Fc tanh(v / 0.01 m/s) with Fc = 0.3 N;
* ``none``: nothing (what the FMU has is all there is; nothing should be discovered).

The truth is integrated by scipy (not by dse-runner's master), with the force held over each 0.02 s
communication step as the master feeds it. Four runs of 10 s, each driven by a different force (a push, a
sine sweep, two sines, a release from 0.3 m then a pulse); the position is recorded every 0.04 s with white
noise of σ 2 mm (seeded). Each case folder gets the force and position CSVs and a space.yaml that calibrates
k and c (a grid: the calibration) against the position. Run from the repository:
``PYTHONPATH=. python jobs/msd/make_discovery_runs.py [CASE ...] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml
from scipy.integrate import solve_ivp

HERE = Path(__file__).resolve().parent
TRUTH = {"m": 1.0, "k": 12.0, "c": 0.6}
CASES: dict[str, Callable[[float, float], float]] = {
    "cubic": lambda x, v: -60.0 * x**3,
    "coulomb": lambda x, v: -0.3 * np.tanh(v / 0.01),
    "none": lambda x, v: 0.0,
}
CONCEALED = {"cubic": "der(v) += -60·x^3", "coulomb": "der(v) += -0.3·tanh(v/0.01)", "none": "nothing"}
DURATION, STEP, SAMPLE = 10.0, 0.02, 0.04  # s: a sample every other communication point
NOISE_SIGMA = 0.002  # m
SEED = 20250301


def forces() -> dict[str, tuple[Callable[[np.ndarray], np.ndarray], float]]:
    """Each run's force [N] as a function of time, and its initial position x0 [m]."""
    return {
        "push": (lambda t: np.where((t >= 1.0) & (t < 5.0), 3.0, 0.0), 0.0),
        "sweep": (lambda t: 1.0 * np.sin(2 * np.pi * (0.2 + 0.05 * t) * t), 0.0),
        "sines": (
            lambda t: 2.5 * np.sin(2 * np.pi * 0.4 * t) + 1.0 * np.sin(2 * np.pi * 0.9 * t + 1.0),
            0.05,
        ),
        "release": (lambda t: np.where((t >= 6.0) & (t < 7.0), -2.5, 0.0), 0.3),
    }


def grid() -> np.ndarray:
    """The master's communication points (cosim._time_grid): start + step · k."""
    n = round(DURATION / STEP)
    times = STEP * np.arange(n + 1)
    times[-1] = DURATION
    return times


def truth(force_at_points: np.ndarray, x0: float, concealed: Callable[[float, float], float]) -> np.ndarray:
    """The position at the communication points, the force held over each step, solved far tighter than the
    noise."""
    m, k, c = TRUTH["m"], TRUTH["k"], TRUTH["c"]
    times = grid()
    state, xs = np.array([x0, 0.0]), [x0]
    for t0, t1, f in zip(times[:-1], times[1:], force_at_points[:-1]):

        def rhs(t, s, f=f):
            return [s[1], (f - k * s[0] - c * s[1] + concealed(s[0], s[1])) / m]

        state = solve_ivp(rhs, (t0, t1), state, rtol=1e-10, atol=1e-12, method="LSODA").y[:, -1]
        xs.append(state[0])
    return np.array(xs)


def make(case: str, folder: Path, seed: int = SEED) -> Path:
    """Write one case's recordings and space.yaml into ``folder``; returns the space's path."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    times = grid()
    scenarios = []
    for name, (force, x0) in forces().items():
        logged = np.arange(0.0, DURATION + 1e-9, 0.01)
        np.savetxt(
            folder / f"{name}-force.csv",
            np.column_stack([logged, force(logged)]),
            delimiter=",",
            header="time,F",
            comments="",
            fmt="%.10g",
        )
        back = np.loadtxt(
            folder / f"{name}-force.csv", delimiter=",", skiprows=1
        )  # what the master will read
        x = truth(np.interp(times, back[:, 0], back[:, 1]), x0, CASES[case])
        every = round(SAMPLE / STEP)  # a sample at every few communication points
        noisy = x[::every] + rng.normal(0.0, NOISE_SIGMA, x[::every].size)
        np.savetxt(
            folder / f"{name}-x.csv",
            np.column_stack([times[::every], noisy]),
            delimiter=",",
            header="time,x",
            comments="",
            fmt="%.6f",
        )
        scenarios.append(
            {
                "name": name,
                "inputs": {"msd.F": {"csv": f"{name}-force.csv", "interpolation": "linear"}},
                "parameters": {"msd.x0": x0},
                "recorded": f"{name}-x.csv",
            }
        )
    spec = {
        "name": f"msd-discovery-{case}",
        "multimodel": os.path.relpath(HERE / "multimodel.yaml", folder),
        "experiment": {"stop_time": DURATION, "step": STEP},
        "scenarios": scenarios,
        "parameters": {"msd.k": {"start": 6, "stop": 20, "step": 2}, "msd.c": [0.2, 0.6, 1.0, 1.4]},
        "objectives": {
            "position_rmse": {"signal": "msd.x", "recorded": "x", "metric": "rmse"},
            "position": {"signal": "msd.x", "recorded": "x", "metric": "residuals"},
        },
        "output": "out",
        "cluster": {"n_workers": 2},
    }
    header = (
        f"# msd recordings, concealed: {CONCEALED[case]} (made by make_discovery_runs.py; truth {TRUTH})\n"
    )
    (folder / "space.yaml").write_text(header + yaml.safe_dump(spec, sort_keys=False))
    return folder / "space.yaml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="*", choices=[*CASES, []], help="default: every case")
    parser.add_argument(
        "--out", type=Path, default=HERE / "discovery", help="one folder per case is made here"
    )
    args = parser.parse_args()
    for case in args.cases or list(CASES):
        print(f"wrote {make(case, args.out / case)}: concealed {CONCEALED[case]}, noise σ {NOISE_SIGMA} m")


if __name__ == "__main__":
    main()
