"""The live dashboard and the HTML report, in a real headless Chromium (Debian's) driven by Playwright.

One sweep runs on the real multi-process cluster while a browser watches its dashboard;
the tests below check what that browser saw, then the report and the stand-alone
``dse-runner dashboard`` on the finished results.
"""

from __future__ import annotations

import re
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, SCENARIOS, sleeper_multimodel, strict_loads, write_space
from support.pages import browser_page, glyphs, measure, open_dashboard, watch_errors

SWEEP_SCENARIOS = ["sin1", "speed_ramp1", "speed_step1", "turn_ramp1"]
PARAMETERS = {
    "vehicle.cAlphaF": [20000, 38000],
    "vehicle.mass": {"start": 1000, "stop": 3000, "num": 3},
    "vehicle.mu": [0.3, 0.7],
}
POINTS = 2 * 3 * 2
TASKS = 4 * POINTS


@dataclass
class Watched:
    """What the browser saw while the sweep ran."""

    output: Path
    url: str
    total: int = 0
    done: list[int] = field(default_factory=list)  # each new "done" count, in order
    best: list[str] = field(default_factory=list)  # each new best-so-far line, in order
    top_rows: list[str] = field(default_factory=list)  # each new first row of the ranking table
    final_state: str = ""
    final_done: str = ""
    errors: list[str] = field(default_factory=list)  # console errors and uncaught exceptions
    dask_page_went_to: str = ""
    dask_nav_has_link: bool = False
    track_title: str = ""
    chosen_track: str = ""  # the caption after choosing another scenario
    farewell: str = ""  # what the page said when submit stopped its server, and the state it showed then
    farewell_state: str = ""


def _text(page, element: str) -> str:
    return page.locator(f"#dse-{element}").inner_text()


def _running(page) -> list[str]:
    """The workers table's "running" column (worker, threads, running, CPU %, memory)."""
    return page.locator("#dse-workers tbody tr td:nth-child(3)").all_inner_texts()


@pytest.fixture(scope="module")
def watched(tmp_path_factory, dask_scheduler) -> Watched:
    from distributed import Client

    from dse_runner.interfaces.dashboard.server import farewell, serve
    from dse_runner.interfaces.dask_link import link_from_dask
    from dse_runner.sweeps.spec import load_space
    from dse_runner.sweeps.sweep import submit

    folder = tmp_path_factory.mktemp("dashboard")
    # Chunks of one task (a simulation takes more than 0.02 s): the sweep keeps 2 * 2 + 2 chunks in flight,
    # fewer than the POINTS tasks of each scenario.
    space = load_space(
        write_space(
            folder,
            name="watched",
            scenarios=[str(SCENARIOS / s) for s in SWEEP_SCENARIOS],
            parameters=PARAMETERS,
            chunk_seconds=0.01,
        )
    )
    server = serve(space.output, space.name, "127.0.0.1:0", space)
    seen = Watched(Path(space.output), server.url)
    client = Client(dask_scheduler)
    links: list[str | None] = []
    outcome: dict = {}
    looked = threading.Condition()  # notified each time the browser has been looked at
    gates = [1, 2 * POINTS]  # tasks done at which the sweep waits for the page to catch up

    def pace(report) -> None:
        """The sweep calls this between chunks (those already on the workers run on). At its first chunk,
        and once every point has finished two scenarios, it waits until the page shows what is on disk: the
        browser sees the sweep in its first scenario and again in its second or third (it runs scenario by
        scenario, and while it waits at most six more chunks of one task finish), however slowly a busy
        machine lets the page refresh, and the sweep stays short."""
        if gates and report.ran >= gates[0]:
            gates.pop(0)
            needed = report.ran
            with looked:
                looked.wait_for(lambda: max(seen.done, default=0) >= needed, timeout=120)

    def run() -> None:
        try:
            outcome["report"] = submit(
                space,
                progress=pace,
                client=client,
                on_connect=lambda c: links.append(link_from_dask(c, server.url)),
            )
        except BaseException as e:  # noqa: BLE001  (reported by the test)
            outcome["error"] = e

    with browser_page(seen.errors, viewport={"width": 1300, "height": 1600}) as page:
        open_dashboard(page, server.url)
        sweep = threading.Thread(target=run)
        sweep.start()

        def look() -> None:
            match = re.match(r"(\d+) of (\d+)", _text(page, "done"))
            if match and (not seen.done or int(match[1]) != seen.done[-1]):
                seen.done.append(int(match[1]))
                seen.total = int(match[2])
            for shown, now in (
                (seen.best, _text(page, "best")),
                (seen.top_rows, page.locator("#dse-ranking tbody tr").first.inner_text()),
            ):
                if not shown or now != shown[-1]:
                    shown.append(now)
            with looked:
                looked.notify_all()

        while sweep.is_alive():
            look()
            time.sleep(0.25)
        sweep.join()
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and _text(page, "state") != "finished":
            time.sleep(0.25)
        look()
        seen.final_state, seen.final_done = _text(page, "state"), _text(page, "done")
        seen.track_title = _text(page, "track")
        page.locator("select").select_option("turn_ramp1")
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and not _text(page, "track").startswith("turn_ramp1"):
            time.sleep(0.25)
        seen.chosen_track = _text(page, "track")
        if links and links[0]:
            dask = page.context.browser.new_page()
            watch_errors(dask, seen.errors)
            dask.goto(client.dashboard_link)
            seen.dask_nav_has_link = dask.locator("a[href='dse-runner']").count() == 1
            dask.goto(links[0])
            seen.dask_page_went_to = dask.url
        ended = "The sweep's submit has ended, and its dashboard server with it."
        server.stop(farewell(space.output, ended))  # as submit does
        seen.farewell, seen.farewell_state = _text(page, "farewell"), _text(page, "state")
    client.close()
    if "error" in outcome:
        raise outcome["error"]
    assert outcome["report"].ok == TASKS, outcome["report"].errors
    return seen


def test_progress_advances_while_the_sweep_runs(watched):
    assert watched.total == TASKS
    assert len(watched.done) >= 3, f"the page showed only these counts: {watched.done}"
    assert watched.done == sorted(watched.done)
    assert any(0 < n < TASKS for n in watched.done), watched.done  # seen mid-sweep, not just before and after
    assert watched.final_done == f"{TASKS} of {TASKS}" and watched.final_state == "finished"


def test_the_best_so_far_ranking_updates(watched):
    shown = [b for b in watched.best if b.startswith("best so far")]
    assert len(set(shown)) >= 2, watched.best
    assert "over 4 of 4 scenarios" in watched.best[-1]
    assert len(set(watched.top_rows)) >= 3, (
        watched.top_rows
    )  # the table refreshes, not only the line above it


def test_the_page_has_no_console_errors(watched):
    assert watched.errors == []


def test_the_best_track_is_drawn_for_the_chosen_scenario(watched):
    from dse_runner.sweeps.rank import rank

    assert watched.track_title.startswith("sin1: best point so far")
    assert watched.chosen_track.startswith("turn_ramp1: best point so far")
    table1 = rank(watched.output, "watched").table1.set_index("scenario")
    assert watched.chosen_track.endswith(
        f"{table1.loc['turn_ramp1', 'computed']:.4f}"
    )  # the sweep's own figure


def test_dask_dashboard_links_to_it(watched):
    assert watched.dask_nav_has_link
    assert watched.dask_page_went_to == watched.url


def test_the_final_page_shows_the_rank_commands_best_point(watched):
    from dse_runner.sweeps.rank import rank

    ranking = rank(watched.output, "watched")
    best = ", ".join(f"{k} = {v:g}" for k, v in ranking.best.items())
    assert best in watched.best[-1]
    top = watched.top_rows[-1].split()  # '#', the parameters, scenarios, mean, total
    assert [float(v) for v in top[1:4]] == list(ranking.best.values())
    assert float(top[-1]) == pytest.approx(ranking.best_total, abs=1e-4)


def test_the_report_opens_offline(watched, tmp_path):
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    from dse_runner.sweeps.rank import rank

    report = tmp_path / "report.html"
    done = subprocess.run(
        [sys.executable, "-m", "dse_runner", "report", str(watched.output), "-o", str(report)],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    ranking = rank(watched.output, "watched")
    errors: list[str] = []
    requests: list[str] = []
    with browser_page(errors, offline=True) as page:
        page.on("request", lambda r: requests.append(r.url))
        page.goto(report.as_uri())
        figures = 3 + 4 + 1 + len(SWEEP_SCENARIOS)  # Figure 5, Figure 6, Pareto, a track per scenario
        # the figures draw themselves (in Bokeh's shadow roots, which locators see into) after the page loads
        try:
            page.locator("canvas").nth(figures - 1).wait_for(state="attached", timeout=30_000)
        except PlaywrightTimeout:
            pass  # the count below says how many there were
        canvases = page.locator("canvas").count()
        text = page.locator("body").inner_text()
    assert errors == []
    assert [r for r in requests if not r.startswith("file:")] == []
    assert canvases >= figures
    for scenario in SWEEP_SCENARIOS:  # Table 1 has every scenario with the rank command's figures
        row = ranking.table1.set_index("scenario").loc[scenario]
        assert re.search(rf"{scenario}\s+\S+\s+{row['min_error']:.6g}\s+{row['max_error']:.6g}", text), (
            scenario
        )
    assert "name: watched" in text and "vehicle.cAlphaF" in text  # the spec
    assert f"{ranking.best_total:.4f}" in text


DRAWN = "() => window.Bokeh && Bokeh.index.roots.length > 0 && Bokeh.index.roots.every(v => v.has_finished())"


def test_the_report_and_the_dashboard_fit_a_1400_px_page(watched, tmp_path):
    """Four scenario groups and three parameters: Figure 6's four panels once overflowed a 1400 px page, and
    Figure 5's title "cross_track_error against vehicle.cAlphaF" ran past its canvas. Measured in the
    browser, charts, titles and toolbars; a grid's Figure 5 keeps one line per scenario."""
    from dse_runner.interfaces.dashboard.server import serve
    from dse_runner.interfaces.report import write_report

    report = write_report(watched.output, tmp_path / "report.html")
    server = serve(watched.output, "watched")
    errors: list[str] = []
    try:
        with browser_page(errors, viewport={"width": 1400, "height": 1000}) as page:
            page.goto(report.as_uri())
            page.wait_for_function(DRAWN, timeout=30_000)
            on_report, report_lines = measure(page), glyphs(page, "dse-by-parameter-vehicle.mass")
            page.screenshot(path=tmp_path / "report-1400.png", full_page=True)
            page.goto(server.url)
            page.wait_for_function(
                "() => window.Bokeh && Bokeh.documents.some(d => "
                "d.get_model_by_name('dse-by-parameter-vehicle.mass')?.renderers[0]"
                ".data_source.get_length() > 0)",
                timeout=30_000,
            )
            page.wait_for_function(DRAWN, timeout=30_000)
            on_dashboard, dashboard_lines = measure(page), glyphs(page, "dse-by-parameter-vehicle.mass")
            page.screenshot(path=tmp_path / "dashboard-1400.png", full_page=True)
    finally:
        server.stop()
    assert errors == []
    figures = 3 + 4 + len(SWEEP_SCENARIOS)  # Figure 5, Figure 6, a track per scenario
    assert on_report.charts == on_report.titles >= figures, on_report
    assert on_dashboard.charts == on_dashboard.titles >= 3 + 4 + 1, on_dashboard  # and the best point's track
    assert on_report.misfits == [] and on_dashboard.misfits == []
    assert report_lines == dashboard_lines == [("MultiLine", len(SWEEP_SCENARIOS))]


def test_a_long_title_is_set_small_enough_to_fit_its_chart(tmp_path):
    """A parameter with a long name, and wide tick labels on the y axis: Figure 5's title shrinks to fit."""
    from bokeh.embed import file_html
    from bokeh.resources import INLINE

    from dse_runner.interfaces import charts

    names = ["controller.proportional_gain_of_the_outer_loop", "controller.k"]
    ok = pd.DataFrame(
        {
            names[0]: [1.0, 2.0, 3.0] * 2,
            names[1]: [0.5] * 6,
            "scenario": ["a"] * 3 + ["b"] * 3,
            "group": ["g"] * 6,
            "settling_time": [-123456.5, 2.5e5, 3.1e5, 1.2e5, 2.2e5, 3.3e5],
        }
    )
    figure5 = charts.ObjectiveByParameter(names, "settling_time", ["g"])
    figure5.update(ok)
    page_file = tmp_path / "long.html"
    page_file.write_text(file_html(figure5.layout, INLINE, "long title"))
    with browser_page(viewport={"width": 1400, "height": 600}) as page:
        page.goto(page_file.as_uri())
        page.wait_for_function(DRAWN, timeout=30_000)
        fit = measure(page)
    assert float(figure5.layout.children[0][0].title.text_font_size.removesuffix("pt")) < charts.TITLE_PT
    assert (fit.charts, fit.titles, fit.misfits) == (2, 2, [])


def test_the_page_shows_the_sweeps_end_when_submit_stops_its_server(watched):
    """Submit stops the dashboard it served as it ends: the open page shows the finished state, then says the
    server has stopped and how to open the results again."""
    assert watched.farewell_state == "finished"
    assert watched.farewell == (
        "The sweep's submit has ended, and its dashboard server with it. This page shows "
        f"the final state, and no longer updates. To open the results again: dse-runner "
        f"dashboard {watched.output}"
    )


def test_dashboard_command_serves_a_finished_sweep_and_its_page_outlives_it_without_error(watched):
    """Stopped by Ctrl-C, the server says goodbye on the open page and exits; the page notices the closed
    connection without a console error and without Bokeh's "connection was lost" banner, which a server
    killed without a word still gets."""
    import signal

    lost: list[str] = []
    for ending in (signal.SIGINT, signal.SIGKILL):
        server = subprocess.Popen(
            [sys.executable, "-m", "dse_runner", "dashboard", str(watched.output)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            line = server.stdout.readline()
            match = re.search(r"http://127\.0\.0\.1:\d+/", line)
            assert match, line + server.stderr.read()
            errors: list[str] = []
            with browser_page(errors) as page:
                page.on("console", lambda m: lost.append(m.text) if "Lost websocket" in m.text else None)
                open_dashboard(page, match[0])
                state, done = _text(page, "state"), _text(page, "done")
                noticed = len(lost)
                server.send_signal(ending)
                server.wait(timeout=30)
                deadline = time.monotonic() + 30
                while time.monotonic() < deadline and len(lost) == noticed:  # until the browser notices
                    page.wait_for_timeout(250)
                banner = page.get_by_text("connection was lost").count()
                said = _text(page, "farewell") if page.locator("#dse-farewell").count() else ""
        finally:
            server.kill()
            server.wait(timeout=10)
        assert (state, done) == ("finished", f"{TASKS} of {TASKS}")
        assert len(lost) > noticed, "the browser never noticed the server's end"
        if ending == signal.SIGINT:
            assert (errors, banner) == ([], 0)
            assert (
                said.startswith("This dashboard server was stopped (Ctrl-C).") and str(watched.output) in said
            )
        else:  # the control: a server killed without a word, as before
            assert banner == 1 and said == ""


def test_the_workers_table_of_a_finished_sweep_shows_no_running_task(tmp_path, dask_scheduler):
    """Two tasks of the sleeper (about 7 s of sleep each: long enough that the page, refreshed each second,
    shows them running on a busy machine too) start together on the cluster's two workers and end within a
    second of each other. The workers are sampled at most once a second, so the last sample, taken as the
    first task ended, still has the other running: the page showed it so while the sweep ran, and, once it
    has finished, shows both workers with nothing running."""
    from distributed import Client

    from dse_runner.interfaces.dashboard.server import serve
    from dse_runner.sweeps.spec import load_space
    from dse_runner.sweeps.status import load_status
    from dse_runner.sweeps.sweep import submit

    space = load_space(
        write_space(
            tmp_path,
            multimodel=str(sleeper_multimodel(tmp_path)),
            scenarios=[str(SCENARIOS / "sin1")],
            parameters={"sleeper.pause": [0.004, 0.00401]},
            keep_trajectories=0,
            chunk_seconds=0.05,
        )
    )
    server = serve(space.output, space.name, "127.0.0.1:0", space)
    outcome: dict = {}
    seen: list[list[str]] = []
    errors: list[str] = []
    with Client(dask_scheduler) as client, browser_page(errors) as page:
        open_dashboard(page, server.url)
        sweep = threading.Thread(target=lambda: outcome.update(report=submit(space, client=client)))
        sweep.start()
        while sweep.is_alive():
            seen.append(_running(page))
            time.sleep(0.5)
        sweep.join()
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and _text(page, "state") != "finished":
            time.sleep(0.25)
        final = _running(page)
    server.stop()  # waits for the page's own threads too: none outlives this test's FMU
    assert server.feed.pages and not [t for p in server.feed.pages for t in p.threads if t.is_alive()]
    assert outcome["report"].ok == 2 and errors == []
    assert any(int(n) > 0 for column in seen for n in column), seen
    assert final == ["0", "0"], final
    assert [w.executing for w in load_status(space.output, space.name).activity] == [0, 0]


def test_the_pages_html_shows_the_counts_before_any_script(watched):
    """A large study's page takes seconds to draw (BokehJS loads, pulls the document, draws it):
    the counts are in the HTML the server answers with, ahead of BokehJS's scripts, so a
    browser shows them as it parses."""
    from urllib.request import urlopen

    from dse_runner.interfaces.dashboard.server import serve

    server = serve(watched.output, "watched")
    try:
        with urlopen(server.url, timeout=60) as answer:
            page = answer.read().decode()
    finally:
        server.stop()
    first = page.index('id="dse-first"')
    assert f'id="dse-done">{TASKS} of {TASKS}<' in page[first : page.index("<script", first)]
    assert 'id="dse-state">finished<' in page and "<script" not in page[:first]


def test_standings_put_the_furthest_points_first():
    from dse_runner.sweeps.rank import standings

    ok = pd.DataFrame(
        {
            "a": [1.0, 1.0, 2.0, 3.0, 3.0],
            "scenario": ["s", "t", "s", "s", "t"],
            "e": [5.0, 1.0, 0.5, 2.0, 2.0],
        }
    )
    table = standings(ok, ["a"], "e", "min")
    assert table["a"].tolist() == [3.0, 1.0, 2.0]  # a=3 (mean 2) and a=1 (mean 3) have 2 scenarios
    assert table["scenarios"].tolist() == [2, 2, 1]


def test_standings_rank_as_the_ranking_reduces_over_scenarios():
    """over_scenarios: max ranks by the worst scenario, which here names another best than the mean."""
    from dse_runner.sweeps.rank import standings

    ok = pd.DataFrame(
        {"a": [1.0, 1.0, 2.0, 2.0], "scenario": ["s", "t", "s", "t"], "e": [0.0, 3.0, 2.0, 2.0]}
    )
    assert standings(ok, ["a"], "e", "min")["a"].tolist() == [1.0, 2.0]
    table = standings(ok, ["a"], "e", "min", "max")
    assert table["a"].tolist() == [2.0, 1.0] and table["ranked"].tolist() == [2.0, 3.0]


def test_draw_standings_rank_by_the_robust_figure_over_finished_draws():
    """Uncertain draws: a point's figure is over the draws finished on every
    scenario; the robust one ranks."""
    from dse_runner.sweeps.rank import draw_standings
    from dse_runner.sweeps.spec import RankingSpec

    draws = {1.0: [1.0, 1.0, 1.0, 1.0], 2.0: [0.0, 0.0, 0.0, 3.0]}  # a=2 has the better mean, the worse q90
    ok = pd.DataFrame(
        [
            {"a": a, "sample": k, "base": "s", "e": v}
            for a, values in draws.items()
            for k, v in enumerate(values)
        ]
        + [{"a": 3.0, "sample": 0, "base": "s", "e": -9.0}]
    )
    robust = RankingSpec(objective="e", robust={"quantile": 0.9})
    table = draw_standings(ok, ["a"], "e", robust, scenarios=1)
    assert table["a"].tolist() == [1.0, 2.0, 3.0] and table["draws"].tolist() == [4, 4, 1]
    assert table["ranked"].iloc[1] == pytest.approx(np.quantile(draws[2.0], 0.9))
    assert draw_standings(ok, ["a"], "e", RankingSpec(objective="e"), scenarios=1)["a"].tolist() == [
        2.0,
        1.0,
        3.0,
    ]
    unfinished = draw_standings(ok, ["a"], "e", robust, scenarios=2)  # no draw has run on both scenarios
    assert unfinished["draws"].tolist() == [0, 0, 0] and unfinished["ranked"].isna().all()


def test_standings_leave_out_finished_points_that_break_a_ranking_constraint():
    """A point that has finished every scenario (every draw on every scenario) and breaks a ranking constraint
    leaves the standings, as rank() leaves it out; one still running stays, ranked by what it has."""
    from dse_runner.sweeps.rank import draw_standings, standings, without_excluded
    from dse_runner.sweeps.spec import RankingSpec

    ok = pd.DataFrame(
        {
            "a": [1.0, 1.0, 2.0, 2.0, 3.0],
            "scenario": ["s", "t", "s", "t", "s"],
            "e": [0.0, 0.5, 1.0, 1.0, 0.1],
            "f": [9.0, 9.0, 1.0, 1.0, 9.0],
        }
    )
    kept = RankingSpec(objective="e", constraints=["f < 10"])  # a=1's total f is 18
    table = without_excluded(standings(ok, ["a"], "e", "min"), ok, ["a"], ["e", "f"], kept, scenarios=2)
    assert table["a"].tolist() == [2.0, 3.0]  # a=3 has finished one scenario of two: not judged yet
    assert without_excluded(
        standings(ok, ["a"], "e", "min"), ok, ["a"], ["e", "f"], RankingSpec(objective="e"), scenarios=2
    )["a"].tolist() == [1.0, 2.0, 3.0]

    drawn = pd.DataFrame(
        [
            {"a": a, "sample": k, "base": "s", "e": e, "f": f}
            for a, e, f in ((1.0, 0.0, 12.0), (2.0, 1.0, 8.0))
            for k in range(2)
        ]
    )
    table = draw_standings(drawn, ["a"], "e", kept, scenarios=1)
    assert without_excluded(table, drawn, ["a"], ["e", "f"], kept, 1, samples=2)["a"].tolist() == [2.0]
    assert without_excluded(table, drawn, ["a"], ["e", "f"], kept, 1, samples=3)["a"].tolist() == [1.0, 2.0]


def test_the_dashboard_names_the_best_point_the_ranking_constraints_keep(tmp_path, dask_scheduler):
    """A finished grid whose best points (y < 0.7, the free optimum y = 0 among them) break the ranking's
    constraint: the page's best-so-far line and table name the point dse-runner rank names, and list only the
    points it ranks."""
    import yaml

    from dse_runner.interfaces.dashboard.feed import Feed
    from dse_runner.interfaces.dashboard.page import best_html
    from dse_runner.sweeps.rank import rank
    from dse_runner.sweeps.spec import load_space
    from dse_runner.sweeps.sweep import submit

    spec = {
        "name": "kept",
        "multimodel": {"fmus": {"cliff": str(REPO / "tests" / "fmus" / "cliff")}},
        "parameters": {"cliff.a": [1, 2.2, 3, 3.5, 5], "cliff.b": [0, 1, 1.5]},  # y = (a - 3)^2 + (b - 1)^2
        "objectives": {"y": {"signal": "cliff.y", "reduce": "final"}},
        "ranking": {"objective": "y", "constraints": ["y >= 0.7"]},
        "output": str(tmp_path / "out"),
        "cluster": {"address": dask_scheduler},
        "keep_trajectories": 0,
    }
    (tmp_path / "space.yaml").write_text(yaml.safe_dump(spec))
    space = load_space(tmp_path / "space.yaml")
    assert submit(space).ok == 15
    ranking = rank(space.output, "kept")
    assert ranking.best == {"cliff.a": 2.2, "cliff.b": 1.5} and ranking.excluded_points == 5
    feed = Feed(space.output, "kept")
    snap = feed.snapshot()
    assert len(snap.standings) == len(ranking.totals) == 10
    assert {p: snap.standings.iloc[0][p] for p in space.parameters} == ranking.best
    assert snap.standings.iloc[0]["ranked"] == pytest.approx(ranking.best_total)
    line = best_html(snap, feed.parameters, feed.ranked_by, feed.counted(1))
    assert "best so far: cliff.a = 2.2, cliff.b = 1.5;" in line


def test_dashboard_address_errors_name_the_address():
    from dse_runner.errors import DseError
    from dse_runner.interfaces.dashboard.server import parse_address

    assert parse_address("127.0.0.1:0") == ("127.0.0.1", 0)
    with pytest.raises(DseError, match="8790x"):
        parse_address("8790x")


def test_report_of_a_folder_without_results_names_it(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "dse_runner", "report", str(tmp_path), "-o", str(tmp_path / "r.html")],
        check=False,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert str(tmp_path) in done.stderr and "no results" in done.stderr
    assert not (tmp_path / "r.html").exists()


def test_submit_prints_the_dashboard_url_and_its_dask_link(tmp_path, dask_scheduler):

    command = [
        sys.executable,
        "-m",
        "dse_runner",
        "submit",
        str(write_space(tmp_path, keep_trajectories=0)),
        "--scheduler",
        dask_scheduler,
        "--json",
    ]
    shown = subprocess.run(command, check=False, capture_output=True, text=True, timeout=300)
    assert shown.returncode == 0, shown.stderr
    assert strict_loads(shown.stdout)["ok"] == 12  # stdout stays one JSON object
    assert re.search(r"dse-runner dashboard: http://127\.0\.0\.1:\d+/", shown.stderr), shown.stderr
    assert re.search(r"linked from Dask's dashboard: http://\S+/dse-runner", shown.stderr), shown.stderr


def test_submit_without_dashboard_prints_no_address_and_keeps_table1s_columns_apart(tmp_path, dask_scheduler):
    """--no-dashboard: no address of ours or of Dask's, though the sweep runs on a scheduler that serves one.
    Its objective is the mean distance from x = -100 km, five or six figures before the decimal point:
    Table 1's columns widen to them, and each row still reads back as six fields."""
    space = write_space(
        tmp_path,
        keep_trajectories=0,
        objectives={"far": {"signal": "vehicle.x", "reduce": "mean", "target": -100000}},
        ranking={"objective": "far"},
    )
    quiet = subprocess.run(
        [
            sys.executable,
            "-m",
            "dse_runner",
            "submit",
            str(space),
            "--scheduler",
            dask_scheduler,
            "--no-dashboard",
        ],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert quiet.returncode == 0, quiet.stderr
    assert "ran 12 simulations (0 failed)" in quiet.stdout
    assert "http" not in quiet.stderr + quiet.stdout, quiet.stderr
    lines = quiet.stdout.splitlines()
    table = lines[lines.index(next(line for line in lines if line.startswith("Table 1: "))) + 1 :][:3]
    assert table[0].split() == ["scenario", "min", "max", "average", "best", "difference"]
    for line in table[1:]:
        scenario, *figures = line.split()
        assert scenario in ("sin1", "speed_step2") and len(figures) == 5, line
        assert all(10000 < float(f) < 1000000 for f in figures[:4]), line
    assert len({len(line) for line in table}) == 1, table  # right-aligned: every line ends at the same column
