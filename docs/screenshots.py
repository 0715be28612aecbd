"""Take the screenshots in docs/images/ from a real sweep of the bundled Robotti job.

    python docs/screenshots.py [--out /tmp/screenshots-sweep]

Runs jobs/robotti/space.yaml on the embedded local cluster into a fresh folder, with the
dashboard served as ``submit`` serves it, photographs the dashboard mid-sweep and at the end
in Debian's Chromium, then writes the report and photographs its top in a 1400 px window and its
figures (from "against each parameter" on) in a 1280 px one.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import threading
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

from dse_runner.interfaces.dashboard.server import serve
from dse_runner.interfaces.dask_link import link_from_dask
from dse_runner.interfaces.report import write_report
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit

REPO = Path(__file__).resolve().parents[1]
IMAGES = REPO / "docs" / "images"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=Path(tempfile.mkdtemp(prefix="screenshots-")))
    out = parser.parse_args().out
    shutil.rmtree(out, ignore_errors=True)
    space = load_space(REPO / "jobs" / "robotti" / "space.yaml").with_overrides(output=out)
    server = serve(space.output, space.name, "127.0.0.1:0", space)
    sweep = threading.Thread(
        target=submit, args=(space,), kwargs={"on_connect": lambda client: link_from_dask(client, server.url)}
    )
    IMAGES.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=shutil.which("chromium"))
        page = browser.new_page(
            viewport={"width": 1400, "height": 1000}
        )  # the width the pages are made to fit
        page.goto(server.url)
        page.wait_for_selector("#dse-first", state="detached")  # BokehJS has drawn the document
        page.wait_for_selector("#dse-done")
        sweep.start()
        while True:  # until a third of the tasks are done
            done, _, total = page.locator("#dse-done").inner_text().partition(" of ")
            if total and int(done) >= int(total) / 3:
                break
            time.sleep(0.2)
        time.sleep(1.5)
        page.screenshot(path=IMAGES / "dashboard-running.png", full_page=True)
        sweep.join()
        time.sleep(2.5)
        page.screenshot(path=IMAGES / "dashboard-finished.png", full_page=True)
        report = write_report(space.output, out / "report.html")
        page.goto(report.as_uri())
        page.wait_for_selector("canvas")
        page.wait_for_timeout(1500)
        page.screenshot(path=IMAGES / "report.png", full_page=False)
        laptop = browser.new_page(viewport={"width": 1280, "height": 1400})  # a laptop's: figures fill it
        laptop.goto(report.as_uri())
        laptop.wait_for_selector("canvas")
        heading = laptop.locator("h2", has_text="against each parameter")
        heading.evaluate("h => h.scrollIntoView()")  # at the top
        laptop.wait_for_timeout(1500)
        laptop.screenshot(path=IMAGES / "report-figures-1280.png", full_page=False)
        browser.close()
    server.stop()
    print(f"screenshots in {IMAGES}; results in {out}")


if __name__ == "__main__":
    main()
