"""Calibration, as every library starts from it: which parameters least squares refines after the space's own
search, where they start and how far a finite difference steps (analysis/diagnose/calibration.py)."""

from __future__ import annotations

import pytest
from conftest import REPO

from dse_runner.analysis.diagnose.calibration import held_at, parameters_at, searched
from dse_runner.analysis.diagnose.library import space_with
from dse_runner.sweeps.spec import derived_space

MSD = REPO / "jobs" / "msd" / "space.yaml"  # a grid of k (10..18) and c (0.4..1.2)


def test_the_grids_parameters_start_at_its_best_point_bounded_by_its_range(tmp_path):
    space = space_with(MSD, None, tmp_path)
    params = {p.name: p for p in parameters_at(space, {"msd.k": 12.5}, 0.01)}
    assert set(params) == {"msd.k", "msd.c"}
    k, c = params["msd.k"], params["msd.c"]
    assert (k.start, k.lower, k.upper) == (12.5, 10.0, 18.0)
    assert k.step == pytest.approx(0.08)  # a hundredth of the range
    assert c.start == pytest.approx(0.8)  # no best value: the middle of its range


def test_a_single_value_and_a_whole_number_are_not_refined(tmp_path):
    """A parameter held at one value stays held; a whole-numbered one is a choice, not for least squares."""
    from dse_runner.sweeps.domain import Interval

    space = derived_space(
        space_with(MSD, None, tmp_path),
        parameters={"msd.k": [14.0], "msd.c": Interval(low=1, high=4, integer=True)},
    )
    assert parameters_at(space, {}, 0.01) == ()
    # held where the search put them, not at the low end of the range; the one value where it set nothing
    assert held_at(space, {"msd.c": 3.0}) == {"msd.k": 14.0, "msd.c": 3.0}
    assert held_at(space, {}) == {"msd.k": 14.0, "msd.c": 1.0}


def test_points_given_as_they_are_search_nothing(tmp_path):
    space = space_with(MSD, None, tmp_path)
    given = derived_space(space, search=space.spec.search.model_copy(update={"strategy": "given"}))
    said = []
    assert searched(given, None, said.append) is None and not said
