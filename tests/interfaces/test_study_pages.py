"""The sensitivity and uncertainty figures (interfaces/study_figures.py) in the HTML report and the live
dashboard, looked at in a real headless Chromium: sweeps of the Ishigami FMU run on the real cluster, a Sobol'
design, a Morris design and an uncertainty study with a robust ranking."""

from __future__ import annotations

import subprocess
import sys

import pytest
import yaml
from conftest import REPO
from support.pages import browser_page, measure

ISHIGAMI = REPO / "jobs" / "ishigami"
PI = 3.141592653589793


def _job(folder, address: str, **changes):
    from dse_runner.sweeps.spec import load_space

    spec = yaml.safe_load((ISHIGAMI / "space.yaml").read_text())
    spec.update(output=str(folder / "out"), cluster={"address": address}, **changes)
    spec["multimodel"] = {"fmus": {"ishigami": str(ISHIGAMI / "fmus" / "ishigami")}}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "space.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return load_space(folder / "space.yaml")


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory, dask_scheduler):
    """Three finished sweeps: name -> (output, the element id of its figure)."""
    from dse_runner.sweeps.sweep import submit

    root = tmp_path_factory.mktemp("studies")
    uniform = {"distribution": "uniform", "low": -PI, "high": PI}
    made = {
        "sobol": (
            _job(root / "sobol", dask_scheduler, search={"strategy": "sobol_indices", "max_points": 1000}),
            "sensitivity-y",
        ),
        "morris": (
            _job(
                root / "morris",
                dask_scheduler,
                name="morris",
                search={"strategy": "morris", "max_points": 200, "levels": 4},
            ),
            "sensitivity-y",
        ),
        "uncertain": (
            _job(
                root / "uncertain",
                dask_scheduler,
                name="robust",
                parameters={"ishigami.a": [-4.0, -2.0], "ishigami.b": [0.0, 0.2]},
                search={"strategy": "exhaustive"},
                uncertain={
                    "samples": 64,
                    "parameters": {x: uniform for x in ("ishigami.x1", "ishigami.x2", "ishigami.x3")},
                },
                ranking={"robust": {"quantile": 0.9}},
            ),
            "uncertainty-distributions",
        ),
    }
    for space, _ in made.values():
        assert submit(space).failed == 0
    return {name: (space.output, space.name, ident) for name, (space, ident) in made.items()}


def _look(url: str, ident: str) -> dict:
    """Open ``url`` in a 1400 px window; the figure's natural size, console errors and what does not fit."""
    errors: list[str] = []
    with browser_page(errors, viewport={"width": 1400, "height": 900}) as page:
        page.goto(url)
        figure = page.locator(f"#{ident}")
        figure.wait_for(state="attached", timeout=60_000)
        page.wait_for_function(
            "() => window.Bokeh && Bokeh.index.roots.length > 0 && "
            "Bokeh.index.roots.every(v => v.has_finished())",
            timeout=60_000,
        )
        size = figure.evaluate("e => [e.complete, e.naturalWidth, e.getBoundingClientRect().right]")
        fit = measure(page)
        text = page.locator("body").inner_text()
        table = page.locator("#dse-ranking")  # the dashboard's best-so-far table
        ranking = (
            {
                "best": page.locator("#dse-best").inner_text(),
                "headings": table.locator("th").all_inner_texts(),
                "top": table.locator("tbody tr").first.locator("td").all_inner_texts(),
            }
            if table.count()
            else {}
        )
    return {
        "loaded": size[0],
        "width": size[1],
        "right": size[2],
        "errors": errors,
        "misfits": fit.misfits,
        "text": text,
        **ranking,
    }


@pytest.mark.parametrize("kind", ["sobol", "morris", "uncertain"])
def test_the_report_shows_the_figure(sweeps, tmp_path, kind):
    output, _, ident = sweeps[kind]
    report = tmp_path / "report.html"
    done = subprocess.run(
        [sys.executable, "-m", "dse_runner", "report", str(output), "-o", str(report)],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    seen = _look(report.as_uri(), ident)
    assert seen["loaded"] and seen["width"] > 300, seen
    assert seen["right"] <= 1400 and seen["errors"] == [] and seen["misfits"] == []
    if kind == "uncertain":
        assert "Ranking by q90 of total y over 64 draws" in seen["text"]
        assert "uniform(low -3.14159, high 3.14159)" in seen["text"]
    else:
        assert ("Sobol' first-order" if kind == "sobol" else "Morris' mu*") in seen["text"]


@pytest.mark.parametrize("kind", ["sobol", "uncertain"])
def test_the_dashboard_of_a_finished_sweep_shows_the_figure(sweeps, kind):
    from dse_runner.interfaces.dashboard.server import serve

    output, sweep, ident = sweeps[kind]
    server = serve(output, sweep, "127.0.0.1:0")
    try:
        seen = _look(server.url, ident)
    finally:
        server.stop()
    assert seen["loaded"] and seen["width"] > 300, seen
    assert seen["errors"] == [] and seen["misfits"] == []


def test_the_uncertain_figure_is_of_the_ranked_points(sweeps):
    """The figure is drawn from the ranking's draws: every ranked point, each with all its draws."""
    from dse_runner.sweeps.rank import rank

    output, sweep, _ = sweeps["uncertain"]
    ranking = rank(output, sweep)
    assert len(ranking.totals) == 4 and len(ranking.draws) == 4 * 64
    assert ranking.ranked_by == "y_robust" and ranking.uncertainty["ranked_by"] == "q90"


def test_the_dashboard_names_the_robust_best_as_rank_does(sweeps):
    """With ``ranking: {robust: {quantile: 0.9}}`` the best-so-far line and table rank by the q90 over the
    draws, as the rank command does and as the uncertainty section below them says, not by the mean; the
    table's last column says so. On this sweep the best q90 and the best mean are different points."""
    from dse_runner.interfaces.dashboard.server import serve
    from dse_runner.sweeps.rank import format_point, rank

    output, sweep, ident = sweeps["uncertain"]
    ranking = rank(output, sweep)
    by_mean = ranking.totals.sort_values("y", kind="stable").iloc[0]
    assert {
        p: by_mean[p] for p in ranking.parameters
    } != ranking.best  # else the test could not tell them apart
    server = serve(output, sweep, "127.0.0.1:0")
    try:
        seen = _look(server.url, ident)
    finally:
        server.stop()
    assert (
        f"best so far: {format_point(ranking.best)}; q90 of "
        f"total y {ranking.best_total:.4f} over 64 of 64 draws" == seen["best"]
    )
    assert seen["headings"][-1] == "ranked by: q90 of total y"
    assert [float(v) for v in seen["top"][1:3]] == list(ranking.best.values())
    assert float(seen["top"][-1]) == pytest.approx(ranking.best_total, abs=1e-4)
    assert seen["errors"] == [] and seen["misfits"] == []
