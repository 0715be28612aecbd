"""Issue 32's two speed targets for sensitivity analysis.

    python benchmarks/sensitivity.py [--points 8192] [--rows 100000] [--json]

1. **The Ishigami study**: ``dse-runner submit jobs/ishigami/space.yaml`` (its FMU built beforehand, so
   the compiler is not timed), the job's own local cluster of 2 workers started by the command, then
   ``dse-runner sensitivity``: each timed as a user's command, wall clock, in a fresh store. Target:
   8192 evaluations in under a minute. The indices' distance from the closed form is printed beside it.
2. **The index computation**: a real store of ``--rows`` result rows (a Saltelli design of the
   Ishigami function over 5 scenarios in 5 groups, written straight to Parquet with the formula's
   values: no simulation, so only the analysis is timed), then ``analysis.sensitivity.sensitivity``:
   read the rows, reduce over scenarios and per group, and SALib's estimators with 100 bootstrap
   resamples, for the whole and each group. Target: 100,000 rows in under 5 s.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's dse_runner

from dse_runner.analysis.sensitivity import sensitivity, stored_design
from dse_runner.simulation.build import build_fmu
from dse_runner.simulation.objectives import Reduce
from dse_runner.sweeps import store
from dse_runner.sweeps.rank import save_sweep_spec
from dse_runner.sweeps.spec import SpaceSpec

REPO = Path(__file__).resolve().parents[1]

ISHIGAMI = REPO / "jobs" / "ishigami"
NAMES = ["ishigami.x1", "ishigami.x2", "ishigami.x3"]
PI = math.pi
B_BY_SCENARIO = (0.0, 0.05, 0.1, 0.15, 0.2)  # one scenario per group, each its own b


def analytic(a: float, b: float) -> dict[str, dict[str, float]]:
    v1, v2, v13 = (1 + b * PI**4 / 5) ** 2 / 2, a**2 / 8, b**2 * PI**8 * (1 / 18 - 1 / 50)
    v = v1 + v2 + v13
    return {
        "ishigami.x1": {"S1": v1 / v, "ST": (v1 + v13) / v},
        "ishigami.x2": {"S1": v2 / v, "ST": v2 / v},
        "ishigami.x3": {"S1": 0.0, "ST": v13 / v},
    }


def command(*args: str) -> tuple[float, subprocess.CompletedProcess]:
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "dse_runner", *args], check=False, capture_output=True, text=True, cwd=REPO
    )
    if done.returncode != 0:
        raise SystemExit(f"dse-runner {' '.join(args)} failed:\n{done.stderr}")
    return time.perf_counter() - started, done


def ishigami_study(folder: Path, points: int) -> dict:
    build_fmu(ISHIGAMI / "fmus" / "ishigami")  # the compiler is not what is timed
    spec = yaml.safe_load((ISHIGAMI / "space.yaml").read_text())
    spec["multimodel"] = {"fmus": {"ishigami": str(ISHIGAMI / "fmus" / "ishigami")}}
    spec["search"]["max_points"] = points
    spec.update(output=str(folder / "out"), cluster={"n_workers": 2})
    folder.mkdir(parents=True)
    path = folder / "space.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    submit_seconds, done = command("submit", str(path), "--no-dashboard", "--json")
    report = json.loads(done.stdout)
    analyse_seconds, done = command("sensitivity", str(folder / "out"), "--json")
    found = json.loads(done.stdout)["objectives"]["y"]["parameters"]
    truth = analytic(7.0, 0.1)
    error = max(abs(found[p][k] - truth[p][k]) for p in truth for k in ("S1", "ST"))
    return {
        "evaluations": report["ok"],
        "failed": report["failed"],
        "workers": report["workers"],
        "submit_seconds": round(submit_seconds, 2),
        "sweep_seconds": report["seconds"],
        "sensitivity_seconds": round(analyse_seconds, 2),
        "total_seconds": round(submit_seconds + analyse_seconds, 2),
        "largest_error": round(error, 4),
        "indices": {p: {k: round(found[p][k], 4) for k in ("S1", "S1_conf", "ST", "ST_conf")} for p in found},
    }


def write_design_store(folder: Path, rows: int) -> SpaceSpec:
    """A sobol_indices sweep of the Ishigami function whose rows are the formula's values at the design."""
    points = rows // len(B_BY_SCENARIO)
    interval = {"low": -PI, "high": PI}
    objectives = {"y": Reduce(signal="ishigami.y", reduce="final")}
    spec = SpaceSpec(
        name="ishigami",
        multimodel="unused.yaml",
        parameters={n: interval for n in NAMES},
        objectives=objectives,
        search={"strategy": "sobol_indices", "max_points": points, "seed": 0},
    )
    save_sweep_spec(folder, spec, "model")
    design, dimensions = stored_design(spec)
    x = np.array([[p[n] for n in NAMES] for p in design.points(dimensions)])
    schema = store.results_schema({n: [0.0] for n in NAMES}, objectives)
    for k, b in enumerate(B_BY_SCENARIO):
        y = np.sin(x[:, 0]) + 7.0 * np.sin(x[:, 1]) ** 2 + b * x[:, 2] ** 4 * np.sin(x[:, 0])
        records = [
            {
                "task_id": f"t{k}-{i}",
                "model": "model",
                "scenario": f"s{k}",
                "group": f"g{k}",
                **dict(zip(NAMES, map(float, x[i]))),
                "y": float(y[i]),
                "status": "ok",
                "error": None,
                "wall_time": 0.0,
                "worker": "w",
            }
            for i in range(len(x))
        ]
        store.write_rows(folder, "ishigami", f"s{k}", records, schema)
    return spec


def index_computation(folder: Path, rows: int, repeats: int = 3) -> dict:
    folder.mkdir(parents=True)
    write_design_store(folder, rows)
    stored = len(store.read_results(folder, "ishigami", ["y"]))
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        found = sensitivity(folder)
        times.append(time.perf_counter() - started)
    return {
        "rows": stored,
        "groups": len(found.objectives["y"].groups),
        "seconds": [round(t, 3) for t in times],
        "median_seconds": round(sorted(times)[len(times) // 2], 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=8192, help="the Ishigami study's budget of evaluations")
    parser.add_argument("--rows", type=int, default=100_000, help="result rows the index computation reads")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="dse-sensitivity-") as tmp:
        study = ishigami_study(Path(tmp) / "study", args.points)
        indices = index_computation(Path(tmp) / "rows", args.rows)
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else None
    result = {
        "ishigami": study,
        "index_computation": indices,
        "load_average": load,
        "targets": {
            "ishigami_under_60_s": study["total_seconds"] < 60,
            "indices_under_5_s": indices["median_seconds"] < 5,
        },
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(
        f"Ishigami, {study['evaluations']} evaluations on {study['workers']} workers: submit "
        f"{study['submit_seconds']} s (sweep {study['sweep_seconds']} s) + sensitivity "
        f"{study['sensitivity_seconds']} s = {study['total_seconds']} s; largest |index - analytic| "
        f"{study['largest_error']}"
    )
    print(
        f"index computation on {indices['rows']} rows ({indices['groups']} groups + the whole): "
        f"{indices['median_seconds']} s median of {indices['seconds']}"
    )
    print(f"load average at the end: {load}")


if __name__ == "__main__":
    main()
