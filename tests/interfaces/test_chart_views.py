"""Views that fit the design: a grid's lines, a sampled design's dots, and above MAX_DOTS rows its binned mean
inside a quantile band, whose size does not grow with the rows."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from dse_runner.interfaces import charts


def sampled(rows: int, seed: int = 0) -> pd.DataFrame:
    """A sampled design's ok rows on two scenarios: y = x^2 plus noise of known spread."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, rows)
    return pd.DataFrame(
        {
            "m.x": np.tile(x, 2),
            "y": np.tile(x**2, 2) + rng.normal(0, 0.1, 2 * rows),
            "scenario": np.repeat(["a", "b"], rows),
            "group": "all",
        }
    )


def test_the_binned_mean_and_band_are_the_rows_statistics_in_each_bin():
    ok = sampled(200_000)
    means, bands = charts.binned(ok, "m.x", "y", {"all": "#000"})
    assert means["scenario"] == ["a", "b"] and len(means["xs"][0]) == charts.BINS
    centres, mean = means["xs"][0], means["ys"][0]
    assert np.allclose(mean, centres**2, atol=0.01)  # the mean of x^2 + noise over a narrow bin
    low, high = bands["ys"][0][: charts.BINS], bands["ys"][0][charts.BINS :][::-1]
    spread = 0.1 * 1.2816  # the noise's 10 % and 90 % quantiles around the mean
    assert np.allclose(high - mean, spread, atol=0.02) and np.allclose(mean - low, spread, atol=0.02)


@pytest.mark.parametrize("rows", [charts.MAX_DOTS // 2 - 1, 10 * charts.MAX_DOTS])
def test_a_sampled_design_draws_dots_up_to_max_dots_and_its_binned_view_above(rows):
    sources = charts._Sources.empty()
    ok = sampled(rows)
    sources.fill(ok, "m.x", "y", {"all": "#000"}, "group", scattered=True)
    drawn = {name: charts.source_rows(getattr(sources, name)) for name in ("dots", "lines", "bands")}
    if 2 * rows <= charts.MAX_DOTS:
        assert drawn == {"dots": 2 * rows, "lines": 0, "bands": 0}
    else:  # a line and a band per scenario, whatever the rows
        assert drawn == {"dots": 0, "lines": 2, "bands": 2}


def test_a_grid_keeps_its_lines_of_means():
    ok = pd.DataFrame(
        {
            "m.x": [0.0, 0.0, 1.0, 1.0],
            "m.z": [0, 1, 0, 1],
            "y": [1.0, 3.0, 5.0, 7.0],
            "scenario": "a",
            "group": "all",
        }
    )
    sources = charts._Sources.empty()
    sources.fill(ok, "m.x", "y", {"all": "#000"}, "group", scattered=False)
    assert sources.lines.data["ys"][0].tolist() == [2.0, 6.0] and charts.source_rows(sources.dots) == 0


def test_point_numbers_follow_the_points_sorted_by_their_values_with_text_values_too():
    """Figure 6's x: each row's point numbered by the points' order (first parameter first), the same number
    for the same point on every scenario."""
    from dse_runner.interfaces.charts import point_index

    ok = pd.DataFrame({"a": [2.0, 1.0, 2.0, 1.0, 2.0], "b": [0.5, 0.7, 0.1, 0.7, 0.5]})
    assert point_index(ok, ["a", "b"]).tolist() == [2.0, 0.0, 1.0, 0.0, 2.0]
    assert point_index(ok, ["b", "a"]).tolist() == [1.0, 2.0, 0.0, 2.0, 1.0]
    text = ok.assign(c=["x", "y", "x", "y", "x"])
    assert point_index(text, ["c", "a"]).tolist() == [0.0, 1.0, 0.0, 1.0, 0.0]
