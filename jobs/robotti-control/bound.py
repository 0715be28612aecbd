"""How far below the default gains' path error ANY steering can go at no more steering effort: a bound
on the tuning target ("half the error at no more effort"), per path, for every controller.

    python bound.py [--budget 1.0] [--rounds 2]    # writes bound.json beside this file

For each path on the nominal diagnosed plant (multimodel.yaml, no plant variants):

1. Run the default gains; keep their speed command, their steering effort E and their mean path error.
2. Find the steering sequence (one angle per communication step, as the controller sends it; the
   wheels start straight) with the least mean path error such that sum |delta_k+1 - delta_k| <= budget x E,
   |delta| <= max_steer and |delta_k+1 - delta_k| <= max_steer_rate x step (the path controller's
   default limits, those of the vehicle), knowing the whole path in advance. Nothing a controller can
   do (causal or not, any structure, any gains) at the same speed does better on this model. It is a
   linear program on the plant's lateral dynamics (the dynamic bicycle of bicycle.h, linearised
   along the defaults' speed, in the path's frame); across a lateral step, where the distance to the
   path is the least of the distances to the old line, the new one and the jump between them, a
   mixed-integer one, stopped after 60 s: there the value is the best sequence found, which the replay
   shows a plant reaching, not a proven least.
3. Replay that sequence open loop through the real plant FMU (bundled replay_controller, the
   defaults' speed command) and score it with the path objectives. Then take the linear model's
   one-step residuals along the replayed run as a known disturbance and solve again, `rounds` times,
   so that the bound is the real plant's near the optimum, not only the linear model's.

Investigation tool of the control study (results.md, "What any controller could reach"); compare.py
quotes bound.json when it is there.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import yaml
from scipy.linalg import expm
from scipy.optimize import Bounds, LinearConstraint, linprog, milp

from dse_runner import simulate
from dse_runner.cases import paths as P
from dse_runner.simulation.build import real_parameters
from dse_runner.simulation.scenario import load_scenario

HERE = Path(__file__).resolve().parent
FMUS = HERE.parents[1] / "fmus"
PATHS = HERE.parents[1] / "scenarios" / "robotti-paths"
MODEL = HERE / "multimodel.yaml"
ERROR, EFFORT = "path_error_mean", "steering_effort"


class Plant:
    """The lateral dynamics of bicycle.h, linearised about straight driving at speed v, in the path's
    frame: states vy, r (body), psi (heading less the path's), e (offset, + left); input the
    counter-clockwise steering angle; disturbance the path's curvature."""

    def __init__(self, parameters: dict[str, float]):
        p = real_parameters(FMUS / "robotti_vehicle_effects") | parameters
        self.m, self.caf, self.car = p["mass"], p["cAlphaF"], p["cAlphaR"]
        self.lf, self.lr, self.v_min = p["lf"], p["lr"], p["v_min"]
        self.iz = self.m * p["r_gyr"] ** 2

    def step(self, v: float, curvature: float, h: float):
        """x+ = A x + B u + c over a step h with u held (exact for the linear model at speed v)."""
        fade, vs = min(1.0, max(v, 0.0) / self.v_min), max(v, self.v_min)
        m, iz, lf, lr, caf, car = self.m, self.iz, self.lf, self.lr, self.caf, self.car
        z = np.zeros((6, 6))
        z[0, :2] = [-fade * (caf + car) / (m * vs), -fade * (caf * lf - car * lr) / (m * vs) - v]
        z[1, :2] = [
            -fade * (lf * caf - lr * car) / (iz * vs),
            -fade * (lf * lf * caf + lr * lr * car) / (iz * vs),
        ]
        z[2, 1] = 1.0
        z[3, 0], z[3, 2] = 1.0, v
        z[:4, 4] = [fade * caf / m, lf * fade * caf / iz, 0.0, 0.0]
        z[2, 5] = -v * curvature
        e = expm(z * h)
        return e[:4, :4], e[:4, 4], e[:4, 5]


class Frame:
    """Where the path error is measured from, in the model's coordinates: the path itself (its curvature
    drives psi), or for a lateral step the row before it (e from the old line, the step a jump of the
    reference)."""

    def __init__(self, scenario):
        self.path, self.step = P.path_of(scenario), P.step_of(scenario)
        self.heading = np.unwrap(self.path.heading)
        self.middle = 0.5 * (self.path.arc[1:] + self.path.arc[:-1])
        if self.step is not None:  # the jump's extent along the row: to the first waypoint on the new line
            rel = self.path.points - self.step.origin
            along = rel @ self.step.direction
            lateral = self.step.direction[0] * rel[:, 1] - self.step.direction[1] * rel[:, 0]
            on_new = (np.abs(lateral - self.step.size) < 1e-6) & (along >= 0)
            self.jump = float(along[on_new].min())

    def curvature(self, arc: np.ndarray) -> np.ndarray:
        """The path's curvature at arc lengths: heading change per metre between segment midpoints (0 along a
        stepped row, whose straight pieces have none)."""
        if self.step is not None or len(self.middle) < 2:
            return np.zeros_like(arc)
        return np.gradient(self.heading, self.middle)[
            np.clip(np.searchsorted(self.middle, arc), 0, len(self.middle) - 1)
        ]

    def states(self, trajectory) -> np.ndarray:
        """The model's states along a simulated run, and each sample's arc length."""
        xy = np.column_stack([trajectory.column("vehicle.x"), trajectory.column("vehicle.y")])
        theta = trajectory.column("vehicle.theta")
        if self.step is not None:
            u = self.step.direction
            e = self.step.lateral(xy) + self.step.size
            psi = theta - np.arctan2(u[1], u[0])
        else:
            found = P.project(self.path, xy)
            d = self.path.direction[found.segment]
            rel = xy - self.path.points[found.segment]
            e = d[:, 0] * rel[:, 1] - d[:, 1] * rel[:, 0]
            psi = theta - np.interp(found.arc, self.middle, self.heading)
        psi = np.angle(np.exp(1j * psi))
        return np.column_stack(
            [trajectory.column("vehicle.vy"), trajectory.column("vehicle.yaw_rate"), psi, e]
        )

    def reference(self, trajectory) -> tuple[np.ndarray, np.ndarray]:
        """Per sample: the offset e the path is at (0, or the step's size past it), and a lower bound on the
        distance to the path that holds wherever the vehicle is sideways (inf: none needed): near a step, the
        distance along the row to the jump."""
        n = len(trajectory.time)
        if self.step is None:
            return np.zeros(n), np.full(n, np.inf)
        xy = np.column_stack([trajectory.column("vehicle.x"), trajectory.column("vehicle.y")])
        along = self.step.along(xy)
        reference = np.where(along > self.jump, self.step.size, 0.0)
        cap = np.maximum(0.0, np.maximum(-along, along - self.jump))
        # farther from the jump than twice the step, a vehicle between the lines is nearer one of them
        return reference, np.where(cap < 2.0 * abs(self.step.size), cap, np.inf)


def least_error(models, x0, time, budget, max_steer, max_step, reference, cap):
    """The steering sequence (counter-clockwise) of least time-mean |e - reference| (or the distance bound
    ``cap``, where smaller) at total variation <= budget: (mean error, sequence)."""
    ad, bd, c = models
    n = len(time) - 1
    ix, iu = 0, 4 * (n + 1)
    ip, iq = iu + n, iu + 2 * n - 1
    i_s = iq + n - 1
    choose = np.flatnonzero(np.isfinite(cap))
    ib = i_s + n + 1
    count = ib + len(choose)
    rows, cols, vals, lo, hi = [], [], [], [], []

    def add(entries, low, high):
        r = len(lo)
        for j, v in entries:
            rows.append(r)
            cols.append(j)
            vals.append(v)
        lo.append(low)
        hi.append(high)

    for k in range(n):
        for i in range(4):
            add(
                [
                    (ix + 4 * (k + 1) + i, 1.0),
                    *((ix + 4 * k + j, -ad[k][i, j]) for j in range(4) if ad[k][i, j]),
                    (iu + k, -bd[k][i]),
                ],
                c[k][i],
                c[k][i],
            )
    for k in range(n - 1):
        add([(iu + k + 1, 1.0), (iu + k, -1.0), (ip + k, -1.0), (iq + k, 1.0)], 0.0, 0.0)
    add([(ip + k, 1.0) for k in range(n - 1)] + [(iq + k, 1.0) for k in range(n - 1)], -np.inf, budget)
    big = 5.0
    binary = {k: ib + j for j, k in enumerate(choose)}
    for k in range(n + 1):
        e, s, b = ix + 4 * k + 3, i_s + k, binary.get(k)
        extra = [(b, big)] if b is not None else []
        add([(s, 1.0), (e, -1.0), *extra], -reference[k], np.inf)
        add([(s, 1.0), (e, 1.0), *extra], reference[k], np.inf)
        if b is not None:  # b = 1: the sample is nearer the jump than either line; at least cap from the path
            add([(s, 1.0), (b, -big)], cap[k] - big, np.inf)
    matrix = sp.csr_matrix((vals, (rows, cols)), shape=(len(lo), count))
    low, high = np.full(count, -np.inf), np.full(count, np.inf)
    low[:4] = high[:4] = x0
    low[iu : iu + n], high[iu : iu + n] = -max_steer, max_steer
    low[iu] = high[iu] = 0.0  # the wheels start straight
    low[ip:i_s], high[ip:i_s] = 0.0, max_step
    low[i_s:] = 0.0
    high[ib:] = 1.0
    weights = np.zeros(n + 1)
    weights[:-1] += np.diff(time) / 2
    weights[1:] += np.diff(time) / 2
    cost = np.zeros(count)
    cost[i_s : i_s + n + 1] = weights / (time[-1] - time[0])
    integrality = np.zeros(count)
    integrality[ib:] = 1
    lo, hi = np.array(lo), np.array(hi)
    found = milp(
        cost,
        constraints=LinearConstraint(matrix, lo, hi),
        bounds=Bounds(low, high),
        integrality=integrality,
        options={"time_limit": 60},
    )
    if found.x is None and not len(
        choose
    ):  # HiGHS's simplex can stall on these long, thin LPs: interior point
        eq = lo == hi
        upper, lower = ~eq & np.isfinite(hi), ~eq & np.isfinite(lo)
        found = linprog(
            cost,
            A_ub=sp.vstack([matrix[upper], -matrix[lower]]),
            b_ub=np.concatenate([hi[upper], -lo[lower]]),
            A_eq=matrix[eq],
            b_eq=lo[eq],
            bounds=list(zip(low, high)),
            method="highs-ipm",
        )
    if found.x is None:
        raise RuntimeError(f"the bound's program failed: {found.message}")
    return float(found.fun), found.x[iu : iu + n]


def replay(steering: np.ndarray, defaults, scenario_folder: Path, work: Path):
    """The sequence (counter-clockwise) and the defaults' speed command, open loop on the real plant."""
    trajectory = defaults.trajectory
    delta_f = -np.concatenate([steering, steering[-1:]])
    table = work / "steering_inputs.csv"
    np.savetxt(
        table,
        np.column_stack([trajectory.time, trajectory.column("controller.velocity"), delta_f]),
        delimiter=",",
        header="time,velocity,delta_f",
        comments="",
        fmt="%.10g",
    )
    spec = yaml.safe_load(MODEL.read_text())
    spec["fmus"]["controller"] = "bundled:fmus/replay_controller"
    spec["connections"] = {
        "controller.velocity": ["vehicle.velocity"],
        "controller.delta_f": ["vehicle.delta_f"],
    }
    spec["scenario"] = {k: v for k, v in spec["scenario"].items() if not k.startswith("controller.")}
    spec["parameters"]["controller.file"] = str(table)
    (work / "multimodel.yaml").write_text(yaml.safe_dump(spec))
    return simulate(work / "multimodel.yaml", scenario_folder)


def bound(folder: Path, budget: float, rounds: int, work: Path) -> dict:
    scenario = load_scenario(folder)
    defaults = simulate(MODEL, folder)
    trajectory = defaults.trajectory
    time, speed = trajectory.time, trajectory.column("vehicle.vx")
    h = np.diff(time)
    limits = real_parameters(FMUS / "path_controller")
    plant = Plant(
        {
            k.split(".", 1)[1]: v
            for k, v in yaml.safe_load(MODEL.read_text())["parameters"].items()
            if k.startswith("vehicle.")
        }
    )
    frame = Frame(scenario)
    arc = P.project(
        frame.path, np.column_stack([trajectory.column("vehicle.x"), trajectory.column("vehicle.y")])
    ).arc
    curvature = frame.curvature(0.5 * (arc[1:] + arc[:-1]))
    steps = [plant.step(0.5 * (speed[k] + speed[k + 1]), curvature[k], h[k]) for k in range(len(h))]
    ad, bd, c = (np.array([s[i] for s in steps]) for i in range(3))
    reference, cap = frame.reference(trajectory)
    effort = defaults.objectives[EFFORT]
    steering, run = -trajectory.column("controller.delta_f")[:-1], trajectory
    history = []
    for _ in range(rounds + 1):
        x = frame.states(run)
        residual = x[1:] - np.einsum("kij,kj->ki", ad, x[:-1]) - bd * steering[:, None] - c
        x0 = frame.states(trajectory)[0]
        error, steering = least_error(
            (ad, bd, c + residual),
            x0,
            time,
            budget * effort,
            limits["max_steer"],
            limits["max_steer_rate"] * float(h.max()),
            reference,
            cap,
        )
        replayed = replay(steering, defaults, folder, work)
        run = replayed.trajectory
        history.append(
            {
                "bound": error,
                "replayed_error": replayed.objectives[ERROR],
                "replayed_effort": replayed.objectives[EFFORT],
            }
        )
    best = min(
        history,
        key=lambda r: r["replayed_error"] if r["replayed_effort"] <= effort * budget * 1.001 else np.inf,
    )
    return {
        "defaults_error": defaults.objectives[ERROR],
        "defaults_effort": effort,
        "budget": budget * effort,
        "bound": history[-1]["bound"],
        "replayed_error": best["replayed_error"],
        "replayed_effort": best["replayed_effort"],
        "rounds": history,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget", type=float, default=1.0, help="effort allowed, times the defaults'")
    parser.add_argument(
        "--rounds", type=int, default=2, help="corrections of the linear model by the real plant"
    )
    parser.add_argument("--out", type=Path, default=HERE / "bound.json")
    args = parser.parse_args()
    folders = sorted(p for p in PATHS.iterdir() if (p / P.PATH_FILE).is_file())
    results = {}
    with tempfile.TemporaryDirectory() as work:
        for folder in folders:
            r = results[folder.name] = bound(folder, args.budget, args.rounds, Path(work))
            print(
                f"{folder.name}: defaults {r['defaults_error']:.4f} m at "
                f"{r['defaults_effort']:.3f} rad; least error at <= {r['budget']:.3f} "
                f"rad: {r['bound']:.4f} m (linear model), {r['replayed_error']:.4f} m "
                f"replayed on the plant ({r['replayed_error'] / r['defaults_error']:.2f} "
                f"x the defaults', effort {r['replayed_effort']:.3f})",
                flush=True,
            )
    args.out.write_text(json.dumps({"budget": args.budget, "paths": results}, indent=1) + "\n")


if __name__ == "__main__":
    main()
