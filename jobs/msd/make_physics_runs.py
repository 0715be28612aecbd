"""Make recordings as unkind as real ones, of machines with physics the msd FMU lacks: physics/CASE/.

Why: a yardstick for diagnosing missing physics *inside* a model-exchange model. make_discovery_runs.py's
recordings are kind (white noise, known initial state, the force pushing from rest); real ones are not
(jobs/cascaded_tanks). Here every record is as a test rig gives it:

* only the position is logged (``time,x``), never the velocity;
* an encoder's quantisation: the position rounded to 0.5 mm;
* coloured noise: AR(1) noise (ρ 0.8, stationary σ 0.7 mm) plus white noise (σ 0.2 mm), seeded;
* an unknown initial state: every record of a case starts from the same position and velocity, neither of
  them zero nor given in the space (the space calibrates msd.x0 and msd.v0 on intervals, as the tanks'
  space does its initial levels);
* open-loop drift where the machine has no spring (``friction``: its position wanders 0.7–1.6 m);
* a force logged and held every 0.04 s (a DAC's zero-order hold), the position sampled with it, 24 s a record.

The user's model is the msd FMU of jobs/msd (m x'' = F − k x − c x'). The truths, per case:

* ``hardening``: an electronic oscillator whose spring hardens, m = 1, k = 12, c = 0.3 and −k3·x³ with
  k3 = 80 N/m³ (der(v) gains −80·x³): at the records' peaks (0.21–0.25 m) the cubic force is 29–42 % of
  the linear one, at 5 cm 1.7 %. Three records: a multisine around the resonance (0.55 Hz), a
  swept sine (0.2 to 1.2 Hz) and an "arrow", a 0.6 Hz sine whose amplitude ramps up linearly. x0 = 0.06 m,
  v0 = −0.25 m/s.
* ``friction``: a positioning stage with no spring, M = 2 kg, viscous c = 1.5 N s/m and Coulomb friction of
  Fc = 1.0 N with sticking: the set-valued law (friction balances the force while |F| ≤ Fc at v = 0, else it
  is −Fc·sign(v)), that is Karnopp's model with its band shrunk to zero. It is integrated exactly: mode by
  mode (slipping forwards, backwards, stuck), each slipping stretch by solve_ivp with an event at v = 0, so no
  smoothed sign and no stiff solver are needed. Three records of zero-mean forces that reverse slowly and
  often (two low-pass-filtered random forces, one low-frequency multisine) of a few Fc: the stage sticks
  and slips and, having no spring, drifts. x0 = 0.12 m, v0 = 0.3 m/s. The user's model has k = 0, fixed.
* ``plain``: the oscillator of ``hardening`` without the cubic (k3 = 0): a control case where nothing is
  missing inside the model.

Each case also gets a held-back ``test/`` record (a scenario folder like jobs/cascaded_tanks/estimation:
scenario.yaml, force.csv, x.csv), from the same initial state, for a benchmark to predict and never to fit:
``dse-runner simulate jobs/msd/multimodel.yaml --scenario jobs/msd/physics/CASE/test --values VALUES.yaml``.
For the oscillators it is a different multisine of larger amplitude (0.30 m: the cubic force 61 % of the
linear one), for the stage another filtered random force.

The force reaches the truth exactly as the master feeds it: read back from its CSV, sampled at the master's
communication points (every 0.02 s; cosim._time_grid) as the scenario's ``interpolation: hold`` does
(trajectory.Series.at) and held over each step. Each case folder gets the force and position CSVs and a
space.yaml that calibrates the user's model on intervals (m, k, c, x0, v0; the stage's k fixed at 0), scored
by the position. Run from the repository:
``PYTHONPATH=. python jobs/msd/make_physics_runs.py [CASE ...] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from scipy.integrate import solve_ivp
from scipy.signal import butter, sosfiltfilt

HERE = Path(__file__).resolve().parent
DURATION, STEP, SAMPLE = 24.0, 0.02, 0.04  # s: the force and the position every other communication point
QUANTUM = 0.0005  # m: the encoder's step
AR_RHO, AR_SIGMA, WHITE_SIGMA = 0.8, 0.0007, 0.0002  # AR(1) coefficient, its stationary σ [m]; white σ [m]
SEED = 20251130  # the noise (one stream per case)
FORCE_SEED = 7  # the forces' random phases and random signals (the same for hardening and plain)
RTOL, ATOL = 1e-10, 1e-12


@dataclass(frozen=True)
class Truth:
    """m x'' = F − k x − c x' − k3 x³ − friction, from (x0, v0); friction is Coulomb's with sticking."""

    m: float
    k: float
    c: float
    k3: float
    fc: float
    x0: float
    v0: float


OSCILLATOR = {"m": 1.0, "k": 12.0, "c": 0.3, "x0": 0.06, "v0": -0.25}
TRUTHS = {
    "hardening": Truth(**OSCILLATOR, k3=80.0, fc=0.0),
    "friction": Truth(m=2.0, k=0.0, c=1.5, k3=0.0, fc=1.0, x0=0.12, v0=0.3),
    "plain": Truth(**OSCILLATOR, k3=0.0, fc=0.0),
}
CONCEALED = {
    "hardening": "a hardening spring, der(v) += -80·x^3 (k3 = 80 N/m^3)",
    "friction": "Coulomb friction with sticking, -1.0 N·sign(v) (der(v) += -0.5·sign(v); stuck at |F| <= 1)",
    "plain": "nothing (the control case)",
}
Force = Callable[[np.ndarray], np.ndarray]


def multisine(freqs: list[float], amplitude: float, seed: int) -> Force:
    """A sum of sines of ``amplitude`` each at ``freqs`` [Hz], random phases."""
    phases = np.random.default_rng(seed).uniform(0.0, 2 * np.pi, len(freqs))
    return lambda t: sum(amplitude * np.sin(2 * np.pi * f * t + p) for f, p in zip(freqs, phases))


def filtered_random(cutoff: float, rms: float, seed: int) -> Force:
    """Gaussian noise low-passed at ``cutoff`` [Hz] (4th-order Butterworth, zero phase), zero mean, ``rms``
    [N], drawn on the sample grid and held between its samples."""
    t = samples()
    sos = butter(4, cutoff, fs=1.0 / SAMPLE, output="sos")
    noise = sosfiltfilt(sos, np.random.default_rng(seed).normal(size=t.size + 400))[200:-200]
    noise = noise - noise.mean()
    values = rms * noise / np.sqrt(np.mean(noise**2))
    return lambda s: values[np.clip(np.searchsorted(t, s, side="right") - 1, 0, t.size - 1)]


def forces(case: str) -> dict[str, Force]:
    """Each record's force [N] by name; ``test`` is the held-back record."""
    if case == "friction":
        return {
            "random1": filtered_random(0.6, 1.5, FORCE_SEED),
            "random2": filtered_random(1.0, 1.5, FORCE_SEED + 1),
            "multisine": multisine([0.12, 0.2, 0.31, 0.47], 0.9, FORCE_SEED + 2),
            "test": filtered_random(0.8, 1.5, FORCE_SEED + 3),
        }
    return {
        "multisine": multisine([0.3, 0.42, 0.5, 0.58, 0.66, 0.8, 1.0], 0.16, FORCE_SEED),
        "sweep": lambda t: 0.5 * np.sin(2 * np.pi * (0.2 + 0.5 * (1.2 - 0.2) * t / DURATION) * t),
        "arrow": lambda t: 0.45 * (t / DURATION) * np.sin(2 * np.pi * 0.6 * t),
        "test": multisine([0.34, 0.46, 0.54, 0.62, 0.74, 0.9], 0.24, FORCE_SEED + 1),
    }


def samples() -> np.ndarray:
    """The logged times: every SAMPLE from 0 to DURATION."""
    return SAMPLE * np.arange(round(DURATION / SAMPLE) + 1)


def grid() -> np.ndarray:
    """The master's communication points (cosim._time_grid): start + step · k, the last one the stop time."""
    times = STEP * np.arange(round(DURATION / STEP) + 1)
    times[-1] = DURATION
    return times


def fed(csv: Path) -> np.ndarray:
    """The force as the master feeds it: the CSV as read, held (trajectory.Series.at, ``hold``) at the
    communication points; each value is held over the step that starts there."""
    back = np.loadtxt(csv, delimiter=",", skiprows=1)
    index = np.searchsorted(back[:, 0], grid(), side="right") - 1
    return back[np.clip(index, 0, len(back) - 1), 1]


def smooth_step(truth: Truth, state: np.ndarray, t0: float, t1: float, f: float) -> np.ndarray:
    """One communication step of the frictionless oscillator under a held force."""

    def rhs(t, s):
        x, v = s
        return [v, (f - truth.k * x - truth.c * v - truth.k3 * x**3) / truth.m]

    return solve_ivp(rhs, (t0, t1), state, method="DOP853", rtol=RTOL, atol=ATOL).y[:, -1]


def friction_step(truth: Truth, state: np.ndarray, t0: float, t1: float, f: float) -> np.ndarray:
    """One communication step with Coulomb friction and sticking under a held force, mode by mode: stuck
    (v = 0) while |F| ≤ Fc; otherwise slipping in the direction s of v (or of F, starting from rest), friction
    −Fc·s, until v reaches 0 (an event), where the mode is chosen again."""
    x, v = state
    t = t0
    while t < t1:
        if v == 0.0:
            if abs(f) <= truth.fc:  # stuck: the force stays a held constant to the step's end
                return np.array([x, 0.0])
            s = float(np.sign(f))
        else:
            s = float(np.sign(v))

        def rhs(_, y, s=s):
            return [
                y[1],
                (f - truth.k * y[0] - truth.c * y[1] - truth.k3 * y[0] ** 3 - truth.fc * s) / truth.m,
            ]

        def stops(_, y):
            return y[1]

        stops.terminal, stops.direction = True, -s  # v falling to 0 from the side it slips on
        sol = solve_ivp(rhs, (t, t1), [x, v], method="DOP853", rtol=RTOL, atol=ATOL, events=stops)
        if sol.status == 1:  # reached v = 0 before the step's end
            t, x, v = float(sol.t_events[0][0]), float(sol.y_events[0][0][0]), 0.0
        else:
            return sol.y[:, -1]
    return np.array([x, v])


def simulate_truth(truth: Truth, force_at_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity at the communication points, the force held over each step."""
    step = friction_step if truth.fc > 0 else smooth_step
    times = grid()
    state = np.array([truth.x0, truth.v0])
    states = [state]
    for t0, t1, f in zip(times[:-1], times[1:], force_at_points[:-1]):
        state = step(truth, state, float(t0), float(t1), float(f))
        states.append(state)
    out = np.array(states)
    return out[:, 0], out[:, 1]


def unkind(x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """What the encoder logs: ``x`` plus AR(1) noise (stationary from the start) and white noise, rounded
    to the encoder's step."""
    innovations = rng.normal(0.0, AR_SIGMA * np.sqrt(1 - AR_RHO**2), x.size)
    ar = np.empty(x.size)
    ar[0] = rng.normal(0.0, AR_SIGMA)
    for i in range(1, x.size):
        ar[i] = AR_RHO * ar[i - 1] + innovations[i]
    noisy = x + ar + rng.normal(0.0, WHITE_SIGMA, x.size)
    return QUANTUM * np.round(noisy / QUANTUM)


def write_csv(path: Path, column: str, t: np.ndarray, values: np.ndarray, fmt: str) -> None:
    np.savetxt(
        path,
        np.column_stack([t, values]),
        delimiter=",",
        header=f"time,{column}",
        comments="",
        fmt=["%.10g", fmt],
    )


def record(
    case: str, force: Force, folder: Path, stem: str, rng: np.random.Generator, judged: bool = False
) -> dict[str, float]:
    """Write ``stem``force.csv and ``stem``x.csv of one record into ``folder``; a few figures of its truth.
    ``judged`` (the held-back record): also the true velocity, noise-free, in ``velocity.csv``, which no
    diagnosis reads: a benchmark judges the predicted velocity by it (the held-back stage is judged so)."""
    t = samples()
    force_csv, x_csv = folder / f"{stem}force.csv", folder / f"{stem}x.csv"
    write_csv(force_csv, "F", t, force(t), "%.6g")
    truth = TRUTHS[case]
    x, v = simulate_truth(truth, fed(force_csv))
    every = round(SAMPLE / STEP)
    write_csv(x_csv, "x", t, unkind(x[::every], rng), "%.4f")
    if judged:
        write_csv(folder / f"{stem}velocity.csv", "v", t, v[::every], "%.8g")
    peak = float(np.max(np.abs(x)))
    if truth.fc == 0:  # the cubic force's share of the linear one at the peak
        return {"peak_x": peak, "cubic_share": truth.k3 * peak**2 / truth.k}
    return {  # how far the stage wanders, how long it sticks, how often it turns
        "range_x": float(np.ptp(x)),
        "net_drift": float(x[-1] - x[0]),
        "stuck_share": float(np.mean(v == 0.0)),
        "reversals": int(np.sum(np.diff(np.sign(v[v != 0])) != 0)),
    }


def make(case: str, folder: Path, seed: int = SEED) -> Path:
    """Write one case's records, its test folder and its space.yaml into ``folder``; returns the space."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng([seed, list(TRUTHS).index(case)])
    scenarios = []
    for name, force in forces(case).items():
        where, stem = (folder / "test", "") if name == "test" else (folder, f"{name}-")
        where.mkdir(exist_ok=True)
        figures = record(case, force, where, stem, rng, judged=name == "test")
        print(f"  {case}/{name}: " + ", ".join(f"{k} {v:.4g}" for k, v in figures.items()))
        inputs = {"msd.F": {"csv": f"{stem}force.csv", "column": "F", "interpolation": "hold"}}
        if name == "test":
            test = {
                "name": "test",
                "inputs": inputs,
                "recorded": "x.csv",
                "stop_time": DURATION,
                "step": STEP,
            }
            if case == "friction":
                test["parameters"] = {"msd.k": 0.0}  # the user's model of a stage has no spring
            (where / "scenario.yaml").write_text(
                f"# The held-back test record of {case} (make_physics_runs.py): predict it, never fit it.\n"
                "# The force F [N] is held between its samples; x [m] is the encoder's position.\n"
                + yaml.safe_dump(test, sort_keys=False)
            )
        else:
            scenarios.append({"name": name, "inputs": inputs, "recorded": f"{stem}x.csv"})
    if case == "friction":
        parameters = {
            "msd.m": {"low": 0.5, "high": 5.0},
            "msd.k": [0.0],  # a stage: no spring
            "msd.c": {"low": 0.05, "high": 5.0},
            "msd.x0": {"low": -0.5, "high": 0.5},
            "msd.v0": {"low": -1.0, "high": 1.0},
        }
    else:
        parameters = {
            "msd.m": {"low": 0.5, "high": 5.0},
            "msd.k": {"low": 2.0, "high": 40.0},
            "msd.c": {"low": 0.05, "high": 5.0},
            "msd.x0": {"low": -0.2, "high": 0.2},
            "msd.v0": {"low": -1.0, "high": 1.0},
        }
    spec = {
        "name": f"msd-physics-{case}",
        "multimodel": os.path.relpath(HERE / "multimodel.yaml", folder),
        "experiment": {"stop_time": DURATION, "step": STEP},
        "scenarios": scenarios,
        "parameters": parameters,
        "objectives": {
            "position_rmse": {"signal": "msd.x", "recorded": "x", "metric": "rmse"},
            "position": {"signal": "msd.x", "recorded": "x", "metric": "residuals"},
        },
        "search": {"strategy": "sobol", "max_points": 64},
        "output": "out",
        "cluster": {"n_workers": 2},
    }
    truth = TRUTHS[case]
    header = (
        f"# msd recordings (made by make_physics_runs.py), concealed: {CONCEALED[case]}.\n"
        f"# Truth: m {truth.m}, k {truth.k}, c {truth.c}, k3 {truth.k3}, Fc {truth.fc}, "
        f"x0 {truth.x0}, v0 {truth.v0}; held-back record: test/.\n"
        f"# Position only, rounded to {QUANTUM} m, AR(1) noise (rho {AR_RHO}, sigma {AR_SIGMA} m) "
        f"and white noise (sigma {WHITE_SIGMA} m).\n"
    )
    (folder / "space.yaml").write_text(header + yaml.safe_dump(spec, sort_keys=False))
    return folder / "space.yaml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="*", choices=[*TRUTHS, []], help="default: every case")
    parser.add_argument("--out", type=Path, default=HERE / "physics", help="one folder per case is made here")
    args = parser.parse_args()
    for case in args.cases or list(TRUTHS):
        print(f"wrote {make(case, args.out / case)}: concealed {CONCEALED[case]}")


if __name__ == "__main__":
    main()
