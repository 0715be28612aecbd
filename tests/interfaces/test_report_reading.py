"""The report as a user reads it (issue 50, point 5), in Debian's Chromium at 1400 and 1280 px: figures as
wide as the page, legends outside the data and no entry for a glyph with nothing drawn, the Pareto front's
extreme points drawn whole, captions in the study's own names, and the spec that ran. Two real sweeps: the
water tank (no recordings, one scenario, a grid of two thresholds), the Robotti (field data, three groups)."""

from __future__ import annotations

import re

import pytest
import yaml
from conftest import REPO, SCENARIOS, write_space, write_yaml
from support.pages import browser_page, measure
from support.plugins import register

from dse_runner.interfaces import charts
from dse_runner.interfaces.report import figure_notes, pareto_note, shown_spec, write_report
from dse_runner.sweeps.spec import SpaceSpec

POINTS = {"tank": 9, "robotti": 6}  # parameter points of each sweep
WIDTHS = (1400, 1280)  # the window the pages are made for, and a common laptop's
DRAWN = "() => window.Bokeh && Bokeh.index.roots.length > 0 && Bokeh.index.roots.every(v => v.has_finished())"

# Per Bokeh root of charts (a chart or a grid of them; not Bokeh's notifications): its width, and each chart's
# name, width and top edge; and the body's width.
LAYOUT = """() => {
  const charts = (view) => (view.canvas_view && view.renderer_views ? [view] : [])
    .concat(...(view.child_views || []).map(charts));
  const roots = Bokeh.index.roots.filter(root => charts(root).length).map(root => ({
    width: root.el.getBoundingClientRect().width,
    charts: charts(root).map(v => { const box = v.el.getBoundingClientRect();
      return {name: v.model.name || v.model.title.text, width: box.width, top: Math.round(box.top)}; })}));
  return {body: document.body.getBoundingClientRect().width, roots: roots};
}"""

# Every chart's legends: where they stand, and each entry's label, visibility and its glyphs' rows; its
# ranges, and its first glyph's values on either axis.
LEGENDS = """() => {
  const out = [];
  const walk = (view) => {
    if (view.canvas_view && view.renderer_views) {
      const m = view.model, glyph = m.renderers[0].glyph, source = m.renderers[0].data_source;
      const values = (spec) => spec && spec.field ? Array.from(source.data[spec.field] || []).flat() : [];
      const legends = [];
      for (const side of ['center', 'below', 'above', 'left', 'right'])
        for (const l of m[side]) if (l.type === 'Legend') legends.push({side: side, visible: l.visible,
          items: l.items.map(i => ({label: JSON.stringify(i.label), visible: i.visible,
                                    rows: i.renderers.map(r => r.data_source.get_length())}))});
      out.push({name: m.name || m.title.text, legends: legends,
                x: [m.x_range.start, m.x_range.end], y: [m.y_range.start, m.y_range.end],
                xs: values(glyph.x || glyph.xs), ys: values(glyph.y || glyph.ys)});
    }
    for (const child of view.child_views || []) walk(child);
  };
  for (const root of Bokeh.index.roots) walk(root);
  return out;
}"""


@pytest.fixture(scope="module")
def reports(tmp_path_factory, dask_scheduler) -> dict:
    """Two finished sweeps and their reports: name -> (report path, the spec the sweep stored)."""
    from dse_runner.sweeps.rank import load_sweep_spec
    from dse_runner.sweeps.spec import load_space
    from dse_runner.sweeps.sweep import submit

    root = tmp_path_factory.mktemp("reading")
    tank = root / "tank"
    tank.mkdir()
    tank_spec = write_yaml(
        tank,
        {
            "name": "tank",
            "multimodel": str(REPO / "jobs" / "watertank" / "multimodel.yaml"),
            "experiment": {"start_time": 0, "stop_time": 100, "step": 0.1},
            "parameters": {"controller.minlevel": [0.5, 1.0, 1.5], "controller.maxlevel": [1.6, 2.0, 2.4]},
            "objectives": {
                "level_deviation": {"signal": "tank.level", "target": 1.5, "reduce": "rms"},
                "switches": {"signal": "controller.valve", "reduce": "changes"},
            },
            "ranking": {"objective": "level_deviation", "pareto": ["level_deviation", "switches"]},
            "output": str(tank / "out"),
            "cluster": {"address": dask_scheduler},
        },
    )
    robotti = root / "robotti"
    robotti.mkdir()
    robotti_spec = write_space(
        robotti,
        name="field",
        cluster={"address": dask_scheduler},
        scenarios=[str(SCENARIOS / s) for s in ("sin1", "speed_step1", "turn_ramp1")],
        objectives=["cross_track_error", "max_error"],
        ranking={"objective": "cross_track_error", "pareto": ["cross_track_error", "max_error"]},
    )
    made = {}
    for name, path in (("tank", tank_spec), ("robotti", robotti_spec)):
        space = load_space(path)
        assert submit(space).failed == 0
        report = write_report(space.output, root / f"{name}.html")
        made[name] = (report, load_sweep_spec(space.output, space.name))
    return made


def _read(report, width: int) -> dict:
    """What a ``width`` px window shows of ``report``: layout, legends, what does not fit, the text."""
    errors: list[str] = []
    with browser_page(errors, offline=True, viewport={"width": width, "height": 1000}) as page:
        page.goto(report.as_uri())
        page.wait_for_function(DRAWN, timeout=60_000)
        seen = {
            "layout": page.evaluate(LAYOUT),
            "legends": page.evaluate(LEGENDS),
            "fit": measure(page),
            "text": page.locator("body").inner_text(),
            "spec": page.locator("pre").inner_text(),
        }
    return {**seen, "errors": errors}


@pytest.fixture(scope="module")
def seen(reports) -> dict:
    """(study, window width) -> what the browser showed."""
    return {(name, width): _read(report, width) for name, (report, _) in reports.items() for width in WIDTHS}


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("study", ["tank", "robotti"])
def test_figures_fill_the_page(seen, study, width):
    """Each figure, or grid of figures, is as wide as the page's body (1300 px at 1400, 1200 at 1280); a
    chart in a row of n is at least 90% of an n-th of it. The report once drew 380 px charts, two in 760."""
    page = seen[study, width]
    body = page["layout"]["body"]
    assert body == (1300 if width == 1400 else width - 80)
    assert page["errors"] == [] and page["fit"].misfits == [], page["fit"]
    for root in page["layout"]["roots"]:
        names = [c["name"] for c in root["charts"]]
        assert root["width"] >= 0.97 * body, (names, root["width"], body)
        per_row = max(sum(c["top"] == chart["top"] for c in root["charts"]) for chart in root["charts"])
        for chart in root["charts"]:
            assert chart["width"] >= 0.9 * (body - 40) / per_row, (chart, per_row, body)


@pytest.mark.parametrize("study", ["tank", "robotti"])
def test_legends_stand_outside_the_data_and_list_only_what_is_drawn(seen, study):
    """No legend inside a plot (the Pareto front's once hid its top-right points), and no entry whose glyphs
    have no rows: the water tank has no recording, and once showed a "recorded" entry for it."""
    charts_seen = seen[study, 1400]["legends"]
    assert len(charts_seen) >= 4
    for chart in charts_seen:
        sides = [legend["side"] for legend in chart["legends"]]
        assert sides and set(sides) == {"below"}, chart["name"]
        for legend in chart["legends"]:
            shown = [item for item in legend["items"] if item["visible"] and legend["visible"]]
            assert shown, chart["name"]
            assert all(max(item["rows"]) > 0 for item in shown), (chart["name"], shown)
    labels = {
        item["label"]
        for chart in charts_seen
        for legend in chart["legends"]
        for item in legend["items"]
        if item["visible"]
    }
    assert ('{"value":"recorded"}' in labels) == (study == "robotti")


@pytest.mark.parametrize("study", ["tank", "robotti"])
def test_the_pareto_fronts_extreme_points_are_drawn_whole(seen, study):
    """Every point lies at least 6% of the range inside each axis's ends: a marker at an end is not cut."""
    pareto = next(c for c in seen[study, 1400]["legends"] if c["name"] == "dse-pareto")
    for axis, (start, end), values in (("x", pareto["x"], pareto["xs"]), ("y", pareto["y"], pareto["ys"])):
        assert len(values) == POINTS[study]
        low, high = min(values), max(values)
        assert min(low - start, end - high) >= 0.06 * (end - start), (axis, start, end, low, high)


def test_captions_name_the_studys_objectives_not_the_paper(seen):
    """The water tank's report once said "the paper's Table 1" and "the paper's Figure 6"."""
    text = seen["tank", 1400]["text"]
    assert "paper" not in text.lower()
    assert "Every ranked point on total level_deviation (lower is better) against total switches" in text
    assert "the mean level_deviation at each of its values, over every value of the others" in text
    assert "in the order of their values of controller.minlevel, controller.maxlevel" in text
    assert "The best point on each scenario" in text and "recording" not in text.split("The best point on")[1]
    assert "The best point against each scenario's recording" in seen["robotti", 1400]["text"]


@pytest.mark.parametrize("study", ["tank", "robotti"])
def test_the_spec_shown_is_the_one_that_ran(seen, reports, study):
    """A grid's spec shows no search section (it once showed ``max_points: 100``, a budget a grid does not
    have), nor any key at its default; read back, with the defaults, it is the spec the sweep stored."""
    shown = seen[study, 1400]["spec"]
    assert "max_points" not in shown and "search:" not in shown and "null" not in shown
    assert SpaceSpec.model_validate(yaml.safe_load(shown)) == reports[study][1]


# --- the pure parts, without a sweep ---------------------------------------------------------------


def test_a_searchs_budget_and_seed_stay_in_the_spec_even_at_their_defaults():
    base = {"name": "s", "multimodel": "m.yaml", "parameters": {"a": {"low": 0, "high": 1}}}
    search = shown_spec(SpaceSpec.model_validate({**base, "search": {"strategy": "tpe"}}))["search"]
    assert search == {"strategy": "tpe", "max_points": 100, "seed": 0}
    grid = shown_spec(
        SpaceSpec.model_validate(
            {**base, "parameters": {"a": [0, 1]}, "search": {"strategy": "exhaustive", "max_points": 7}}
        )
    )
    assert "search" not in grid


def test_a_plug_in_strategy_says_whether_a_budget_chose_its_points(tmp_path, monkeypatch):
    """The report asks the strategy, not a list of names: a plug-in that walks its own points keeps the
    budget out of the spec shown, as exhaustive does."""
    register(
        monkeypatch,
        tmp_path,
        "corners",
        """
        from dse_runner.sweeps.search import Strategy

        class Corners(Strategy):
            closed_loop = False
            budgeted = False

            def ask(self):
                return None
        """,
        {"dse_runner.search": {"corners": "corners:Corners"}},
    )
    base = {"name": "s", "multimodel": "m.yaml", "parameters": {"a": {"low": 0, "high": 1}}}
    shown = shown_spec(SpaceSpec.model_validate({**base, "search": {"strategy": "corners", "max_points": 7}}))
    assert shown["search"] == {"strategy": "corners"}  # max_points chose nothing


def test_captions_say_what_a_search_draws():
    notes = figure_notes("rmse", ["k", "c"], scattered=True)
    assert "a dot per scenario" in notes["by_parameter"] and "a dot per point" in notes["by_group"]
    assert all("paper" not in note for note in notes.values())
    three = pareto_note([("a", "min"), ("b", "max"), ("c", "min")], "total")
    assert "total b (higher is better)" in three and "all 3 Pareto objectives (a, b, c)" in three


def test_a_track_without_a_recording_has_no_recorded_entry():
    import numpy as np

    from dse_runner.simulation.comparison import Comparison

    chart = charts.TrackChart()
    chart.update(Comparison(None, (np.arange(3.0), np.ones(3)), "time [s]", "level"), "nominal")
    assert [(item.label.value, item.visible) for item in chart.figure.legend[0].items] == [
        ("recorded", False),
        ("simulated", True),
    ]
    chart.update(Comparison((np.arange(2.0), np.ones(2)), (np.arange(3.0), np.ones(3)), "x", "y"), "sin1")
    assert all(item.visible for item in chart.figure.legend[0].items)


def test_a_grids_panels_get_legends_of_one_height():
    """Figure 6's panels, each with its group's scenarios: the same columns and rows, so their plots align."""
    groups = [["sin1", "sin2", "sin3"], ["speed_ramp1", "speed_ramp2", "speed_ramp3"]]
    assert charts.legend_room(groups) == (2, 2)
    assert charts.legend_room([["a"]]) == (1, 1)
    assert re.fullmatch(r"\d+(\.\d+)?pt", charts.title_size(["x" * 200], 300))
