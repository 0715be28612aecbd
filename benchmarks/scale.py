"""How the commands scale with a study's rows: submit, rank, report, sensitivity and the dashboard at 10^4,
10^5 and 10^6 rows, each as a user runs it (the installed ``dse-runner`` in a subprocess), side by side in
one run.

    python benchmarks/scale.py [--rows 10000,100000,1000000] [--json]

The study is jobs/ishigami/space.yaml's (the Ishigami function as a C FMU, Sobol' indices by Saltelli's
design: one row per point), with ``max_points`` set to the rows asked for, into a fresh folder each; submit
runs on the embedded local cluster of 2 workers without a dashboard. For each command: wall seconds, and the
peak resident memory of the command's own process (the client: sampled every 50 ms with psutil; submit's
workers are other processes and not counted); for submit, also that peak up to its summary line, which it
prints when the sweep has ended and before it ranks (the sweep part: what issue 52 wants flat in the rows).
For the report, its size.

The dashboard: once submit has finished, ``dse-runner dashboard OUT --address 127.0.0.1:PORT`` is started
while a headless Chromium (Debian's, launched as tests/support/pages.py launches it, before the command)
waits; from the command's start (wall clock) to the page showing its first number (the progress line's
"done" count, #dse-done, which the page's HTML carries before BokehJS draws the document; looked for from
the answer's first bytes on), and to all figures drawn: every visible Bokeh plot with a non-empty data
source as BokehJS's documents hold them, every Bokeh view finished rendering, and the sensitivity
section's images loaded (or its note saying why there are none). The page is polled every 100 ms for at
most 600 s; a figure not reached by then is reported as a timeout (null in --json). Its peak resident
memory is the dashboard process's.

The ratios to the smallest study show what grows with the rows; issue 52's targets at 10^6 rows are a client
peak of 1 GB, rank 10 s, report 20 s and 8 MB, and the dashboard's first number within 5 s and all its
figures within 20 s.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import socket
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
POLL_SECONDS = 0.1  # how often the dashboard's page is looked at
SWEPT = " simulations ("  # in submit's summary line: the sweep has ended, its ranking begins
DASHBOARD_TIMEOUT = 600.0  # seconds from the dashboard command's start after which a figure is a timeout


def space(folder: Path, rows: int) -> Path:
    """The Ishigami Sobol' study of ``rows`` points in ``folder``."""
    spec = yaml.safe_load((ISHIGAMI / "space.yaml").read_text())
    spec.update(
        multimodel={"fmus": {"ishigami": str(ISHIGAMI / "fmus" / "ishigami")}},
        output=str(folder / "out"),
        cluster={"n_workers": 2},
        search={**spec.get("search", {}), "strategy": "sobol_indices", "max_points": rows},
    )
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "space.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def dse_runner(*args: str) -> list[str]:
    return [str(Path(sys.executable).with_name("dse-runner")), *args]


def sampled(process: subprocess.Popen) -> tuple[threading.Thread, list[int]]:
    """A thread sampling ``process``'s resident memory until it exits, and its peak [bytes] so far."""
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
    return sampler, peak


def measured(*args: str, phase: str | None = None) -> dict:
    """One command: its wall seconds and its own process's peak resident memory [MB]; with ``phase``, also
    the peak until the first line of its output containing it (submit's summary line, printed when the sweep
    has ended and before its ranking begins)."""
    started = time.perf_counter()
    process = subprocess.Popen(dse_runner(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    sampler, peak = sampled(process)
    phase_peak = None
    errors: list[str] = []
    drain = threading.Thread(target=lambda: errors.append(process.stderr.read()), daemon=True)
    drain.start()
    for line in process.stdout:
        if phase is not None and phase_peak is None and phase in line:
            phase_peak = peak[0]
    process.wait()
    seconds = time.perf_counter() - started
    sampler.join()
    drain.join()
    if process.returncode != 0:
        raise SystemExit(f"{' '.join(args)}: exit {process.returncode}: {''.join(errors).strip()[-500:]}")
    found = {"seconds": round(seconds, 2), "peak_mb": round(peak[0] / 2**20)}
    if phase is not None:
        found["phase_peak_mb"] = None if phase_peak is None else round(phase_peak / 2**20)
    return found


# What the page holds, read through BokehJS (the charts live in shadow roots): every visible plot's data
# sources' rows (a chart keeps empty glyphs for what another design would draw: one non-empty source counts),
# and whether every view has finished rendering. null before BokehJS has a document.
PLOTS = """() => {
  if (!window.Bokeh || !Bokeh.documents || Bokeh.documents.length === 0) return null;
  const plots = [];
  for (const doc of Bokeh.documents) {
    for (const model of doc.all_models) {
      if (!('renderers' in model.properties) || !('x_range' in model.properties) || !model.visible) continue;
      const rows = model.renderers.filter(r => r.data_source).map(r => r.data_source.get_length() || 0);
      const title = model.title && model.title.text;
      plots.push({name: title || model.name || model.type, rows: rows.reduce((a, b) => Math.max(a, b), 0)});
    }
  }
  const roots = (Bokeh.index && Bokeh.index.roots) || [];
  return {plots: plots, rendered: roots.length > 0 && roots.every(v => v.has_finished())};
}"""
IMAGES = "els => els.map(e => e.complete && e.naturalWidth > 0)"


def chromium(playwright):
    """Debian's Chromium, found and launched as tests/support/pages.py does."""
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if not path:
        raise SystemExit(
            "no chromium on PATH: install Debian's (apt-get install chromium), as .ci/install does"
        )
    return playwright.chromium.launch(executable_path=path)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def figures_drawn(page) -> tuple[bool, str]:
    """Whether every figure on the page is drawn; if not, what is still missing, in words."""
    found = page.evaluate(PLOTS)
    if found is None:
        return False, "no Bokeh document yet"
    missing = [p["name"] for p in found["plots"] if p["rows"] == 0]
    if not found["plots"] or missing:
        return False, f"plots without data: {missing or 'no plots'}"
    if not found["rendered"]:
        return False, "Bokeh views still rendering"
    if page.locator("#sensitivity-note").count():  # no figures, and says why: the section is what it will be
        return True, ""
    images = page.locator("#sensitivity-figures img").evaluate_all(IMAGES)
    if not images or not all(images):
        return False, f"sensitivity images loaded: {sum(images)} of {len(images)}"
    return True, ""


def dashboard(out: Path, log: Path) -> dict:
    """``dse-runner dashboard out`` as a user starts it, watched by Chromium: seconds from the command's start
    to the page's first number and to all its figures drawn (None: not within DASHBOARD_TIMEOUT), and the
    process's peak resident memory [MB]."""
    from playwright.sync_api import Error as PlaywrightError
    from playwright.sync_api import TimeoutError as PlaywrightTimeout
    from playwright.sync_api import sync_playwright

    address = f"127.0.0.1:{free_port()}"
    url = f"http://{address}/"
    found: dict = {"first_number_s": None, "all_figures_s": None, "peak_mb": 0}
    waiting, failed = "the command to serve", ""
    with sync_playwright() as playwright, log.open("w") as errors:
        browser = chromium(playwright)  # started before the command: a user's browser is already open
        page = browser.new_context(viewport={"width": 1400, "height": 1000}).new_page()
        started = time.perf_counter()
        process = subprocess.Popen(
            dse_runner("dashboard", str(out), "--address", address),
            stdout=subprocess.PIPE,
            stderr=errors,
            text=True,
        )
        sampler, peak = sampled(process)
        serving = threading.Event()

        def read() -> None:  # the URL line says the server listens; the rest is drained
            for line in process.stdout:
                if url in line:
                    serving.set()

        threading.Thread(target=read, daemon=True).start()
        deadline = started + DASHBOARD_TIMEOUT
        try:
            while process.poll() is None and time.perf_counter() < deadline:
                if serving.wait(POLL_SECONDS):
                    break
            if serving.is_set():
                waiting = "the page"
                # the server answers once it has built the page's document; the page is looked at from its
                # first bytes on (its HTML carries the counts, shown as it is parsed, before BokehJS's load)
                answer = page.goto(
                    url, timeout=max(1.0, deadline - time.perf_counter()) * 1000, wait_until="commit"
                )
                waiting = "the first number"
                if answer is not None and not answer.ok:  # the page failed to build (the log says why)
                    failed = f"the page answered HTTP {answer.status}"
                while not failed and process.poll() is None and time.perf_counter() < deadline:
                    now = round(time.perf_counter() - started, 2)
                    if found["first_number_s"] is None:
                        done = page.locator("#dse-done").all_inner_texts()
                        if done and re.match(r"\d+", done[0]):
                            found["first_number_s"] = now
                    if found["first_number_s"] is not None:
                        drawn, waiting = figures_drawn(page)
                        if drawn:
                            found["all_figures_s"] = now
                            break
                    time.sleep(POLL_SECONDS)
        except PlaywrightTimeout:
            pass  # goto's: reported as a timeout below
        except PlaywrightError as e:
            failed = f"Chromium, waiting for {waiting}: {str(e).splitlines()[0]}"
        finally:
            browser.close()
            exited = process.poll()  # on its own, before being stopped here
            if exited is None:
                process.terminate()
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
            sampler.join()
    found["peak_mb"] = round(peak[0] / 2**20)
    if found["all_figures_s"] is not None:
        return found
    if exited is not None:
        found["error"] = f"dashboard exit {exited}"
    elif failed:
        found["error"] = failed
    else:
        found["timeout_waiting_for"] = waiting
    found["log"] = log.read_text().strip()[-500:]  # the command's stderr: a traceback, Bokeh's errors
    return found


def study(rows: int, work: Path) -> dict:
    folder = work / f"rows-{rows}"
    path = space(folder, rows)
    out = folder / "out"
    found = {"rows": rows, "submit": measured("submit", str(path), "--no-dashboard", phase=SWEPT)}
    found["dashboard"] = dashboard(out, folder / "dashboard.log")
    found["rank"] = measured("rank", str(out))
    found["report"] = measured("report", str(out), "-o", str(folder / "report.html"))
    found["report"]["mb"] = round((folder / "report.html").stat().st_size / 2**20, 1)
    found["sensitivity"] = measured("sensitivity", str(out))
    # once more, on the same store: the Sobol' indices are kept in it now (computed above by whichever of the
    # dashboard, report and sensitivity ran first), as they are for anyone who opens a finished study again
    found["dashboard_again"] = dashboard(out, folder / "dashboard-again.log")
    shutil.rmtree(folder, ignore_errors=True)
    return found


def seconds(value: float | None) -> str:
    return "timeout" if value is None else f"{value:.1f} s"


def megabytes(value: int | None) -> str:
    return "–" if value is None else f"{value:5d} MB"


def ratio(value: float | None, first: float | None) -> str:
    return "–" if value is None or not first else f"{value / first:.1f}x"


def table(found: list[dict]) -> None:
    first = found[0]
    print(
        f"{'rows':>9} | {'submit (its sweep part)':>26} | {'rank':>15} | {'report':>22} | "
        f"{'sensitivity':>15} | {'dashboard: first number, all figures':>37} | {'again, indices kept':>29}"
    )
    for f in found:
        cells = [f"{f[c]['seconds']:6.1f} s {f[c]['peak_mb']:5d} MB" for c in ("submit", "rank")]
        cells[0] += f" ({megabytes(f['submit']['phase_peak_mb'])})"
        report = f["report"]
        cells.append(f"{report['seconds']:6.1f} s {report['peak_mb']:5d} MB {report['mb']:5.1f} MB")
        cells.append(f"{f['sensitivity']['seconds']:6.1f} s {f['sensitivity']['peak_mb']:5d} MB")
        for key in ("dashboard", "dashboard_again"):
            shown = f[key]
            cells.append(
                f"{seconds(shown['first_number_s']):>9} {seconds(shown['all_figures_s']):>9} "
                f"{shown['peak_mb']:5d} MB"
            )
        print(f"{f['rows']:>9} | " + " | ".join(cells))
        for key in ("dashboard", "dashboard_again"):
            shown = f[key]
            if "error" in shown:
                print(f"{'':>9}   {key}: {shown['error']}")
            elif "timeout_waiting_for" in shown:
                print(
                    f"{'':>9}   {key}: timed out after {DASHBOARD_TIMEOUT:g} s waiting for "
                    f"{shown['timeout_waiting_for']}"
                )
            if shown.get("log"):
                print(f"{'':>9}   {key}'s stderr ends: {shown['log'].splitlines()[-1]}")
    for f in found[1:]:
        ratios = [
            f"{c} {f[c]['seconds'] / first[c]['seconds']:.1f}x time, "
            f"{f[c]['peak_mb'] / first[c]['peak_mb']:.1f}x memory"
            for c in ("submit", "rank", "report", "sensitivity")
        ]
        ratios.append(
            f"submit's sweep part {ratio(f['submit']['phase_peak_mb'], first['submit']['phase_peak_mb'])} "
            "memory"
        )
        shown, before = f["dashboard"], first["dashboard"]
        ratios.append(
            f"dashboard {ratio(shown['first_number_s'], before['first_number_s'])} to the first "
            f"number, {ratio(shown['all_figures_s'], before['all_figures_s'])} to all figures, "
            f"{ratio(shown['peak_mb'], before['peak_mb'])} memory"
        )
        print(
            f"{f['rows']} against {first['rows']} rows ({f['rows'] / first['rows']:.0f}x): "
            f"{', '.join(ratios)}"
        )


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
