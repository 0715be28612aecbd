"""One blind diagnosis on two versions of the code, in turns: its CPU, and whether it gave the same answer.

For a change meant to save work and change no answer. It checks ``--base`` (a git revision) out into a
temporary worktree and runs the same case of tests/support/blind.py (the test suite's form) with each version
in turns, each in a process of its own with that version first on PYTHONPATH (its local cluster's workers
import the same version; checked). Per run it prints the case's wall time, the CPU seconds of the client (the
diagnosis itself, and the local cluster's scheduler, which runs in its process), of the 2 workers, and a
digest of the diagnosis's JSON (its own folder's paths left out); then the means and their ratios.

    python3 benchmarks/versions.py --base HEAD~1 [--case steering_lag+time_offset] [--rounds 3] [--json]

Each run first diagnoses the case "none" on its cluster, so FMUs are built and workers warm before the case
is measured.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FIGURES = ("wall_s", "client_cpu_s", "workers_cpu_s")


def one_run(tree: Path, case: str, out: Path) -> dict:
    """In the child process: the case diagnosed with the code of ``tree``, its figures and answer."""
    sys.path.insert(0, str(tree / "tests"))
    from fit_schedule import cluster_cpu as workers_cpu  # this process's children: its local cluster
    from support import blind  # the tree's: fit_schedule, next, then finds it imported

    import dse_runner
    from dse_runner.sweeps.cluster import connect
    from dse_runner.sweeps.makers import Cluster

    where = {Path(dse_runner.__file__).resolve()}
    with connect(Cluster(n_workers=2)) as client:
        where |= {Path(w).resolve() for w in client.run(lambda: __import__("dse_runner").__file__).values()}
        if not all(tree.resolve() in w.parents for w in where):
            raise SystemExit(f"dse_runner came from {sorted(map(str, where))}, not {tree}")
        blind.run_case("none", out / "warm-up", client)
        client0, workers0, started = time.process_time(), workers_cpu(), time.perf_counter()
        _, _, result = blind.run_case(case, out / case, client)
        figures = {
            "wall_s": time.perf_counter() - started,
            "client_cpu_s": time.process_time() - client0,
            "workers_cpu_s": workers_cpu() - workers0,
        }
    answer = json.dumps(result.to_json(), sort_keys=True, default=str).replace(str(out), "<out>")
    return {
        **{k: round(v, 2) for k, v in figures.items()},
        "answer": hashlib.sha256(answer.encode()).hexdigest()[:16],
    }


def measured(tree: Path, case: str, folder: Path) -> dict:
    """One run in a fresh process that imports the code of ``tree``."""
    out = folder / "out"
    shutil.rmtree(out, ignore_errors=True)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(tree), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep),
    }
    done = subprocess.run(
        [sys.executable, __file__, "--run", str(tree), "--case", case, "--out", str(out)],
        check=False,
        env=env,
        capture_output=True,
        text=True,
        cwd=folder,
    )
    if done.returncode != 0:
        sys.exit(f"the run with {tree} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", help="the git revision to compare the checkout with")
    parser.add_argument("--case", default="steering_lag+time_offset")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--run", type=Path, help=argparse.SUPPRESS)  # in the child: the tree to run
    parser.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.run:
        print(json.dumps(one_run(args.run, args.case, args.out)))
        return
    if not args.base:
        parser.error("--base is required")
    folder = Path(tempfile.mkdtemp(prefix="versions-"))
    base = folder / "base"
    subprocess.run(
        ["git", "-C", str(REPO), "worktree", "add", "--detach", "-q", str(base), args.base], check=True
    )
    trees = {"base": base, "checkout": REPO}
    runs: dict[str, list[dict]] = {name: [] for name in trees}
    try:
        for k in range(args.rounds):
            for name, tree in trees.items():  # in turns: the machine's drift falls on both alike
                row = measured(tree, args.case, folder)
                runs[name].append(row)
                if not args.json:
                    print(
                        f"round {k + 1} {name:8s}: "
                        + ", ".join(f"{f} {row[f]}" for f in FIGURES)
                        + f", answer {row['answer']}",
                        flush=True,
                    )
    finally:
        subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(base)], check=False)
        shutil.rmtree(folder, ignore_errors=True)
    means = {
        name: {f: round(statistics.mean(r[f] for r in rows), 2) for f in FIGURES}
        for name, rows in runs.items()
    }
    ratios = {f: round(means["checkout"][f] / means["base"][f], 2) for f in FIGURES}
    same = len({r["answer"] for rows in runs.values() for r in rows}) == 1
    if args.json:
        print(
            json.dumps(
                {
                    "base": args.base,
                    "case": args.case,
                    "runs": runs,
                    "means": means,
                    "checkout/base": ratios,
                    "same_answer": same,
                }
            )
        )
        return
    for name, figures in means.items():
        print(f"{name:8s} mean: " + ", ".join(f"{f} {v}" for f, v in figures.items()))
    print("checkout/base: " + ", ".join(f"{f} {v}" for f, v in ratios.items()))
    print("the same diagnosis in every run" if same else "DIFFERENT answers between runs")


if __name__ == "__main__":
    main()
