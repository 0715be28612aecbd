"""What held-out means: folds of scenarios, or one record's blocks of time, each a view of the whole run."""

from __future__ import annotations

import numpy as np
from conftest import REPO

from dse_runner.analysis.diagnose.validation import Fold, blocks, complements, validated
from dse_runner.simulation.scenario import Recording, Scenario
from dse_runner.simulation.trajectory import Series
from dse_runner.sweeps.expand import scenario_hash
from dse_runner.sweeps.spec import load_space


def _record(n: int) -> Scenario:
    t = np.arange(n) * 4.0
    y = np.sin(t / 300.0)
    y[7] = np.nan  # a dropout stays a dropout in every view
    return Scenario(
        "estimation",
        inputs={"tanks.u": Series(t, np.ones(n), "hold")},
        recorded=Recording(REPO / "level.csv", t, {"y": y}, missing=1),
        stop_time=float(t[-1]),
    )


def test_one_record_is_cut_into_blocks_and_the_first_is_never_held_out():
    record = _record(1024)
    views = blocks(record, 3, ["y"])
    assert [(train.name, test.name) for train, test in views] == [
        ("estimation~train2", "estimation~block2"),
        ("estimation~train3", "estimation~block3"),
        ("estimation~train4", "estimation~block4"),
    ]
    y = record.recorded.columns["y"]
    kept_by_tests = np.zeros(y.size, dtype=bool)
    for train, test in views:
        seen, judged = np.isfinite(train.recorded.columns["y"]), np.isfinite(test.recorded.columns["y"])
        assert not (seen & judged).any()  # a fold never sees what it is judged on
        assert (seen | judged).sum() == np.isfinite(y).sum()  # and between them they hold the whole record
        assert judged.sum() in (255, 256) and np.all(
            np.diff(np.flatnonzero(judged)) == 1
        )  # one contiguous block
        kept_by_tests |= judged
        assert train.inputs == record.inputs and train.stop_time == record.stop_time  # the same run
    assert (
        not kept_by_tests[:257].any() and kept_by_tests[257:].all()
    )  # the first block (with the dropout): always fitted
    hashes = {scenario_hash(s) for pair in views for s in pair} | {scenario_hash(record)}
    assert len(hashes) == 7  # every view's tasks are its own in the store


def test_a_record_too_short_to_cut_is_judged_in_sample_and_several_scenarios_by_folds():
    space = load_space(REPO / "jobs" / "cascaded_tanks" / "space.yaml")
    assert blocks(_record(20), 3, ["y"]) == []  # 5 samples a block: fewer than 8
    cut, validation = validated(space, 3, ["y"])
    assert validation.by == "time blocks" and validation.fitted == ("estimation",)
    assert [f.test for f in validation.folds] == [
        ("estimation~block2",),
        ("estimation~block3",),
        ("estimation~block4",),
    ]
    assert [s.name for s in cut.scenarios][:2] == ["estimation", "estimation~train2"]
    assert complements([["b"], ["a", "c"]], ["a", "b", "c"]) == [
        Fold(("a", "c"), ("b",)),
        Fold(("b",), ("a", "c")),
    ]
