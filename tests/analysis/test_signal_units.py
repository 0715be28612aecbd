"""The pieces of the diagnosis of any model, without a cluster: locate's windows, the noise rule and the
verdict's words (the combination screens: test_screens.py)."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from dse_runner.analysis.diagnose import explain, lookalike, signal_claims, signal_locate
from dse_runner.analysis.diagnose.explain import Candidate
from dse_runner.errors import DseError
from dse_runner.simulation.scenario import Scenario
from dse_runner.simulation.trajectory import Series
from dse_runner.sweeps.fit import FitResult


def _fit(
    label: str, residuals: list[np.ndarray], point: dict[str, float], names=(), jacobian=None
) -> FitResult:
    sse = float(sum(r @ r for r in residuals))
    return FitResult(
        label,
        list(names),
        {n: point[n] for n in names},
        sse,
        sum(map(len, residuals)),
        1,
        True,
        {n: 0.1 for n in names},
        [],
        point,
        jacobian or [np.zeros((len(r), len(names))) for r in residuals],
        residuals,
    )


def test_windows_are_labelled_by_what_the_inputs_do():
    t = np.linspace(0.0, 10.0, 201)
    pushed = Scenario(
        "pushed", inputs={"m.F": Series(np.array([0.0, 2.0, 4.0]), np.array([0.0, 1.0, 0.0]), "hold")}
    )
    edges = signal_locate.windows(t)
    assert len(edges) == signal_locate.WINDOWS + 1
    labels = [signal_locate.activity(pushed, a, b) for a, b in pairwise(edges)]
    assert labels[0] == signal_locate.STEADY and labels[1] == labels[3] == signal_locate.CHANGING
    assert labels[5] == signal_locate.STEADY
    assert signal_locate.activity(Scenario("free"), 0.0, 1.0) == signal_locate.NO_INPUT
    assert len(signal_locate.windows(t[:20])) == 3  # 20 samples hold two windows of at least 8


def test_located_gives_each_window_in_noise_floors_before_and_after():
    t = np.arange(0.0, 10.0, 0.1)
    scenario = Scenario("run")
    before = [signal_locate.Residual("m.x", "run", t, np.where(t < 5.0, 0.04, 0.0))]
    after = [signal_locate.Residual("m.x", "run", t, np.full(t.size, 0.01))]
    found = signal_locate.located(before, after, {"m.x": 0.01}, {"run": scenario})
    first, last = found["windows"][0], found["windows"][-1]
    assert np.isclose(first["floors_before"], 4.0) and np.isclose(last["floors_before"], 0.0)
    assert np.isclose(first["floors_after"], 1.0)
    (whole,) = found["by_scenario"]
    assert np.isclose(whole["floors_before"], np.sqrt(8.0)) and found["worst"][0]["floors_before"] == 4.0


def _candidate(ids, held_out: dict[str, float]) -> Candidate:
    fit = _fit("+".join(ids) or "none", [np.zeros(3)], {})
    return Candidate(tuple(ids), fit, held_out=held_out)


def test_a_member_that_changes_the_fit_by_less_than_the_noise_is_not_claimed():
    none = _candidate((), {"r1": 5.0, "r2": 5.0})
    a = _candidate(("a",), {"r1": 1.2, "r2": 1.2})
    b = _candidate(("b",), {"r1": 4.9, "r2": 4.9})
    both = _candidate(("a", "b"), {"r1": 1.0, "r2": 1.0})  # b adds 1.44 - 1 = 0.44 noise variance: too little
    chosen, dropped = explain.claimed(both, [none, a, b, both], none)
    assert chosen is a and [d.id for d in dropped] == ["b"] and np.isclose(dropped[0].worth, 0.44)
    kept, none_dropped = explain.claimed(a, [none, a, b, both], none)
    assert kept is a and none_dropped == []


def test_a_remaining_error_points_inside_the_fmus_and_says_which_can_take_a_correction():
    chosen = _candidate(("input_gain(p.u)",), {"r": 4.0})
    text = signal_claims.verdict_text(
        explain.PARTIAL, 4.0, chosen, {"plant": "cs", "sensor": "me"}, [], [], 2.0
    )
    assert "co-simulation FMU plant, which cannot be augmented from outside" in text
    assert "model-exchange FMU sensor" in text
    assert "inside" not in signal_claims.verdict_text(
        explain.EXPLAINED, 1.0, chosen, {"plant": "cs"}, [], [], 2.0
    )


def test_look_alikes_are_told_apart_only_where_their_residuals_differ_by_more_than_the_noise():
    t = np.linspace(0.0, 10.0, 201)
    run = Scenario("run")
    chosen = [signal_locate.Residual("m.x", "run", t, np.full(t.size, 0.01))]
    twin = [signal_locate.Residual("m.x", "run", t, np.where(t >= 9.0, 0.03, 0.01))]
    (window,) = signal_claims.telling_windows(chosen, twin, {"m.x": 0.01}, {"run": run})
    assert window["start"] == 9.0 and np.isclose(window["delta_mean_square"], 8.0)
    assert signal_claims.telling_windows(chosen, chosen, {"m.x": 0.01}, {"run": run}) == []
    a = _candidate(("a",), {"r1": 1.0, "r2": 1.0})
    b = _candidate(("b",), {"r1": 1.02, "r2": 1.02})  # within 5 %: alike
    c = _candidate(("c",), {"r1": 2.0, "r2": 2.0})
    both = _candidate(("a", "b"), {"r1": 0.99, "r2": 0.99})  # more, not another explanation
    assert signal_claims.alike(a, [a, b, c, both]) == [b]


def test_a_look_alike_carries_the_engines_llr_with_segments_from_the_inputs():
    """The signal library's twins are weighed by the engine: the LLR in noise units (σ 1), over
    the autocorrelation time, with each sample labelled by what the inputs do in its window; a decisive
    LLR tells the twins apart even where no window differs by a whole noise variance."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 10.0, 401)
    pushed = Scenario(
        "run", inputs={"m.F": Series(np.array([0.0, 6.0, 7.0]), np.array([0.0, 1.0, 0.0]), "hold")}
    )
    noise = rng.normal(0.0, 0.01, t.size)
    bump = np.where((t > 5.0) & (t <= 7.0), 0.007, 0.0)  # a fraction of the noise, where the input steps
    residuals = {
        "a": [signal_locate.Residual("m.x", "run", t, noise)],
        "b": [signal_locate.Residual("m.x", "run", t, noise + bump)],
    }
    a = _candidate(("a",), {"r1": 1.0, "r2": 1.0})
    b = _candidate(("b",), {"r1": 1.02, "r2": 1.02})
    look = signal_claims.weigh(a, b, residuals, {"m.x": 0.01}, {"run": pushed})
    saved = look.to_json()["segment_llr"]
    assert look.telling == [] and look.told_apart  # no window differs by a noise variance; the LLR decides
    assert saved["decision"] == lookalike.DECIDED_BY_LLR and saved["llr"] >= lookalike.DECISIVE
    assert saved["favours"] == saved["chosen"] == "a" and saved["sigma"] == 1.0
    assert saved["autocorrelation_samples"] == pytest.approx(1.0, abs=0.3)
    by = saved["by_segment"]
    assert set(by) == {"changing", "steady"} and by["changing"]["llr"] > 0.9 * saved["llr"]
    assert sum(s["samples"] for s in by.values()) == t.size
    even = signal_claims.weigh(
        a, b, {"a": residuals["a"], "b": residuals["a"]}, {"m.x": 0.01}, {"run": pushed}
    )
    assert even.llr.decision == lookalike.CANNOT_TELL and not even.told_apart
    # the report draws it: the engine's evidence in this library's words, then how alike the two fit
    from dse_runner.analysis.diagnose import answer, report, signal_report
    from dse_runner.analysis.diagnose.signal_library import SignalDiagnosis

    drawn = answer.Answer(
        library="signals",
        verdict="explained",
        verdict_text="a",
        held_out_before=2.0,
        held_out_after=1.0,
        held_out_unit=SignalDiagnosis.held_out_unit,
        noise_floor=answer.NoiseFloor(held_out=1.0, factor=2.0, ratio=1.0, method="samples"),
        effects=[answer.nothing_missing("nothing")],
        runner_up=None,
        candidates=[],
        calibrated=answer.Fitted(parameters={}),
        fitted=answer.Fitted(parameters={}),
        lookalikes=[look.to_json()],
    )
    text = report.lookalikes_part(drawn, signal_report.WORDS)
    assert (
        f"`a` against `b` (swapping `a` for `b`): LLR {saved['llr']:+.1f}, in favour of `a`, mostly on "
        "windows where an input changes" in text
    )
    assert "σ = 1.0000 noise floors" in text and "samples. `b` fits alike (1.02 held-out" in text
    assert "2/2 runs better for the chosen); no window tells them apart by more than the noise.\n" in text
    assert "| segment | samples | LLR (a over b) |" in text and "| windows where the inputs hold |" in text


def test_a_selection_keeps_only_the_named_effects_and_names_an_unknown_one():
    from dse_runner.analysis.diagnose.signal_library import restricted

    found = {"input_delay(msd.F)": "delay", "output_gain(msd.x)": "gain"}
    assert restricted(found, ()) == found
    assert restricted(found, ("output_gain(msd.x)",)) == {"output_gain(msd.x)": "gain"}
    with pytest.raises(
        DseError,
        match=r"--hypothesis input_lag\(msd.F\): not a signal effect of this space; it has "
        r"input_delay\(msd.F\), output_gain\(msd.x\)",
    ):
        restricted(found, ("input_lag(msd.F)",))


def test_a_verdict_made_partial_by_coloured_residuals_does_not_claim_error_above_the_floor():
    chosen = _candidate(("input_rate(p.u)",), {"r": 1.6})
    text = signal_claims.verdict_text(
        explain.unless_white(explain.EXPLAINED, False),
        1.6,
        chosen,
        {"plant": "me"},
        [],
        [],
        2.0,
        coloured={"p.y": _white(0.33, 1e-69)},
    )
    assert text.startswith("partial: input_rate(p.u)") and "residuals of p.y are not white" in text
    assert "more than 2 noise floors remain" not in text
    assert explain.unless_white(explain.NONE, False) == explain.UNEXPLAINED
    assert explain.unless_white(explain.EXPLAINED, True) == explain.EXPLAINED


def _white(rho1: float, p: float):
    from dse_runner.analysis.diagnose.noise import Whiteness

    return Whiteness(rho1, 100.0, p, 10, 800)
