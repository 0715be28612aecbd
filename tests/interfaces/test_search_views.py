"""What the dashboard and the report add for a closed-loop search: best so far against simulations and
the Pareto front as it grew (charts.best_so_far, charts.pareto_stages), the search line, and both pages
in Debian's Chromium over a real search on the multi-process cluster."""

from __future__ import annotations

import re
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, write_msd_search
from support.pages import Fit, browser_page, glyphs, measure, watch_errors

from dse_runner.interfaces import charts
from dse_runner.interfaces.dashboard.feed import search_summary
from dse_runner.interfaces.dashboard.page import search_html
from dse_runner.sweeps.closed_loop import SearchStatus
from dse_runner.sweeps.history import SearchHistory

MSD = REPO / "jobs" / "msd"
POINTS = 24


# --- the pure functions, on hand-made histories ---------------------------------------------------


def told(history: SearchHistory, number: int, state: str = "ok", **values: float) -> None:
    history.tell(number, state, values)


def hand_made() -> SearchHistory:
    """Six asks with two in flight at a time, told out of order: a failed point, an infeasible one, and a
    point asked again after its first copy was told (the search reads that one from the store)."""
    h = SearchHistory(sweep="s", strategy="tpe", settings="x")
    for k in (1.0, 2.0):
        h.ask({"k": k})
    told(h, 1, rmse=5.0, peak=1.0)  # number 1 first
    h.ask({"k": 3.0})  # 2
    told(h, 0, rmse=7.0, peak=0.5)
    h.ask({"k": 4.0})  # 3: infeasible
    told(h, 3, "infeasible")
    h.ask({"k": 5.0})  # 4
    told(h, 2, "failed")
    h.ask({"k": 2.0})  # 5: the same point as number 1, told already
    told(h, 5, rmse=5.0, peak=1.0)
    told(h, 4, rmse=3.0, peak=2.0)
    return h


def test_best_so_far_follows_the_tells_and_counts_simulations():
    progress = charts.best_so_far(hand_made(), "rmse", "min", n_scenarios=3)
    assert progress["number"].tolist() == [1, 0, 2, 5, 4]  # tell order; the infeasible point has no row
    assert progress["state"].tolist() == ["ok", "ok", "failed", "ok", "ok"]
    assert progress["simulated"].tolist() == [True, True, True, False, True]
    assert progress["simulations"].tolist() == [3, 6, 9, 9, 12]  # 3 scenarios a point; the repeat is free
    np.testing.assert_array_equal(progress["value"], [5.0, 7.0, np.nan, 5.0, 3.0])
    assert progress["best"].tolist() == [5.0, 5.0, 5.0, 5.0, 3.0]


def test_best_so_far_is_the_running_best_by_goal():
    rng = np.random.default_rng(3)
    h = SearchHistory(sweep="s", strategy="random", settings="x")
    values = rng.normal(size=200)
    failed = np.arange(200) % 17 == 5
    for i, v in enumerate(values):
        h.ask({"a": float(i)})
        told(h, i, "failed" if failed[i] else "ok", e=float(v))
    for goal, running in (("min", np.fmin.accumulate), ("max", np.fmax.accumulate)):
        progress = charts.best_so_far(h, "e", goal, n_scenarios=1)
        best = progress["best"].to_numpy()
        assert np.all(np.diff(best) <= 0) if goal == "min" else np.all(np.diff(best) >= 0)  # monotone
        np.testing.assert_array_equal(best, running(progress["value"].to_numpy()))
        ok = values[~failed]  # a failed point has no value
        assert best[-1] == (ok.min() if goal == "min" else ok.max())
        assert progress["simulations"].tolist() == list(range(1, 201))


def test_best_so_far_of_an_empty_or_all_failed_history():
    h = SearchHistory(sweep="s", strategy="tpe", settings="x")
    assert charts.best_so_far(h, "e", "min", 2).empty
    h.ask({"a": 1})
    h.ask({"a": 2})  # still running: not drawn
    told(h, 0, "failed")
    progress = charts.best_so_far(h, "e", "min", 2)
    assert progress["simulations"].tolist() == [2] and progress["best"].isna().all()


def dominated(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether ``a`` is dominated by ``b`` (both minimised)."""
    return bool(np.all(b <= a) and np.any(b < a))


@pytest.mark.parametrize("goals", [("min", "min"), ("min", "max"), ("max", "min")])
def test_pareto_stages_are_the_fronts_of_the_first_points(goals):
    rng = np.random.default_rng(7)
    h = SearchHistory(sweep="s", strategy="nsga2", settings="x")
    for i in range(41):
        h.ask({"a": float(i)})
        x = rng.uniform()
        told(h, i, "infeasible" if i % 10 == 3 else "ok", f=x, g=float(1 / (x + 0.05) + rng.uniform(0, 4)))
    points = charts.search_points(h, ["f", "g"])
    assert len(points) == 41 - 4 and points["order"].tolist() == list(range(len(points)))
    stages = charts.pareto_stages(points, list(zip(["f", "g"], goals)))
    assert [n for n, _ in stages] == [10, 19, 28, 37]  # ceil of 25, 50, 75, 100% of 37
    signs = np.array([1.0 if g == "min" else -1.0 for g in goals])
    for n, front in stages:
        first = points.iloc[:n][["f", "g"]].to_numpy() * signs
        shown = front[["f", "g"]].to_numpy() * signs
        assert front["order"].max() < n  # only points told by then
        assert not any(dominated(p, q) for p in shown for q in first)  # non-dominated among the first n
        assert all(any(dominated(p, q) or np.array_equal(p, q) for q in shown) for p in first)  # and complete
        assert front["f"].is_monotonic_increasing  # sorted along the first objective: drawn as steps
    previous = set()
    for _, front in stages:  # a later front has points at least as good as every earlier front point
        now = front[["f", "g"]].to_numpy() * signs
        assert all(any(dominated(np.array(p), q) or np.array_equal(p, q) for q in now) for p in previous)
        previous = {tuple(p) for p in now}


def test_charts_fill_from_a_history():
    h = hand_made()
    best = charts.BestSoFarChart("rmse", "min", 3)
    best.update(h)
    assert list(best.points.data["simulations"]) == [3, 6, 9, 12]  # ok points only
    assert list(best.best.data["best"]) == [5.0, 5.0, 5.0, 5.0, 3.0]
    growth = charts.ParetoGrowthChart([("rmse", "min"), ("peak", "min")], ["k"])
    stages = growth.update(h)
    assert list(growth.points.data["order"]) == [0, 1, 2, 3] and list(growth.points.data["k"]) == [
        2.0,
        1.0,
        2.0,
        5.0,
    ]
    assert [n for n, _ in stages] == [1, 2, 3, 4]
    assert sorted(growth.fronts[-1].data["x"]) == [3.0, 5.0, 5.0, 7.0]  # 5.0 twice: the point asked again
    growth.update(SearchHistory(sweep="s", strategy="tpe", settings="x"))  # an empty history empties it
    assert len(growth.points.data["x"]) == 0 and all(len(s.data["x"]) == 0 for s in growth.fronts)


def test_search_line_from_the_status_or_else_the_history():
    status = SearchStatus(
        strategy="tpe",
        objective="rmse",
        goal="min",
        max_points=30,
        points=12,
        infeasible=2,
        failed=1,
        best=0.0123456,
        threads=2,
        busy_seconds=9.0,
        window_seconds=5.0,
        stopped="budget",
    )
    line = search_html(search_summary(status, None, "rmse", "min", 30))
    assert re.search(
        r'id="dse-search">tpe · 12 of 30 points · best rmse 0.0123456 · 2 infeasible · 1 failed · '
        r"utilisation 90% · stopped budget<",
        line,
    ), line
    cells = dict(search_summary(None, hand_made(), "rmse", "min", 30))  # no status: counted from the history
    assert cells["strategy"] == "tpe" and cells["points"] == "5 of 30" and cells["best rmse"] == "3"
    assert (cells["infeasible"], cells["failed"]) == ("1", "1")


# --- a real search, watched in Chromium ------------------------------------------------------------


def write_search(folder: Path) -> Path:
    """The mass-spring-damper calibration as a tpe search over continuous k and c, two objectives."""
    return write_msd_search(
        folder,
        {"strategy": "tpe", "max_points": POINTS, "seed": 1},
        keep_trajectories=1,
        objectives={
            "position_rmse": {"signal": "msd.x", "recorded": "x", "metric": "rmse"},
            "position_max": {"signal": "msd.x", "recorded": "x", "metric": "max_abs"},
        },
        ranking={"objective": "position_rmse", "pareto": ["position_rmse", "position_max"]},
    )


def drawn(page, name: str, column: str) -> int:
    """How many rows the browser's copy of the Bokeh data source ``name`` holds."""
    return page.evaluate(
        "([name, column]) => { for (const doc of Bokeh.documents) {"
        " const model = doc.get_model_by_name(name); if (model) return model.data[column].length; }"
        " return -1 }",
        [name, column],
    )


@dataclass
class Seen:
    output: Path
    mid_points: int = -1  # best-so-far dots on the page while the search waited halfway
    mid_line: str = ""
    final_line: str = ""
    final_points: int = -1
    final_fronts: list[int] = field(default_factory=list)
    headings: int = 0  # the search's heading, found (Bokeh's Divs are in shadow roots, which locators pierce)
    canvases: int = 0
    finished_line: str = ""  # `dse-runner dashboard`'s page of the finished search (no space given)
    finished_points: int = -1
    errors: list[str] = field(default_factory=list)
    fit: Fit | None = None  # the finished search's page, measured in a 1400 px window
    by_parameter: list | None = None  # the glyphs of Figure 5's chart of msd.k, and their rows


@pytest.fixture(scope="module")
def searched(tmp_path_factory, dask_scheduler) -> Seen:
    from distributed import Client

    from dse_runner.interfaces.dashboard.server import serve
    from dse_runner.sweeps.spec import load_space
    from dse_runner.sweeps.sweep import submit

    space = load_space(write_search(tmp_path_factory.mktemp("search-views")))
    server = serve(space.output, space.name, "127.0.0.1:0", space)
    seen = Seen(Path(space.output))
    outcome: dict = {}
    looked = threading.Event()
    gate = [POINTS // 2]

    def pace(report) -> None:
        """Halfway, wait until the page shows the search's first points: so the browser sees it mid-way."""
        if gate and report.ran >= gate[0]:
            gate.pop()
            looked.wait(timeout=60)

    def run() -> None:
        try:
            with Client(dask_scheduler) as client:
                outcome["report"] = submit(space, progress=pace, client=client)
        except BaseException as e:  # noqa: BLE001  (reported by the test)
            outcome["error"] = e

    with browser_page(seen.errors, viewport={"width": 1300, "height": 1600}) as page:
        page.goto(server.url)
        page.locator("#dse-search").wait_for(timeout=30_000)
        search = threading.Thread(target=run)
        search.start()
        while search.is_alive():
            if not looked.is_set() and drawn(page, "dse-best-so-far-points", "value") > 0:
                seen.mid_points = drawn(page, "dse-best-so-far-points", "value")
                seen.mid_line = page.locator("#dse-search").inner_text()
                looked.set()
            time.sleep(0.2)
        search.join()
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and (
            f"{POINTS} of {POINTS} points" not in page.locator("#dse-search").inner_text()
            or drawn(page, "dse-best-so-far-points", "value") < POINTS
        ):
            time.sleep(0.25)
        seen.final_line = page.locator("#dse-search").inner_text()
        seen.final_points = drawn(page, "dse-best-so-far-points", "value")
        seen.final_fronts = [drawn(page, f"dse-front-growth-{share}", "x") for share in (25, 50, 75, 100)]
        seen.headings = page.get_by_text(
            "Search: best position_rmse against simulations, and the Pareto front as it grew"
        ).count()
        seen.canvases = page.locator("canvas").count()
        page.set_viewport_size({"width": 1400, "height": 1600})
        page.wait_for_function("() => Bokeh.index.roots.every(v => v.has_finished())", timeout=30_000)
        seen.fit, seen.by_parameter = measure(page), glyphs(page, "dse-by-parameter-msd.k")
        page.screenshot(path=space.output.parent / "dashboard-1400.png", full_page=True)
        server.stop()

        finished = serve(space.output, space.name)  # as `dse-runner dashboard RESULTS` does: no space
        other = page.context.browser.new_page()
        watch_errors(other, seen.errors)
        other.goto(finished.url)
        other.locator("#dse-search").wait_for(timeout=30_000)
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and drawn(other, "dse-best-so-far-points", "value") < POINTS:
            time.sleep(0.25)
        seen.finished_line = other.locator("#dse-search").inner_text()
        seen.finished_points = drawn(other, "dse-best-so-far-points", "value")
        finished.stop()
    if "error" in outcome:
        raise outcome["error"]
    assert outcome["report"].search.points == POINTS, outcome["report"]
    return seen


def test_dashboard_shows_the_search_as_it_runs(searched):
    assert searched.errors == []
    assert 0 < searched.mid_points < POINTS, searched.mid_points  # seen mid-search
    assert searched.mid_line.startswith("tpe · ") and f"of {POINTS} points" in searched.mid_line
    assert re.fullmatch(
        rf"tpe · {POINTS} of {POINTS} points · best position_rmse [\d.e-]+ · 0 infeasible · "
        r"0 failed · utilisation \d+% · stopped budget",
        searched.final_line,
    ), searched.final_line
    assert searched.final_points == POINTS
    assert searched.headings == 1
    assert 0 < searched.final_fronts[0] and all(n > 0 for n in searched.final_fronts)
    assert searched.canvases >= 2 + 2 + 1 + 1  # the search's two charts, Figure 5, Figure 6, the track


def test_dashboard_draws_the_searchs_points_as_dots_on_a_page_that_fits_1400_px(searched):
    assert searched.by_parameter == [("Scatter", POINTS)]  # one dot a point on its one scenario
    assert searched.fit.charts == searched.fit.titles >= 2 + 2 + 1 + 1, searched.fit
    assert searched.fit.misfits == []


def test_dashboard_of_the_finished_search_reads_it_from_the_store(searched):
    assert searched.finished_line == searched.final_line
    assert searched.finished_points == POINTS


def test_dashboard_best_matches_the_rank_command(searched):
    from dse_runner.sweeps.rank import rank

    ranking = rank(searched.output, "msd-search")
    assert len(ranking.totals) == POINTS
    assert f"best position_rmse {ranking.best_total:.6g}" in searched.final_line


def test_report_has_the_search(searched, tmp_path):
    from dse_runner.interfaces.report import write_report
    from dse_runner.sweeps.history import load_history
    from dse_runner.sweeps.rank import rank

    report = write_report(searched.output, tmp_path / "report.html")
    history = load_history(searched.output, "msd-search")
    progress = charts.best_so_far(history, "position_rmse", "min", 1)
    assert progress["best"].iloc[-1] == pytest.approx(rank(searched.output).best_total)
    errors: list[str] = []
    with browser_page(errors, offline=True) as page:
        page.goto(report.as_uri())
        page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0", timeout=30_000)
        dots, line = (
            drawn(page, "dse-best-so-far-points", "value"),
            drawn(page, "dse-best-so-far-line", "best"),
        )
        front = drawn(page, "dse-front-growth-100", "x")
        search = page.locator("#search").inner_text()
    assert errors == []
    assert (dots, line) == (POINTS, POINTS) and front > 0
    rows = dict(r.split("\t") for r in search.splitlines())
    assert rows["strategy"] == "tpe" and rows["points"] == f"{POINTS} of {POINTS}"
    assert float(rows["best position_rmse"]) == pytest.approx(progress["best"].iloc[-1], rel=1e-5)


def test_report_draws_the_searchs_points_as_dots_on_a_page_that_fits_1400_px(searched, tmp_path):
    from dse_runner.interfaces.report import write_report

    report = write_report(searched.output, tmp_path / "report.html")
    with browser_page(offline=True, viewport={"width": 1400, "height": 1000}) as page:
        page.goto(report.as_uri())
        page.wait_for_function(
            "() => window.Bokeh && Bokeh.index.roots.length > 0 && "
            "Bokeh.index.roots.every(v => v.has_finished())",
            timeout=30_000,
        )
        fit = measure(page)
        drawn = {name: glyphs(page, f"dse-by-parameter-{name}") for name in ("msd.k", "msd.c")}
        page.screenshot(path=tmp_path / "report-1400.png", full_page=True)
    assert drawn == {"msd.k": [("Scatter", POINTS)], "msd.c": [("Scatter", POINTS)]}
    assert fit.charts == fit.titles >= 2 + 1 + 2 + 1 + 1, fit  # search, Pareto, Figures 5 and 6, a track
    assert fit.misfits == []


def test_a_grid_sweep_shows_no_search():
    """A grid sweep (exhaustive, no history) gets no search line or charts: its pages are as before."""
    from dse_runner.interfaces.dashboard.feed import Feed, Snapshot
    from dse_runner.sweeps.spec import load_space

    space = load_space(MSD / "space.yaml")
    feed = Feed(space.output, space.name, space)
    assert not feed.closed_loop
    assert not feed.searching(Snapshot(None, pd.DataFrame(), 0, 0, pd.DataFrame()))
