"""The strategy contract (search.Strategy): every available strategy is one, and a plug-in that has only
``ask`` runs a real search with the defaults of the optional parts (no options, tell ignored)."""

from __future__ import annotations

import pytest
from conftest import write_msd_search
from pydantic import BaseModel
from support.plugins import register

from dse_runner.errors import DseError
from dse_runner.sweeps import search
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit

FIXED = """
from dse_runner.sweeps.search import Strategy

POINTS = [{"msd.k": 10.0, "msd.c": 0.5}, {"msd.k": 14.0, "msd.c": 0.8}, {"msd.k": 20.0, "msd.c": 1.5}]


class Fixed(Strategy):
    '''Three given points, whatever their results.'''

    def __init__(self, problem):
        super().__init__(problem)
        self.left = list(POINTS)

    def ask(self):
        return self.left.pop(0) if self.left else None
"""


def test_every_available_strategy_holds_to_the_contract():
    for name in search.available():
        found = search.strategy(name)
        assert issubclass(found, search.Strategy), name
        assert issubclass(found.Options, BaseModel), name
        assert isinstance(found.closed_loop, bool) and isinstance(found.multi_objective, bool), name


def test_a_strategy_with_only_ask_runs_a_search(tmp_path, monkeypatch, dask_scheduler):
    register(
        monkeypatch,
        tmp_path / "plugin",
        "fixed_strategy_plugin",
        FIXED,
        {"dse_runner.search": {"fixed": "fixed_strategy_plugin:Fixed"}},
    )
    space = load_space(
        write_msd_search(
            tmp_path / "run", {"strategy": "fixed", "max_points": 10}, cluster={"address": dask_scheduler}
        )
    )
    report = submit(space)
    assert (report.search.points, report.search.stopped) == (
        3,
        "strategy",
    )  # None with nothing in flight: done
    assert (report.ok, report.failed) == (3, 0)
    assert report.search.best_point == {"msd.k": 14.0, "msd.c": 0.8}  # the truth is among them

    with pytest.raises(
        DseError, match=r"search\.population: extra inputs are not permitted \(an option of Fixed\)"
    ):
        load_space(write_msd_search(tmp_path / "bad", {"strategy": "fixed", "population": 4}))
