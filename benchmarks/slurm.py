"""Slurm against the local cluster on one machine, and what a worker job's start costs.

    python3 benchmarks/slurm.py [--repeats 3] [--json]      # as root, with Debian's Slurm and munge

A single-node Slurm (tests/support/slurm.py, the tests' own) is brought up here. Then:

1. The same sweep (jobs/robotti/space.yaml restricted to vehicle.mu in {0.3, 0.5}: 600 tasks) with
   `dse-runner submit --json`, 2 workers, into a fresh folder each time: once on the embedded local
   cluster (`--cluster local`) and once as 2 Slurm jobs of 1 core (`--cluster slurm`). Reported: the
   command's wall time (start-up, cluster, sweep, ranking) and the sweep's own seconds, median of
   --repeats.
2. A worker job's start: `connect` to a 1-job Slurm cluster, timed from the scale request to the
   job's worker joining the scheduler (sbatch, Slurm's scheduling, the job's Python and
   `distributed` import, the connection), median of --repeats.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]


def sweep(folder: Path, kind: str) -> tuple[float, float]:
    """(command wall seconds, the sweep's own seconds) for the 600-task sweep on ``kind``."""
    import yaml

    spec = yaml.safe_load((ROOT / "jobs" / "robotti" / "space.yaml").read_text())
    spec["parameters"]["vehicle.mu"] = {"start": 0.3, "stop": 0.5, "step": 0.2}
    spec["multimodel"] = "bundled:robotti/multimodel.yaml"
    spec["scenarios"] = [str(ROOT / "scenarios" / "robotti" / "*")]
    spec["output"] = str(folder / "out")
    spec["cluster"] = {"kind": kind, "n_workers": 2, "slurm": {"log_directory": str(folder / "logs")}}
    path = folder / "space.yaml"
    path.write_text(yaml.safe_dump(spec))
    started = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-m", "dse_runner", "submit", str(path), "--json", "--no-dashboard"],
        check=False,
        capture_output=True,
        text=True,
        cwd=folder,
    )
    wall = time.perf_counter() - started
    if result.returncode:
        raise SystemExit(result.stderr)
    report = json.loads(result.stdout)
    assert report["ok"] == 600, report
    return wall, report["seconds"]


def job_start(folder: Path) -> float:
    """Seconds from asking for one worker job to its worker joining the scheduler."""
    from dse_runner.sweeps.jobqueue import Slurm
    from dse_runner.sweeps.makers import Cluster

    spec = Cluster.model_validate({"kind": "slurm", "slurm": {"log_directory": str(folder / "logs")}})
    maker = Slurm()
    cluster = maker.started(spec, None)
    try:
        from distributed import Client

        with Client(cluster) as client:
            started = time.perf_counter()
            maker.scale(cluster, 1)
            client.wait_for_workers(1, timeout=120)
            return time.perf_counter() - started
    finally:
        maker.close(cluster)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    from support.slurm import SingleNodeSlurm, why_not

    if why_not():
        raise SystemExit(why_not())
    with tempfile.TemporaryDirectory() as tmp:
        up = time.perf_counter()
        slurm = SingleNodeSlurm(Path(tmp) / "slurm")
        figures: dict[str, object] = {"slurm_up_s": round(time.perf_counter() - up, 2)}
        os.environ["SLURM_CONF"] = str(slurm.conf)
        try:
            for kind in ("local", "slurm"):
                runs = []
                for i in range(args.repeats):
                    folder = Path(tmp) / f"{kind}-{i}"
                    folder.mkdir()
                    runs.append(sweep(folder, kind))
                    slurm.wait_for_no_jobs(60)
                figures[f"{kind}_command_s"] = [round(w, 2) for w, _ in runs]
                figures[f"{kind}_sweep_s"] = [round(s, 2) for _, s in runs]
                figures[f"{kind}_command_median_s"] = round(statistics.median(w for w, _ in runs), 2)
                figures[f"{kind}_sweep_median_s"] = round(statistics.median(s for _, s in runs), 2)
            starts = []
            for i in range(args.repeats):
                starts.append(job_start(Path(tmp) / f"start-{i}"))
                slurm.wait_for_no_jobs(60)
            figures["job_start_s"] = [round(s, 2) for s in starts]
            figures["job_start_median_s"] = round(statistics.median(starts), 2)
        finally:
            down = time.perf_counter()
            slurm.close()
            figures["slurm_down_s"] = round(time.perf_counter() - down, 2)
    if args.json:
        print(json.dumps(figures))
        return
    for key, value in figures.items():
        print(f"{key}: {value}")


if __name__ == "__main__":
    main()
