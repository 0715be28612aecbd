"""Make recordings of a pendulum whose truth has a drag the pendulum FMU lacks: discovery/CASE/.

Why: a second model-exchange model for terms inside the model (dse_runner/analysis/diagnose/
term_hypotheses.py), with a concealed term of another shape than the msd's. The truth is

    m l² w' = tau − m g l sin(theta) − b w − (concealed)

with m = 1 kg, l = 0.8 m, g = 9.81 m/s², b = 0.05 N m s and, per case, the concealed term:

* ``drag``: quadratic air drag on the bob, cd w |w| with cd = 0.08 N m s² (der(w) gains −0.125·w·|w|);
* ``none``: nothing.

The truth is integrated by scipy (not by dse-runner's master), with the torque held over each 0.02 s
communication step as the master feeds it. Four runs of 10 s (two releases, a push, a sine torque); the angle
is recorded every 0.04 s with white noise of σ 2 mrad (seeded). Each case folder gets the torque and angle
CSVs and a space.yaml that calibrates l and b (a grid: the calibration) against the angle. Run from the
repository: ``PYTHONPATH=. python jobs/pendulum/make_discovery_runs.py [CASE ...] [--out DIR]``.
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
TRUTH = {"m": 1.0, "l": 0.8, "g": 9.81, "b": 0.05}
CASES: dict[str, Callable[[float], float]] = {"drag": lambda w: 0.08 * w * abs(w), "none": lambda w: 0.0}
CONCEALED = {"drag": "der(w) += -0.125·w·|w|", "none": "nothing"}
DURATION, STEP, SAMPLE = 10.0, 0.02, 0.04  # s: a sample every other communication point
NOISE_SIGMA = 0.002  # rad
SEED = 20250302


def torques() -> dict[str, tuple[Callable[[np.ndarray], np.ndarray], float]]:
    """Each run's torque [N m] as a function of time, and its initial angle theta0 [rad]."""
    return {
        "release": (lambda t: 0.0 * t, 0.8),
        "high": (lambda t: 0.0 * t, 1.3),
        "push": (lambda t: np.where((t >= 1.0) & (t < 3.0), 2.0, 0.0), 0.0),
        "sine": (lambda t: 1.5 * np.sin(2 * np.pi * 0.45 * t), 0.2),
    }


def grid() -> np.ndarray:
    """The master's communication points (cosim._time_grid): start + step · k."""
    n = round(DURATION / STEP)
    times = STEP * np.arange(n + 1)
    times[-1] = DURATION
    return times


def truth(torque_at_points: np.ndarray, theta0: float, concealed: Callable[[float], float]) -> np.ndarray:
    """The angle at the communication points, the torque held over each step, solved far tighter than the
    noise."""
    m, l, g, b = TRUTH["m"], TRUTH["l"], TRUTH["g"], TRUTH["b"]
    times = grid()
    state, angles = np.array([theta0, 0.0]), [theta0]
    for t0, t1, tau in zip(times[:-1], times[1:], torque_at_points[:-1]):

        def rhs(t, s, tau=tau):
            return [s[1], (tau - m * g * l * np.sin(s[0]) - b * s[1] - concealed(s[1])) / (m * l * l)]

        state = solve_ivp(rhs, (t0, t1), state, rtol=1e-10, atol=1e-12, method="LSODA").y[:, -1]
        angles.append(state[0])
    return np.array(angles)


def make(case: str, folder: Path, seed: int = SEED) -> Path:
    """Write one case's recordings and space.yaml into ``folder``; returns the space's path."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    times = grid()
    every = round(SAMPLE / STEP)
    scenarios = []
    for name, (torque, theta0) in torques().items():
        logged = np.arange(0.0, DURATION + 1e-9, 0.01)
        np.savetxt(
            folder / f"{name}-tau.csv",
            np.column_stack([logged, torque(logged)]),
            delimiter=",",
            header="time,tau",
            comments="",
            fmt="%.10g",
        )
        back = np.loadtxt(folder / f"{name}-tau.csv", delimiter=",", skiprows=1)  # what the master will read
        theta = truth(np.interp(times, back[:, 0], back[:, 1]), theta0, CASES[case])
        noisy = theta[::every] + rng.normal(0.0, NOISE_SIGMA, theta[::every].size)
        np.savetxt(
            folder / f"{name}-theta.csv",
            np.column_stack([times[::every], noisy]),
            delimiter=",",
            header="time,theta",
            comments="",
            fmt="%.6f",
        )
        scenarios.append(
            {
                "name": name,
                "inputs": {"pendulum.tau": {"csv": f"{name}-tau.csv", "interpolation": "linear"}},
                "parameters": {"pendulum.theta0": theta0},
                "recorded": f"{name}-theta.csv",
            }
        )
    spec = {
        "name": f"pendulum-discovery-{case}",
        "multimodel": os.path.relpath(HERE / "multimodel.yaml", folder),
        "experiment": {"stop_time": DURATION, "step": STEP},
        "scenarios": scenarios,
        "parameters": {
            "pendulum.l": {"start": 0.5, "stop": 1.2, "step": 0.1},
            "pendulum.b": [0.0, 0.1, 0.2, 0.3],
        },
        "objectives": {
            "angle_rmse": {"signal": "pendulum.theta", "recorded": "theta", "metric": "rmse"},
            "angle": {"signal": "pendulum.theta", "recorded": "theta", "metric": "residuals"},
        },
        "output": "out",
        "cluster": {"n_workers": 2},
    }
    header = (
        f"# pendulum recordings, concealed: {CONCEALED[case]} "
        f"(made by make_discovery_runs.py; truth {TRUTH})\n"
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
        print(f"wrote {make(case, args.out / case)}: concealed {CONCEALED[case]}, noise σ {NOISE_SIGMA} rad")


if __name__ == "__main__":
    main()
