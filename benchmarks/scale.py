"""How the commands scale with a study's rows: submit, rank, report and sensitivity at 10^4, 10^5 and
10^6 rows, each as a user runs it (the installed ``dse-runner`` in a subprocess), side by side in one run.

    python benchmarks/scale.py [--rows 10000,100000,1000000] [--json]

The study is jobs/ishigami/space.yaml's (the Ishigami function as a C FMU, Sobol' indices by Saltelli's
design: one row per point), with ``max_points`` set to the rows asked for, into a fresh folder each; submit
runs on the embedded local cluster of 2 workers without a dashboard. For each command: wall seconds, and the
peak resident memory of the command's own process (the client: sampled every 50 ms with psutil; submit's
workers are other processes and not counted). For the report, its size. The ratios to the smallest study
show what grows with the rows; issue 52's targets at 10^6 rows are a client peak of 1 GB, rank 10 s,
report 20 s and 8 MB.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import psutil
import yaml

REPO = Path(__file__).resolve().parents[1]
ISHIGAMI = REPO / "jobs" / "ishigami"
SAMPLE_SECONDS = 0.05


def space(folder: Path, rows: int) -> Path:
    """The Ishigami Sobol' study of ``rows`` points in ``folder``."""
    spec = yaml.safe_load((ISHIGAMI / "space.yaml").read_text())
    spec.update(multimodel={"fmus": {"ishigami": str(ISHIGAMI / "fmus" / "ishigami")}},
                output=str(folder / "out"), cluster={"n_workers": 2},
                search={**spec.get("search", {}), "strategy": "sobol_indices", "max_points": rows})
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "space.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def measured(*args: str) -> dict:
    """One command: its wall seconds and its own process's peak resident memory [MB]."""
    command = [str(Path(sys.executable).with_name("dse-runner")), *args]
    started = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    peak = [0]

    def sample() -> None:
        watched = psutil.Process(process.pid)
        while process.poll() is None:
            try:
                peak[0] = max(peak[0], watched.memory_info().rss)
            except psutil.Error:
                return
            time.sleep(SAMPLE_SECONDS)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    _, stderr = process.communicate()
    seconds = time.perf_counter() - started
    sampler.join()
    if process.returncode != 0:
        raise SystemExit(f"{' '.join(args)}: exit {process.returncode}: {stderr.strip()[-500:]}")
    return {"seconds": round(seconds, 2), "peak_mb": round(peak[0] / 2**20)}


def study(rows: int, work: Path) -> dict:
    folder = work / f"rows-{rows}"
    path = space(folder, rows)
    out = folder / "out"
    found = {"rows": rows, "submit": measured("submit", str(path), "--no-dashboard")}
    found["rank"] = measured("rank", str(out))
    found["report"] = measured("report", str(out), "-o", str(folder / "report.html"))
    found["report"]["mb"] = round((folder / "report.html").stat().st_size / 2**20, 1)
    found["sensitivity"] = measured("sensitivity", str(out))
    shutil.rmtree(folder, ignore_errors=True)
    return found


def table(found: list[dict]) -> None:
    first = found[0]
    print(f"{'rows':>9} | {'submit':>16} | {'rank':>15} | {'report':>22} | {'sensitivity':>15}")
    for f in found:
        cells = [f"{f[c]['seconds']:6.1f} s {f[c]['peak_mb']:5d} MB" for c in ("submit", "rank")]
        report = f["report"]
        cells.append(f"{report['seconds']:6.1f} s {report['peak_mb']:5d} MB {report['mb']:5.1f} MB")
        cells.append(f"{f['sensitivity']['seconds']:6.1f} s {f['sensitivity']['peak_mb']:5d} MB")
        print(f"{f['rows']:>9} | " + " | ".join(cells))
    for f in found[1:]:
        ratios = ", ".join(f"{c} {f[c]['seconds'] / first[c]['seconds']:.1f}x time, "
                           f"{f[c]['peak_mb'] / first[c]['peak_mb']:.1f}x memory"
                           for c in ("submit", "rank", "report", "sensitivity"))
        print(f"{f['rows']} against {first['rows']} rows ({f['rows'] / first['rows']:.0f}x): {ratios}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", default="10000,100000,1000000", help="comma-separated study sizes")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="dse-scale-") as work:
        found = []
        for rows in (int(r) for r in args.rows.split(",")):
            found.append(study(rows, Path(work)))
            print(json.dumps(found[-1]), file=sys.stderr, flush=True)
    if args.json:
        print(json.dumps(found, indent=2))
    else:
        table(found)


if __name__ == "__main__":
    main()
