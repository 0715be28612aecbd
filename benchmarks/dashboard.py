"""What watching a sweep costs: the Robotti calibration with and without a dashboard page open.

    python benchmarks/dashboard.py [--repeats 2] [--json]

Runs jobs/robotti/space.yaml (1500 tasks) on the embedded local cluster into fresh folders,
alternating: no dashboard, then the dashboard served in this process with a Chromium page
open on it (refreshing every second, as a user would watch it). Prints the wall times side by
side and their ratio, then the cost of one dashboard refresh (reading the store) and of
writing the report, on the finished results.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

from dse_runner.interfaces.dashboard.feed import Feed
from dse_runner.interfaces.dashboard.server import serve
from dse_runner.interfaces.report import build_report
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit

REPO = Path(__file__).resolve().parents[1]


def sweep_seconds(folder: Path, watched: bool, browser) -> float:
    shutil.rmtree(folder, ignore_errors=True)
    space = load_space(REPO / "jobs" / "robotti" / "space.yaml").with_overrides(output=folder)
    server = page = None
    if watched:
        server = serve(space.output, space.name, "127.0.0.1:0", space)
        page = browser.new_page()
        page.goto(server.url)
        page.wait_for_selector("#dse-first", state="detached")  # BokehJS has drawn the document
        page.wait_for_selector("#dse-done")
    started = time.perf_counter()
    report = submit(space)
    seconds = time.perf_counter() - started
    if watched:
        page.close()
        server.stop()
    assert report.ok == report.total, report.errors
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="bench-dashboard-"))
    plain, watched = [], []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=shutil.which("chromium"))
        for i in range(args.repeats):
            plain.append(sweep_seconds(root / f"plain{i}", False, browser))
            watched.append(sweep_seconds(root / f"watched{i}", True, browser))
        browser.close()
    output = root / f"watched{args.repeats - 1}"
    feed = Feed(output, "robotti-calibration")
    reads = []
    for _ in range(10):
        started = time.perf_counter()
        feed._read()
        reads.append(time.perf_counter() - started)
    started = time.perf_counter()
    size = len(build_report(output).encode())
    report_seconds = time.perf_counter() - started
    figures = {
        "sweep_without_dashboard_s": statistics.median(plain),
        "sweep_with_dashboard_page_open_s": statistics.median(watched),
        "ratio": statistics.median(watched) / statistics.median(plain),
        "refresh_read_ms": 1e3 * statistics.median(reads),
        "report_s": report_seconds,
        "report_mb": size / 1e6,
        "runs": {"plain": plain, "watched": watched},
    }
    shutil.rmtree(root, ignore_errors=True)
    if args.json:
        print(json.dumps(figures, indent=2))
        return
    print(
        f"sweep of 1500 tasks, median of {args.repeats}: {figures['sweep_without_dashboard_s']:.1f} "
        f"s without a dashboard, {figures['sweep_with_dashboard_page_open_s']:.1f} s with one open "
        f"(ratio {figures['ratio']:.3f})"
    )
    print(f"one dashboard refresh reads the store in {figures['refresh_read_ms']:.1f} ms (1500 rows)")
    print(f"the report: {report_seconds:.1f} s to build, {figures['report_mb']:.2f} MB")


if __name__ == "__main__":
    main()
