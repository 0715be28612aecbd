"""How long ranking a 100,000-point Pareto front takes, from the Parquet store to the front.

    python benchmarks/pareto.py [--points 100000] [--json]

It writes a real store of ``--points`` parameter points (one scenario each)
with two and with three random objectives, and times ``dse-runner``'s whole
``rank`` (read the rows, totals, Table 1, the front) and the front alone
(``pareto_mask``: pymoo's non-dominated sort). Beside it, the O(n²)
pairwise loop a naive reducer would run, timed on a 2,000-point subsample and
scaled by (n / 2000)², for the ratio. Issue 14's target: a 100,000-point
front ranked in under 5 s.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from dse_runner.simulation.objectives import Reduce
from dse_runner.sweeps import store
from dse_runner.sweeps.rank import pareto_mask, rank, save_sweep_spec
from dse_runner.sweeps.spec import SpaceSpec

SUBSAMPLE = 2_000
CHUNK = 20_000


def pairwise_front(costs: np.ndarray) -> np.ndarray:
    """The naive reducer: every point against every front member, in Python."""
    front: list[int] = []
    for i, c in enumerate(costs):
        if not any(np.all(costs[j] <= c) and np.any(costs[j] < c) for j in front):
            front = [j for j in front if not (np.all(c <= costs[j]) and np.any(c < costs[j]))]
            front.append(i)
    mask = np.zeros(len(costs), dtype=bool)
    mask[front] = True
    return mask


def write_store(folder: Path, values: np.ndarray) -> None:
    """A sweep of len(values) points, objectives f0.. as given, one scenario."""
    objectives = {f"f{k}": Reduce(signal=f"p.y{k}", reduce="final") for k in range(values.shape[1])}
    spec = SpaceSpec(
        name="front",
        multimodel="unused.yaml",
        parameters={"p.a": [0.0], "p.b": [0.0]},
        objectives=objectives,
        ranking={"objective": "f0", "pareto": list(objectives)},
    )
    save_sweep_spec(folder, spec, "model")
    schema = store.results_schema({"p.a": [0.0], "p.b": [0.0]}, objectives)
    rng = np.random.default_rng(1)
    for start in range(0, len(values), CHUNK):
        rows = [
            {
                "task_id": f"t{i}",
                "model": "model",
                "scenario": "s",
                "group": "g",
                "p.a": float(rng.random()),
                "p.b": float(i),
                **dict(zip(objectives, map(float, values[i]))),
                "status": "ok",
                "error": None,
                "wall_time": 0.0,
                "worker": "w",
            }
            for i in range(start, min(start + CHUNK, len(values)))
        ]
        store.write_rows(folder, "front", f"c{start}", rows, schema)


def measure(points: int, objectives: int) -> dict:
    values = np.random.default_rng(objectives).random((points, objectives))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        write_store(folder, values)
        start = time.perf_counter()
        ranking = rank(folder, "front")
        rank_s = time.perf_counter() - start
    start = time.perf_counter()
    mask = pareto_mask(values, ["min"] * objectives)
    front_s = time.perf_counter() - start
    sample = values[:SUBSAMPLE]
    start = time.perf_counter()
    naive = pairwise_front(sample)
    naive_s = (time.perf_counter() - start) * (points / SUBSAMPLE) ** 2
    return {
        "points": points,
        "objectives": objectives,
        "front": int(mask.sum()),
        "front_in_ranking": len(ranking.pareto),
        "rank_s": round(rank_s, 3),
        "pareto_mask_s": round(front_s, 3),
        "pairwise_loop_s_estimated": round(naive_s, 1),
        "same_front_on_subsample": bool(np.array_equal(naive, pareto_mask(sample, ["min"] * objectives))),
        "rank_under_5_s": rank_s < 5.0,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    results = [measure(args.points, k) for k in (2, 3)]
    if args.json:
        print(json.dumps(results, indent=1))
        return
    print(
        f"{'objectives':>10}{'points':>9}{'front':>7}{'rank s':>9}{'front s':>9}{'O(n²) loop s (est.)':>21}"
        f"{'ratio':>8}{'same':>6}"
    )
    for r in results:
        print(
            f"{r['objectives']:>10}{r['points']:>9}{r['front']:>7}{r['rank_s']:>9.2f}{r['pareto_mask_s']:>9.2f}"
            f"{r['pairwise_loop_s_estimated']:>21.0f}{r['pairwise_loop_s_estimated'] / r['rank_s']:>8.0f}"
            f"{r['same_front_on_subsample']!s:>6}"
        )
    print("rank s: the whole reducer from the Parquet store; front s: the non-dominated sort alone;")
    print(f"the loop is timed on {SUBSAMPLE} points and scaled by (n / {SUBSAMPLE})^2")


if __name__ == "__main__":
    main()
