"""Fast unit tests of the diagnosis' pure parts, no simulation: the noise floor estimated from
synthetic fixes written here, and the verdict, partial flag and runner-up on constructed candidates."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from conftest import strict_loads

from dse_runner import strict_json
from dse_runner.analysis.diagnose import discovery, explain, response
from dse_runner.analysis.diagnose import lookalike as engine_lookalike
from dse_runner.analysis.diagnose.explain import Candidate
from dse_runner.analysis.diagnose.lookalike import SegmentEvidence
from dse_runner.analysis.diagnose.response import ResponseFit
from dse_runner.analysis.diagnose.screens import ScreenSettings, linearised
from dse_runner.cases.fielddata import load_run
from dse_runner.cases.robotti_diagnosis import (
    Diagnosis,
    DiagnosisSettings,
    kinematics,
    lookalike,
    noise,
    segments,
)
from dse_runner.cases.robotti_diagnosis.chain import VehicleEffect
from dse_runner.cases.robotti_diagnosis.hypotheses import LIBRARY, LOOK_ALIKES
from dse_runner.errors import DseError
from dse_runner.sweeps.fit import FitProblem, FitResult, LevenbergMarquardt, Parameter

PERIOD = 0.1  # s between fixes, as the bundled receiver


def commands(duration: float, rest_start: float, rest_end: float) -> tuple[np.ndarray, np.ndarray]:
    """A 20 Hz speed log: standing, then driving at 1.5 m/s, then standing for the last ``rest_end`` s."""
    t = np.round(np.arange(0.0, duration + 1e-9, 0.05), 2)
    v = np.where((t >= rest_start) & (t < duration - rest_end), 1.5, 0.0)
    return t, v


def truth(t: np.ndarray, cmd_t: np.ndarray, cmd_v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The path: a circle of 12 m radius (0.19 m/s² of lateral acceleration) at the commanded speed."""
    v = np.interp(t, cmd_t, cmd_v)  # stops are exact: no motion at all while the command is 0
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    return 12.0 * np.sin(s / 12.0), 12.0 * (1 - np.cos(s / 12.0))


def write_run(
    folder: Path,
    name: str,
    sigma: float,
    seed: int,
    dropout: float = 0.1,
    outage: float = 5.0,
    duration: float = 60.0,
    rest_start: float = 2.0,
    rest_end: float = 6.0,
    colour: float = 0.0,
    creep: float = 0.0,
) -> Path:
    """A run in the field-data format: noisy fixes at 10 Hz with random dropouts and one outage.
    ``colour`` makes the noise AR(1) with that coefficient (same marginal σ); ``creep`` [m/s] moves the
    vehicle along x while its speed command is 0, as a slope does against the drive's hold."""
    rng = np.random.default_rng(seed)
    run = folder / name
    run.mkdir(parents=True)
    cmd_t, cmd_v = commands(duration, rest_start, rest_end)
    (run / "steering_inputs.csv").write_text(
        "time,velocity,delta_f\n" + "".join(f"{t:.2f},{v:.3f},0.0000\n" for t, v in zip(cmd_t, cmd_v))
    )
    (run / "scenario.yaml").write_text(
        yaml.safe_dump(
            {
                "name": name,
                "group": "synthetic",
                "duration": duration,
                "initial_pose": {"x": 0.0, "y": 0.0, "theta": 0.0},
            }
        )
    )
    t = np.round(np.arange(0.0, duration + 1e-9, PERIOD), 2)
    x, y = truth(t, cmd_t, cmd_v)
    still = np.interp(t, cmd_t, cmd_v) == 0
    x = x + creep * np.concatenate([[0.0], np.cumsum(still[1:] * np.diff(t))])
    white = rng.normal(0.0, sigma, (2, t.size))
    if colour:
        noise_xy = np.empty_like(white)
        noise_xy[:, 0] = white[:, 0]
        for k in range(1, t.size):
            noise_xy[:, k] = colour * noise_xy[:, k - 1] + math.sqrt(1 - colour**2) * white[:, k]
        white = noise_xy
    keep = rng.random(t.size) >= dropout
    start = int(rng.integers(t.size // 4, t.size // 2))
    keep[start : start + round(outage / PERIOD)] = False
    keep[0] = True
    rows = []
    for k in range(t.size):  # a dropout is a missing row or an empty row: both occur in the field
        if keep[k]:
            rows.append(f"{t[k]:.2f},{x[k] + white[0, k]:.4f},{y[k] + white[1, k]:.4f}")
        elif k % 2:
            rows.append(f"{t[k]:.2f},,")
    (run / "gps_position.csv").write_text("time,x,y\n" + "\n".join(rows) + "\n")
    return run


def scenarios(folder: Path, sigma: float, runs: int = 4, **options) -> list:
    return [
        load_run(write_run(folder, f"run{k}", sigma, seed=100 * k + int(sigma * 1000), **options))
        for k in range(runs)
    ]


@pytest.mark.parametrize("sigma", [0.02, 0.05])
def test_noise_is_recovered_from_fixes_with_dropouts_and_an_outage(tmp_path, sigma):
    floor = noise.estimate_noise(scenarios(tmp_path, sigma))
    assert floor.available
    assert floor.sigma == pytest.approx(sigma, rel=0.10)
    for method in (noise.CLOSE_FIXES, noise.AT_REST):  # each estimator alone, too
        assert floor.estimates[method].sigma == pytest.approx(sigma, rel=0.10), method
    assert floor.cross_track == pytest.approx(floor.sigma * math.sqrt(math.pi / 2))
    assert floor.method in (noise.CLOSE_FIXES, noise.AT_REST)
    assert floor.fixes == floor.estimates[floor.method].fixes > 0
    assert sorted(floor.per_run) == ["run0", "run1", "run2", "run3"]
    assert all(v == pytest.approx(sigma, rel=0.25) for v in floor.per_run.values())
    assert abs(floor.rho1) < 0.3  # white


def test_heavy_noise_with_long_outages(tmp_path):
    """5 cm, 10 % dropouts and a 10 s outage per run, only 2 s of rest at the start and none at the end."""
    floor = noise.estimate_noise(scenarios(tmp_path, 0.05, outage=10.0, rest_end=0.0))
    assert floor.sigma == pytest.approx(0.05, rel=0.10)


def test_coloured_noise_is_caught_at_rest(tmp_path):
    """Second differences cancel slowly wandering noise; the spread at rest does not, and decides."""
    floor = noise.estimate_noise(scenarios(tmp_path, 0.03, colour=0.8, rest_start=5.0, rest_end=10.0))
    assert floor.estimates[noise.CLOSE_FIXES].sigma < 0.75 * 0.03
    assert floor.method == noise.AT_REST
    assert floor.rho1 > 0.3
    assert floor.sigma == pytest.approx(0.03, rel=0.2)


def test_a_vehicle_creeping_while_commanded_to_stop_is_not_counted_as_noise(tmp_path):
    """On a slope the vehicle creeps while its speed command is 0: the spread at rest is taken about a
    straight line in time, or 4 cm/s of creep over 6 s would triple the noise."""
    floor = noise.estimate_noise(scenarios(tmp_path, 0.02, creep=0.04))
    assert floor.estimates[noise.AT_REST].sigma == pytest.approx(0.02, rel=0.10)
    assert floor.sigma == pytest.approx(0.02, rel=0.10)


def test_second_differences_skip_triples_across_a_dropout():
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.5, 0.6, 0.7])  # 0.4 missing
    x = np.array([0.0, 0.0, 0.0, 0.0, 9.0, 9.0, 9.0])  # a jump hidden in the gap must not show
    d2 = noise.second_differences(t, x, np.zeros_like(x))
    assert d2.size == 2 * 3  # middles at 0.1, 0.2 and 0.6, for x and y
    assert np.all(d2 == 0)
    assert noise.second_differences(t[:2], x[:2], x[:2]).size == 0
    slow = np.arange(0.0, 5.0, 0.5)  # fixes 0.5 s apart: motion would leak in, so none are used
    assert noise.second_differences(slow, slow, slow).size == 0


def test_rest_windows():
    t = np.round(np.arange(0.0, 20.0, 0.05), 2)
    v = np.where((t >= 1.0) & (t < 10.0), 1.0, 0.0)  # 1 s at rest first: too short
    v[(t >= 12.0) & (t < 13.0)] = 1.0  # a 2 s stop from 10 to 12 s
    windows = noise.rest_windows(t, v, end=20.0)
    assert windows == [(pytest.approx(10.5), pytest.approx(12.0)), (pytest.approx(13.5), pytest.approx(20.0))]
    assert noise.rest_windows(t, np.zeros_like(t), end=20.0) == [
        (0.0, 20.0)
    ]  # at rest from the start: no settling


def test_no_estimate_without_usable_fixes():
    run = noise.RecordedRun(np.array([0.0, 1.0]), np.zeros(2), np.zeros(2), np.array([0.0]), np.array([1.0]))
    floor = noise.estimate({"a": run})
    assert not floor.available and floor.method == noise.UNAVAILABLE
    assert strict_loads(strict_json.dumps(floor.to_json()))["sigma"] is None


# ---- verdicts, partial and runner-up on constructed candidates ---------------------------------------


@pytest.mark.parametrize(
    "held_out, floor, chosen, expected",
    [
        (0.03, 0.02, False, "none"),
        (0.05, 0.02, False, "unexplained"),
        (0.04, 0.02, True, "explained"),  # exactly at 2x: still noise
        (0.041, 0.02, True, "partial"),
        (0.5, None, True, "explained"),  # no floor: claim no more than the library's rule
        (0.5, None, False, "none"),
    ],
)
def test_verdict(held_out, floor, chosen, expected):
    assert explain.verdict(held_out, floor, 2.0, chosen) == expected


@pytest.mark.parametrize("chosen", [False, True])
def test_a_discovered_correction_is_the_answer_only_down_to_the_noise(chosen):
    """A correction that passed the rule but leaves a residual above the noise
    is part of the cause: partial."""
    assert explain.verdict(0.04, 0.02, 2.0, chosen, discovered=True) == "discovered"
    assert explain.verdict(0.041, 0.02, 2.0, chosen, discovered=True) == "partial"


def candidate(
    ids: tuple[str, ...], held_out: list[float], sse: float, values: dict[str, float] | None = None
) -> Candidate:
    names = ["vehicle.mass", *(values or {})]
    allv = {"vehicle.mass": 1800.0, **(values or {})}
    fit = FitResult(
        "+".join(ids) or "none", names, allv, sse, 1000, 5, True, {n: 0.001 for n in names}, [], {}
    )
    return Candidate(ids, fit, held_out={f"run{k}": v for k, v in enumerate(held_out)})


def table() -> list[Candidate]:
    return explain.ranked(
        [
            candidate((), [1.0, 1.2, 0.9, 1.1], 400.0),
            candidate(("wheel_slip",), [0.12, 0.13, 0.11, 0.12], 20.0, {"vehicle.wheel_slip": 0.08}),
            candidate(("time_offset",), [0.30, 0.35, 0.10, 0.31], 60.0, {"vehicle.time_offset": 0.3}),
            candidate(
                ("wheel_slip", "antenna_offset"),
                [0.118, 0.129, 0.112, 0.119],
                19.0,
                {"vehicle.wheel_slip": 0.08, "vehicle.antenna_x": 0.01, "vehicle.antenna_y": 0.0},
            ),
        ]
    )


def test_runner_up_is_the_best_candidate_that_is_no_subset_of_the_chosen():
    cands = table()
    slip = next(c for c in cands if c.ids == ("wheel_slip",))
    up = explain.runner_up(slip, cands)
    assert up.ids == ("wheel_slip", "antenna_offset")  # ranked first of the rest; none is a subset
    pair = next(c for c in cands if len(c.ids) == 2)
    assert explain.runner_up(pair, cands).ids == ("time_offset",)  # wheel_slip alone is part of the pair
    baseline = next(c for c in cands if not c.ids)
    assert explain.runner_up(baseline, cands).ids == ("wheel_slip", "antenna_offset")
    assert explain.runner_up(slip, [slip, baseline]) is None


def test_evidence():
    cands = table()
    slip = next(c for c in cands if c.ids == ("wheel_slip",))
    other = next(c for c in cands if c.ids == ("time_offset",))
    e = explain.evidence(slip, other)
    assert e.other == "time_offset"
    assert e.delta_held_out == pytest.approx(0.265 - 0.12)
    assert e.delta_held_out_percent == pytest.approx(100 * (0.265 - 0.12) / 0.12)
    assert e.delta_bic == pytest.approx(other.bic - slip.bic) and e.delta_bic > 0
    assert e.runs_better_text == "3/4"  # run2: time_offset predicts 0.10 against 0.11


def diagnosis(chosen_ids: tuple[str, ...], floor: float, factor: float = 2.0) -> Diagnosis:
    cands = table()
    chosen = next(c for c in cands if c.ids == chosen_ids)
    baseline = next(c for c in cands if not c.ids)
    sigma = floor / noise.MEAN_DISTANCE
    nf = noise.NoiseFloor(
        sigma,
        floor,
        noise.CLOSE_FIXES,
        5000,
        {"run0": sigma},
        {noise.CLOSE_FIXES: noise.Estimate(sigma, 5000)},
        0.02,
    )
    return Diagnosis(
        Path("/nowhere"),
        {"vehicle": "vehicle"},
        DiagnosisSettings(noise_factor=factor),
        baseline=baseline,
        chosen=chosen,
        candidates=cands,
        floor=nf,
    )


def test_json_verdict_partial_and_runner_up():
    from dse_runner.analysis.diagnose.answer import Answer

    explained = strict_loads(strict_json.dumps(diagnosis(("wheel_slip",), floor=0.1).to_json()))
    assert explained["verdict"] == "explained"
    assert [e["partial"] for e in explained["effects"]] == [False]
    assert explained["held_out_after"] == pytest.approx(0.12)
    floor = explained["noise_floor"]
    assert (floor["held_out"], floor["factor"], floor["ratio"], floor["method"]) == (
        0.1,
        2.0,
        pytest.approx(1.2),
        "close_fixes",
    )
    assert floor["details"] | {"per_run": None, "estimates": None} == {
        "sigma": pytest.approx(0.1 / noise.MEAN_DISTANCE),
        "cross_track": 0.1,
        "method": "close_fixes",
        "fixes": 5000,
        "rho1": 0.02,
        "per_run": None,
        "estimates": None,
    }
    assert explained["runner_up"]["id"] == "wheel_slip+antenna_offset"
    assert explained["runner_up"]["runs_better"] == "1/4"  # run2 only: the pair is a hair better elsewhere
    assert explained["runner_up"]["delta_held_out"] < 0

    partial = diagnosis(("wheel_slip",), floor=0.025).to_json()
    assert partial["verdict"] == "partial" and partial["effects"][0]["partial"] is True
    assert diagnosis(("wheel_slip",), floor=0.025, factor=5.0).to_json()["verdict"] == "explained"

    unexplained = diagnosis((), floor=0.025).to_json()
    assert unexplained["verdict"] == "unexplained"
    (none,) = unexplained["effects"]
    assert (none["id"], none["parameters"], none["interval"], none["partial"]) == ("none", {}, {}, False)
    # one shape for every library: the same keys as the signal library's answer, the case's own under "case"
    assert set(unexplained) == set(Answer.model_fields)
    assert Answer.model_validate(unexplained).case["dropouts"] == {}


def test_report_words(tmp_path):
    """The verdict in an engineer's words (the answer's verdict_text, as the report shows it), the runner-up's
    evidence and the GPS noise floor."""
    from dse_runner.analysis.diagnose import report as page
    from dse_runner.cases.robotti_diagnosis import report

    text = page.verdict(diagnosis(("wheel_slip",), floor=0.025).answer())
    assert "**Verdict: partial.**" in text and "does not explain the residual" in text and "4.8×" in text
    assert "caused by" not in text
    d = diagnosis(("wheel_slip",), floor=0.1)
    assert "**Verdict: explained.** With `wheel_slip` the held-out error" in page.verdict(d.answer())
    words = page.runner_up(d.answer().runner_up, "m")
    assert "overstates" in words and "did not pass the rule" in words and "1/4" in words
    assert "0.100 m" in report.noise_text(d.answer())


def test_a_bad_noise_factor_is_refused():
    with pytest.raises(DseError, match="noise factor"):
        DiagnosisSettings(noise_factor=0.0)
    with pytest.raises(DseError, match="pairs = -1"):
        DiagnosisSettings(pairs=-1)
    with pytest.raises(DseError, match="floor stop"):
        DiagnosisSettings(floor_stop=float("nan"))


def test_an_effect_fitted_to_nothing_ties_rather_than_wins_runs():
    """A superset whose extra effect is fitted to ~0 predicts the same: its runs are ties, not evidence."""
    chosen = candidate(("wheel_slip",), [0.12, 0.13, 0.11, 0.12], 20.0)
    same = candidate(("wheel_slip", "time_offset"), [0.12 + 1e-11, 0.13 - 1e-11, 0.11, 0.12 + 2e-4], 19.9)
    e = explain.evidence(chosen, same)
    assert (e.runs_better, e.runs_tied, e.runs) == (1, 3, 4)
    assert e.to_json()["runs_tied"] == 3


# ---- the screen and the selection --------------------------------------------------------------------------

BASE = (
    Parameter("vehicle.mass", 2400.0, 1000.0, 3000.0, 20.0),
    Parameter("vehicle.cAlphaF", 30000.0, 20000.0, 38000.0, 180.0),
)
SCREENED = ("wheel_slip", "steering_lag", "speed_lag", "steering_offset", "time_offset")
TRUTH = {
    "vehicle.mass": 1800.0,
    "vehicle.cAlphaF": 26000.0,
    "vehicle.wheel_slip": 0.08,
    "vehicle.steering_lag": 0.4,
}


def masked_residuals(runs: int = 3, fixes: int = 150, seed: int = 7):
    """Residuals linear in every parameter, for ``runs`` runs of ``fixes`` fixes (x offsets then y offsets),
    in which slip and a steering lag mask each other: each one's signature is mostly a large common part ``w``
    that the other cancels, so either alone explains almost nothing, and both together explain it all.
    Returns the residual function (fit.Residuals) and the scenario names."""
    rng = np.random.default_rng(seed)
    rows = 2 * fixes
    names = [p.name for p in BASE] + [f"vehicle.{v}" for h in SCREENED for v in LIBRARY[h].variables]
    columns = {}
    for s in range(runs):
        w, e1, e2 = rng.normal(0, 1.0, rows), rng.normal(0, 0.05, rows), rng.normal(0, 0.05, rows)
        per_unit = {n: rng.normal(0, 1.0, rows) / 1000 for n in names}  # m per unit: mass, cAlphaF alike
        per_unit["vehicle.cAlphaF"] = rng.normal(0, 1.0, rows) / 8000
        per_unit["vehicle.wheel_slip"] = (w + e1) / TRUTH["vehicle.wheel_slip"]
        per_unit["vehicle.steering_lag"] = (-w + e2) / TRUTH["vehicle.steering_lag"]
        columns[f"run{s}"] = (np.column_stack([per_unit[n] for n in names]), rng.normal(0, 0.02, rows))

    def residuals(point: dict[str, float], scenario: str) -> np.ndarray:
        jacobian, noise_ = columns[scenario]
        offset = np.array([point.get(n, 0.0) - TRUTH.get(n, 0.0) for n in names])
        return jacobian @ offset + noise_

    return residuals, tuple(columns), names


def fitted(ids: tuple[str, ...], residuals, scenarios) -> FitResult:
    """A real Levenberg-Marquardt fit (fit.py's ask/tell machine), told the synthetic residuals."""
    params = BASE + tuple(
        Parameter(f"vehicle.{p.variable}", 0.0, p.lower, p.upper, p.step)
        for h in ids
        for p in LIBRARY[h].parameters
    )
    fixed = {f"vehicle.{v}": 0.0 for h in SCREENED for v in LIBRARY[h].variables if h not in ids}
    solver = LevenbergMarquardt(FitProblem("+".join(ids) or "none", params, fixed, scenarios, 30))
    while not solver.done:
        solver.ask()
        solver.tell(residuals)
    return solver.result()


@dataclass
class Synthetic:
    """What a screen reads of the engine's fits (engine.Fits): the vehicle's library, synthetic residuals."""

    residuals: Any
    scenarios: tuple[str, ...]
    ids: tuple[str, ...] = SCREENED
    base: tuple[Parameter, ...] = BASE
    asked: list[int] = field(default_factory=list)  # points per sweep
    look_alikes: Any = field(default_factory=lambda: LOOK_ALIKES)

    @property
    def library(self) -> dict[str, VehicleEffect]:
        return {h: VehicleEffect.of("vehicle", h) for h in self.ids}

    def shares(self, a: str, b: str) -> bool:
        return False

    def evaluate(self, points):
        self.asked.append(len(points))
        return self.residuals


def test_the_screen_finds_a_masked_pair_neither_effect_of_which_passes_alone():
    residuals, scenarios, _ = masked_residuals()
    fits = {ids: fitted(ids, residuals, scenarios) for ids in [(), *((h,) for h in SCREENED)]}
    none = fits[()]
    for hid in ("wheel_slip", "steering_lag"):  # masked: neither passes the BIC half of the gate alone
        assert explain.bic(fits[(hid,)]) > explain.bic(none) - explain.BIC_MARGIN
    # the fit exposes its final Jacobian: on linear residuals, exactly the model's columns
    assert len(none.jacobian) == len(scenarios) and none.jacobian[0].shape == (300, len(BASE))
    moved = dict(none.point, **{"vehicle.mass": none.point["vehicle.mass"] + 1.0})
    assert np.allclose(
        none.jacobian[0][:, 0], residuals(moved, scenarios[0]) - residuals(none.point, scenarios[0])
    )
    assert np.allclose(np.concatenate(none.residuals) @ np.concatenate(none.residuals), none.sse)

    chain = Synthetic(residuals, scenarios)
    found = linearised.Linearised().run(chain, fits, ScreenSettings(pairs=4, triples=2, limit=10))
    seen, short = found.screened, found.shortlist
    entries = linearised.catalogue(chain, SCREENED)
    assert len(chain.asked) == 2  # one sweep of probes, one of trials
    assert chain.asked[0] == sum(
        len(linearised.extra_parameters(a, entries)) for a in linearised.anchors(fits)
    )
    assert {x.ids for x in seen if len(x.ids) == 2} == set(linearised.pairs_of(SCREENED))  # every pair
    best = seen[0]
    assert best.ids == ("wheel_slip", "steering_lag")
    assert best.sse == pytest.approx(
        best.predicted_sse, rel=1e-6
    )  # linear: the check confirms the prediction
    assert best.start["vehicle.wheel_slip"] == pytest.approx(0.08, rel=0.02)
    assert best.start["vehicle.steering_lag"] == pytest.approx(0.4, rel=0.02)
    assert best.sse < 0.2 * none.sse and best.bic < explain.bic(none) - explain.BIC_MARGIN
    labels = [x.label for x in short]
    assert labels[0] == "wheel_slip+steering_lag" and len(short) <= 10
    assert "wheel_slip+time_offset" in labels  # the lag's look-alike is fitted beside it
    assert all(x in short for x in [x for x in seen if len(x.ids) == 3][:2])  # the two best triples


def test_the_prediction_keeps_to_the_bounds():
    residuals, scenarios, _ = masked_residuals(seed=3)
    fits = {ids: fitted(ids, residuals, scenarios) for ids in [(), ("wheel_slip",)]}
    entries = linearised.catalogue(Synthetic(residuals, scenarios), ("wheel_slip", "steering_lag"))
    lin = linearised.linearise(linearised.Anchor((), fits[()]), entries, scenarios, residuals)
    negative = dict(lin.point, **{"vehicle.wheel_slip": 0.0})
    flipped = linearised.Linearisation(
        lin.anchor, negative, lin.names, lin.owners, -lin.jacobian, lin.residuals
    )
    delta, _ = linearised.predict(flipped, ("wheel_slip", "steering_lag"), entries)
    assert (
        delta["vehicle.wheel_slip"] >= 0.0 and delta["vehicle.steering_lag"] >= 0.0
    )  # slip and lag are >= 0
    assert all(entries[n][1].lower <= lin.point[n] + d <= entries[n][1].upper for n, d in delta.items())


def test_select_demands_that_every_member_pays_its_way():
    none = candidate((), [1.0, 1.0, 1.0, 1.0], 400.0)
    slip = candidate(("wheel_slip",), [0.98, 0.99, 0.97, 0.99], 399.0)  # masked: fails alone
    lag = candidate(("steering_lag",), [0.99, 1.0, 0.98, 0.97], 398.0)
    pair = candidate(("wheel_slip", "steering_lag"), [0.03, 0.03, 0.02, 0.03], 5.0)
    triple = candidate(("wheel_slip", "steering_lag", "time_offset"), [0.029, 0.03, 0.02, 0.029], 4.9)
    cands = [none, slip, lag, pair, triple]
    assert not explain.beats(slip, none) and not explain.beats(lag, none)
    assert explain.select(cands, none) is pair  # the triple's extra member does not pay its way
    assert explain.beats_subsets(pair, cands) and not explain.beats_subsets(triple, cands)
    assert explain.select([none, slip, lag], none) is none
    other = candidate(("time_offset",), [0.031, 0.031, 0.021, 0.031], 6.0)  # within 5 %: fewer effects win
    assert explain.select([*cands, other], none) is other
    unvalidated = candidate(("antenna_offset",), [], 1.0)  # fitted on every run only: never the answer
    assert explain.select([none, unvalidated], none) is none
    assert explain.runner_up(pair, [*cands, unvalidated]).ids == triple.ids


def test_the_bic_gate_and_the_order_of_effects():
    none = candidate((), [1.0, 1.0, 1.0, 1.0], 400.0)
    slip = candidate(("wheel_slip",), [0.5, 0.5, 0.5, 0.5], 100.0)
    lag = candidate(("steering_lag",), [0.9, 0.9, 0.9, 0.9], 300.0)
    pair = candidate(("wheel_slip", "steering_lag"), [], 5.0)
    weak = candidate(("wheel_slip", "time_offset"), [], 99.9)  # no better than slip alone
    gated = explain.bic_gate([pair, weak], [none, slip, lag, pair, weak], slip, explain.BIC_MARGIN, 3)
    assert gated == [pair]
    assert explain.bic_gate([pair], [none, slip, lag, pair], slip, explain.BIC_MARGIN, 0) == []
    pair.held_out.update({f"run{k}": 0.03 for k in range(4)})
    assert explain.removal_order(pair, [none, slip, lag, pair]) == ("wheel_slip", "steering_lag")
    swapped = candidate(("steering_lag", "wheel_slip"), [0.03] * 4, 5.0)
    assert explain.removal_order(swapped, [none, slip, lag, swapped]) == ("wheel_slip", "steering_lag")


def test_fitted_error_is_equation_1_on_the_fitted_runs():
    from dse_runner.cases.robotti_diagnosis.chain import fitted_error

    fit = FitResult(
        "x",
        [],
        {},
        0.0,
        4,
        1,
        True,
        {},
        [],
        {},
        residuals=[np.array([3.0, 0.0, 4.0, 1.0]), np.array([0.0, 2.0])],
    )
    assert fitted_error(fit) == pytest.approx(((5.0 + 1.0) / 2 + 2.0) / 2)


def test_the_stop_rule_screens_only_when_a_fit_leaves_more_than_noise():
    """The engine's stop rule (choice.unscreened) with the Robotti's in-sample error, Equation 1 from the
    fix residuals: combinations are screened only while every single leaves more than 1.25 floors."""
    from types import SimpleNamespace

    from dse_runner.analysis.diagnose.choice import unscreened
    from dse_runner.cases.robotti_diagnosis.chain import fitted_error

    def fitted_to(error: float) -> FitResult:  # every fix off by ``error`` along x
        return FitResult(
            "x", [], {}, 0.0, 4, 1, True, {}, [], {}, residuals=[np.array([error, error, 0.0, 0.0])]
        )

    chain = SimpleNamespace(in_sample=fitted_error)
    floor, stop = 0.025, DiagnosisSettings().floor_stop

    def singles(*errors: float) -> dict:
        return {(): fitted_to(1.0), **{(f"h{k}",): fitted_to(e) for k, e in enumerate(errors)}}

    assert unscreened(chain, singles(0.09, 1.2 * floor), floor, stop, 6)
    assert unscreened(chain, singles(0.09, 1.3 * floor), floor, stop, 6) == ""
    assert unscreened(chain, singles(0.0, 0.0), None, stop, 6) == ""  # no floor: nothing to stop at
    assert unscreened(chain, singles(0.09, 0.09), floor, stop, 1)  # one effect at a time
    assert unscreened(chain, singles(0.09), floor, stop, 6)  # one hypothesis offered


# ---- look-alikes: segments, kinematics, the LLR between twins, response fits -------------------------


def command_log() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 20 Hz log with one of each kind: standing, a speed step, a steering step and back, a steering ramp
    to a held turn, a speed ramp, cruising."""
    t = np.round(np.arange(0.0, 40.0 + 1e-9, 0.05), 2)
    speed = np.where(t >= 1.0, 1.2, 0.0) + np.clip((t - 25.0) / 5.0, 0.0, 1.0) * 0.8
    steering = np.where((t >= 5.0) & (t < 10.0), 0.1, 0.0) + np.clip((t - 15.0) / 5.0, 0.0, 1.0) * 0.1
    steering = np.where(t >= 25.0, 0.0, steering)  # straightened in one step at 25 s
    return t, speed, steering


@pytest.mark.parametrize(
    "time, kind",
    [
        (0.5, "rest"),
        (2.0, "speed_step"),
        (4.5, "cruise"),
        (6.0, "steer_step"),
        (9.0, "steer_hold"),
        (11.0, "steer_step"),
        (14.0, "cruise"),
        (17.0, "steer_ramp"),
        (24.0, "steer_hold"),
        (26.0, "steer_step"),
        (29.0, "speed_ramp"),
        (38.0, "cruise"),
    ],
)
def test_segments_come_from_the_command_log(time, kind):
    t, speed, steering = command_log()
    table = segments.command_segments(t, speed, steering)
    assert segments.kinds_at(table, np.array([time]))[0] == kind
    assert np.allclose(table["start"].to_numpy()[1:], table["end"].to_numpy()[:-1])  # a partition of the run
    assert table["end"].iloc[-1] == pytest.approx(t[-1])


def test_a_fast_sine_is_a_ramp_not_a_step():
    t = np.round(np.arange(0.0, 60.0 + 1e-9, 0.05), 2)
    table = segments.command_segments(t, np.full(t.size, 1.5), 0.32 * np.sin(2 * np.pi * t / 20.0))
    kinds = set(table["kind"])
    assert "steer_step" not in kinds and "steer_ramp" in kinds


def test_kinematics_recover_speed_and_yaw_rate_through_noise_and_dropouts():
    rng = np.random.default_rng(5)
    t = np.round(np.arange(0.0, 60.0, PERIOD), 2)
    keep = rng.random(t.size) >= 0.1
    keep[(t >= 20.0) & (t < 25.0)] = False  # a 5 s outage
    t = t[keep]
    speed, radius = 1.5, 12.0
    x = radius * np.sin(speed * t / radius) + rng.normal(0, 0.02, t.size)
    y = radius * (1 - np.cos(speed * t / radius)) + rng.normal(0, 0.02, t.size)
    kin = kinematics.gps_kinematics(t, x, y)
    assert np.nanmedian(np.abs(kin.speed - speed)) < 0.03
    assert np.nanmean(kin.yaw_rate) == pytest.approx(speed / radius, abs=0.01)
    assert np.nanmean(kin.acceleration) == pytest.approx(0.0, abs=0.01)
    assert np.isnan(kin.speed[(t > 19.8) & (t < 25.2)]).all()  # nothing invented across the outage
    assert np.isfinite(kin.speed).mean() > 0.8


def test_a_derivative_operator_is_made_afresh_from_the_windows_it_keeps():
    """The operators of one run's fix times are asked for at every reference point: their windows' fits are
    kept, and each call lays out a new matrix, so a caller that writes into one changes no later estimate."""
    t = np.round(np.arange(0.0, 30.0, PERIOD), 2)
    t = t[(t < 10.0) | (t >= 14.0)]  # an outage: rows without a window are NaN
    first = kinematics.derivative_operator(t, kinematics.ACCELERATION_WINDOW, 2, 2)
    kinematics._windows.cache_clear()  # the same as the windows fitted anew
    fresh = kinematics.derivative_operator(t, kinematics.ACCELERATION_WINDOW, 2, 2)
    assert np.array_equal(first, fresh, equal_nan=True)
    assert np.isnan(first[np.searchsorted(t, 10.0) - 1]).all() and np.isfinite(first[len(t) // 4]).all()
    first[:] = 0.0
    again = kinematics.derivative_operator(t, kinematics.ACCELERATION_WINDOW, 2, 2)
    x = 0.5 * t**2  # a constant acceleration of 1: its second derivative wherever there is a window
    assert np.nanmax(np.abs(again @ x - 1.0)) < 1e-9 and np.isnan(again @ x).any()


def speed_channel(form: str, size: float, seed: int) -> lookalike.SignalAtFixes:
    """Recorded speed = the model's speed steps through a delay or a lag of
    ``size`` s, as GPS would show it."""
    t, speed, steering = command_log()
    truth = response.delayed(t, speed, size) if form == "delay" else response.lagged(t, speed, size)
    rng = np.random.default_rng(seed)
    fixes = np.round(np.arange(0.0, 40.0, PERIOD), 2)
    fixes = fixes[rng.random(fixes.size) >= 0.05]
    operator = kinematics.derivative_operator(fixes, kinematics.VELOCITY_WINDOW, 1, 1)
    recorded = kinematics.smoothed_like(operator, 1, t, truth, fixes) + rng.normal(0, 0.005, fixes.size)
    kinds = segments.kinds_at(segments.command_segments(t, speed, steering), fixes)
    return lookalike.SignalAtFixes(fixes, recorded, kinds, operator, 1, t, speed)


@pytest.mark.parametrize("form", ["delay", "lag"])
def test_the_response_fit_tells_a_delay_from_a_lag_through_the_gps_window(form):
    """The engine's response fit (tests/analysis/test_response.py) on the Robotti's channel: the model's
    speed seen through the same kinematics window as the fixes' (SignalAtFixes.seen), so the window's own
    smoothing is not mistaken for a lag."""
    channel = speed_channel(form, 0.5, 1)
    fits = {r.kind: r for r in response.response_fit([channel], lookalike.SPEED, lookalike.MOVING_KINDS)}
    step = fits["speed_step"]
    assert step.best == form
    assert (step.delay if form == "delay" else step.lag) == pytest.approx(0.5, abs=0.05)
    assert step.gain_sse > min(step.delay_sse, step.lag_sse)
    assert fits["cruise"].gain == pytest.approx(1.0, abs=0.02)  # a phase, no attenuation, through the window


def look(decision: str, llr: float, kinds: dict[str, float]) -> lookalike.LookAlike:
    e = SegmentEvidence(llr, kinds, {k: 100 for k in kinds}, 1.3, 0.015)
    return lookalike.LookAlike(
        ("steering_lag", "time_offset"),
        ("steering_lag", "time_offset"),
        e,
        decision,
        "steering_lag",
        lookalike.telling("steering_lag", "time_offset"),
    )


def test_the_answers_shape_favours_the_twin_whose_form_fits_the_telling_segment():
    """Steering lag against a delay is told on steering steps (TELLING): the lag form fits better there, so
    the shape favours the lag, by the engine's LLR between forms, counted in fixes."""
    twins = look(engine_lookalike.CANNOT_TELL, 1.2, {"steer_step": 1.0})
    on_steps = ResponseFit("course", segments.STEER_STEP, 100, 4.0, 0.3, 2.0, 0.4, 1.0, 1.0, 3.0)
    on_cruise = ResponseFit("course", segments.CRUISE, 100, 4.0, 0.3, 1.0, 0.4, 2.0, 1.0, 3.0)
    twins.response = [on_cruise, on_steps]
    assert twins.shape == {
        "segment": segments.STEER_STEP,
        "favours": "steering_lag",
        "llr": response.form_llr(on_steps, "lag", "delay"),
        "fixes": 100,
    }
    saved = twins.to_json()
    assert saved["shape"]["llr"] == pytest.approx(50.0) and saved["response_fit"][1]["fixes"] == 100
    twins.response = [on_cruise]  # no steering steps in these runs: the shape cannot tell
    assert twins.shape == {"segment": segments.STEER_STEP, "favours": None, "llr": 0.0, "fixes": 0}


def test_lookalikes_in_json_and_words():
    from dse_runner.cases.robotti_diagnosis import report

    d = diagnosis(("wheel_slip",), floor=0.1)
    d.lookalikes = [look(engine_lookalike.CANNOT_TELL, 1.2, {"steer_ramp": 1.0, "cruise": 0.2})]
    saved = strict_loads(strict_json.dumps(d.to_json()))["lookalikes"][0]
    assert saved["pair"] == ["steering_lag", "time_offset"] and saved["decision"] == "cannot_tell"
    assert saved["by_segment"]["steer_ramp"] == {"llr": 1.0, "fixes": 100} and saved["telling_fixes"] == 0
    from dse_runner.analysis.diagnose import report as skeleton

    words = skeleton.twins_sentence(d.lookalikes[0].to_json(), report.WORDS)  # the engine's, in its words
    assert "`steering_lag` or its look-alike `time_offset`" in words
    assert (
        "cannot tell on these runs" in words
        and "these runs have no steering steps and no speed steps" in words
    )
    assert words.endswith("a run with steering steps would.")
    decided = skeleton.twins_sentence(
        look(engine_lookalike.DECIDED_BY_LLR, -7.5, {"steer_step": -7.0, "cruise": -0.5}).to_json(),
        report.WORDS,
    )
    assert decided.startswith("**Look-alikes:** `time_offset` rather than its look-alike `steering_lag`")
    assert "but the fixes can (LLR 7.5 in its favour, mostly on steering steps (-7.0))" in decided
    # the whole page, drawn from the answer with the Robotti's sections: the twins right under the verdict

    d.calibration.update(
        folds=[["run0"], ["run1"]],
        grid_best={"vehicle.mass": 1800.0},
        grid_at_bound=[],
        refined={"vehicle.mass": 1800.0},
        refined_at_bound=[],
        no_effect=[],
        insensitive_scenarios=[],
    )
    page = skeleton.markdown(d.answer(), report.sections(d.answer()))
    assert page.index("**Verdict") < page.index(words) < page.index("## Named effects")
    # the look-alikes part: the engine's evidence in the Robotti's words, then what tells the twins apart
    part = page.split("## Look-alikes\n")[1].split("\n## ")[0]
    assert "divided by the residuals' autocorrelation time in fixes" in part
    assert (
        "`steering_lag` against `time_offset` (swapping `steering_lag` for `time_offset`): LLR +1.2, in "
        "favour of `steering_lag`, mostly on steering ramps and sines (+1.0)" in part
    )
    assert (
        "autocorrelation time 1.3 fixes. What tells them apart best: steering steps, speed steps (0 fixes"
        in part
    )
    assert (
        "| segment | fixes | LLR (steering_lag over time_offset) |" in part
        and "| cruising straight | 100 |" in part
    )


# ---- discovery: PySINDy's STLSQ on equation error, the rule, the words ------------------------------------


def acc_regression(
    seed: int, runs: int = 6, rows: int = 200, coefficient: float | None = -0.31, noise_rms: float = 0.03
) -> dict:
    """The acc channel's regression over synthetic runs, each at its own speeds (0.4 to 2.4 m/s, so that 1,
    v and v² differ): the target is ``coefficient``·v (a drag the model lacks) plus white noise, or
    noise alone when ``coefficient`` is None."""
    from dse_runner.cases.robotti_diagnosis import correction, discover

    rng = np.random.default_rng(seed)
    terms = tuple(t for t in correction.searched_terms() if t.channel == "acc")
    parts = []
    for k in range(runs):
        t = np.arange(rows) * 0.1
        v = 0.4 + 0.35 * k + 0.6 * np.sin(2 * np.pi * t / (8.0 + 3 * k)) ** 2  # slow runs and fast
        v_cmd = v + 0.05 * np.sin(t)
        inputs = correction.FeatureInputs(
            v=v,
            psi=0.3 * t,
            r=0.1 * np.sin(0.37 * t + k),
            s=correction.distance(t, v),
            v_cmd=v_cmd,
            a_cmd=np.gradient(v_cmd, t),
            delta=np.zeros(rows),
            delta_rate=np.zeros(rows),
            f_drive=4.4 * (v_cmd - v),
            t=t,
            onset=10.0,
        )
        columns = correction.features(inputs, terms)
        theta = np.column_stack([columns[tm.variable] for tm in terms])
        y = rng.normal(0.0, noise_rms, rows) + (coefficient * v if coefficient is not None else 0.0)
        rms = {tm.variable: float(np.sqrt(np.mean(theta[:, j] ** 2))) for j, tm in enumerate(terms)}
        parts.append(discover.ChannelRegression("acc", terms, theta, y, np.zeros(rows, int), rms))
    return {"acc": discover.ChannelRegression.join(parts)}


def test_stlsq_recovers_a_known_speed_term():
    """The exact PySINDy calls discovery makes (STLSQ, threshold by leave-one-run-out, bootstrap over runs)
    find d(v)/dt += -0.31·v among the acc channel's features: v among the proposed terms, and the
    proposed correction is that term (shrunk: equation-error coefficients are starting values, the fits
    size them). The ridge shares it with v's look-alikes (1, v² and sgn v, which is 1 above v_min);
    ranking on positions orders them and the fits prune the ones that only stand in."""
    from dse_runner.cases.robotti_diagnosis import correction, discover

    regs = acc_regression(seed=1)
    proposal = discover.propose(regs)
    assert "corr_acc_v" in proposal.terms
    assert set(proposal.terms) <= {"corr_acc_v", "corr_acc_1", "corr_acc_v2", "corr_acc_sgnv"}
    assert proposal.inclusion["corr_acc_v"] >= discover.INCLUSION
    reg = regs["acc"]
    column = {t.variable: reg.theta[:, k] for k, t in enumerate(reg.terms)}
    proposed = sum(c * column[v] for v, c in proposal.terms.items())
    truth = -0.31 * column["corr_acc_v"]
    assert (
        np.corrcoef(proposed, truth)[0, 1] >= 0.99
    )  # the same correction, shrunk by the ridge: a start only
    assert 0.5 <= np.linalg.norm(proposed) / np.linalg.norm(truth) <= 1.1
    assert correction.readable(proposal.terms)[0].startswith("d(v)/dt += -")
    assert discover.propose(acc_regression(seed=1)).terms == proposal.terms  # seeded: a re-run asks the same


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_noise_alone_proposes_no_term(seed):
    from dse_runner.cases.robotti_diagnosis import discover

    proposal = discover.propose(acc_regression(seed=seed, coefficient=None))
    assert proposal.empty, proposal.terms


def loop_run(name: str, seconds: float, turn: float, speed: float = 1.6) -> tuple:
    """A synthetic run that drives at ``speed`` and turns at ``turn`` rad/s from 2 s, as its command log and
    exact fixes (no receiver noise), with its heading at each fix."""
    from dse_runner.cases.robotti_diagnosis import discover

    log_t = np.round(np.arange(0.0, seconds + 1e-9, 0.05), 2)
    t = np.round(np.arange(0.0, seconds + 1e-9, 0.1), 2)
    fine = np.linspace(0.0, seconds, 20001)
    v = np.where(fine >= 1.0, speed, 0.0)
    psi = np.where(fine >= 2.0, turn * (fine - 2.0), 0.0)
    x = np.concatenate([[0.0], np.cumsum(np.diff(fine) * v[1:] * np.cos(psi[1:]))])
    y = np.concatenate([[0.0], np.cumsum(np.diff(fine) * v[1:] * np.sin(psi[1:]))])
    observed = discover.Observed(
        name,
        t,
        np.interp(t, fine, x),
        np.interp(t, fine, y),
        log_t,
        np.where(log_t >= 1.0, speed, 0.0),
        np.where(log_t >= 2.0, 0.25, 0.0),
    )
    return observed, np.interp(t, fine, psi)


@pytest.mark.slow  # discovery's regressions over four long runs
def test_antenna_channels_are_proposed_from_the_fix_residuals_in_body_axes():
    """A mast that leans by h·sin(ψ − ψ_s) to the left is an output effect, invisible to equation
    error: the residuals of a model without it, turned into body axes, propose gps_cross += −h·sin
    ψ_s·cos ψ + h·cos ψ_s·sin ψ (sin(ψ − ψ_s) expanded) and nothing along the track; white
    receiver noise alone proposes nothing."""
    from dse_runner.cases.robotti_diagnosis import correction, discover

    values = discover.vehicle_values({}, "vehicle")
    h, heading = 0.2, 0.7
    rng = np.random.default_rng(5)
    runs, leaning, noisy = [], {}, {}
    for k, turn in enumerate((0.2, -0.15, 0.25, 0.1)):
        run, psi = loop_run(f"loop{k}", 32.0, turn)
        runs.append(run)
        shift = h * np.sin(psi - heading)  # the antenna sits this far to the left of where the model has it
        noise = rng.normal(0.0, 0.02, (2, len(psi)))
        # fix_residuals: simulated minus recorded, x then y; the recorded antenna is moved left by ``shift``
        leaning[run.name] = np.concatenate([shift * np.sin(psi) - noise[0], -shift * np.cos(psi) - noise[1]])
        noisy[run.name] = -np.concatenate(noise)
    proposal = discover.propose(
        {c: r for c, r in discover.regressions(runs, values, leaning).items() if c in discover.OUTPUT}
    )
    assert set(proposal.terms) == {"corr_gps_cross_cospsi", "corr_gps_cross_sinpsi"}, proposal.terms
    assert proposal.terms["corr_gps_cross_sinpsi"] == pytest.approx(h * np.cos(heading), rel=0.1)
    assert proposal.terms["corr_gps_cross_cospsi"] == pytest.approx(-h * np.sin(heading), rel=0.1)
    assert correction.readable(proposal.terms)[0].startswith("gps_cross += ")
    quiet = discover.propose(
        {c: r for c, r in discover.regressions(runs, values, noisy).items() if c in discover.OUTPUT}
    )
    assert quiet.empty, quiet.terms
    assert "gps_cross" not in discover.regressions(runs, values)  # no residuals, no antenna channel


def straight_run(
    name: str, seconds: float, speed: float, deceleration: float, onset: float, values: dict
) -> object:
    """A straight synthetic run at a constant speed command, its speed integrated here (1 ms Euler) with
    the drive of ``values`` and, from ``onset`` on, a force against the motion: d(v)/dt +=
    deceleration·clamp(v/v_min, −1, 1); exact fixes at 10 Hz."""
    from dse_runner.cases.robotti_diagnosis import discover

    dt = 0.001
    fine = np.arange(0.0, seconds + dt / 2, dt)
    v = np.zeros(len(fine))
    tau = values["mass"] / values["Kv"]
    for k in range(1, len(fine)):
        resist = (
            deceleration * min(max(v[k - 1] / values["v_min"], -1.0), 1.0) if fine[k - 1] >= onset else 0.0
        )
        v[k] = v[k - 1] + dt * ((speed - v[k - 1]) / tau + resist)
    x = np.concatenate([[0.0], np.cumsum(dt * 0.5 * (v[1:] + v[:-1]))])
    t = np.round(np.arange(0.0, seconds + 1e-9, 0.1), 2)
    log_t = np.round(np.arange(0.0, seconds + 1e-9, 0.05), 2)
    return discover.Observed(
        name,
        t,
        np.interp(t, fine, x),
        np.zeros(len(t)),
        log_t,
        np.full(len(log_t), speed),
        np.zeros(len(log_t)),
    )


def test_a_change_mid_run_is_found_at_its_time_and_proposed_as_an_onset_term():
    """A drag that starts 8 s into every run (an implement lowered) is a step in the acc channel's equation
    error: the onset scan finds its time to within the fixes' smoothing window, and the proposal carries an
    onset term and that time; the same runs without the drag propose no onset term."""
    from dse_runner.cases.robotti_diagnosis import correction, discover

    values = discover.vehicle_values({}, "vehicle")
    speeds = (0.8, 1.2, 1.6, 2.0)
    dragged = [straight_run(f"run{k}", 16.0, u, -0.6, 8.0, values) for k, u in enumerate(speeds)]
    regs = discover.regressions(dragged, values)
    assert regs["acc"].shapes["corr_onset_time"] == pytest.approx(8.0, abs=0.3)
    proposal = discover.propose(regs)
    assert proposal.shapes["corr_onset_time"] == regs["acc"].shapes["corr_onset_time"]
    assert any(
        correction.shape_of(correction.term(v)) == correction.SHAPES["onset"] for v in proposal.terms
    ), proposal.terms
    assert any("[t ≥ " in line and " s]" in line for line in proposal.readable())
    clean = [straight_run(f"run{k}", 16.0, u, 0.0, 8.0, values) for k, u in enumerate(speeds)]
    quiet = discover.propose(discover.regressions(clean, values))
    assert not any(
        correction.shape_of(correction.term(v)) == correction.SHAPES["onset"] for v in quiet.terms
    ), quiet.terms


def test_rate_limits_that_bind_most_of_the_time_are_not_scanned():
    """A steering sine of 0.2 rad and 8 s turns at most 0.157 rad/s: a limit above that never binds, one far
    below binds nearly all the time and is a gain, not a limit, so the scan leaves it out."""
    from types import SimpleNamespace

    from dse_runner.cases.robotti_diagnosis import correction, discover

    t = np.round(np.arange(0.0, 40.0 + 1e-9, 0.05), 2)
    delta = 0.2 * np.sin(2 * np.pi * t / 8.0)
    zero = np.zeros(len(t))
    inputs = correction.FeatureInputs(
        v=zero + 1.0,
        psi=zero,
        r=zero,
        s=zero,
        v_cmd=zero + 1.0,
        a_cmd=zero,
        delta=delta,
        delta_rate=zero,
        f_drive=zero,
        t=t,
    )
    refs = [SimpleNamespace(inputs=inputs)]
    assert discover.binding(refs, 0.2) == 0.0
    assert discover.binding(refs, 0.01) > 0.9
    scanned = discover.candidates(refs, correction.SHAPES["rate_limit"])
    assert len(scanned) and all(discover.binding(refs, v) <= discover.MAX_BINDING for v in scanned)
    assert scanned.min() > 0.05 and scanned.max() == pytest.approx(discover.RATE_LIMITS[1])


def test_extended_bic_charges_the_search():
    from dse_runner.analysis.diagnose.proof import extended_margin
    from dse_runner.cases.robotti_diagnosis import discover

    p = discover.searched_count()
    assert extended_margin(10.0, p, 0) == pytest.approx(10.0)
    assert extended_margin(10.0, p, 2) == pytest.approx(10.0 + 2 * math.log(math.comb(p, 2)))
    assert extended_margin(10.0, 38, 2) == pytest.approx(10.0 + 2 * math.log(703))  # +13.1


def with_terms(ids, held_out, sse, values, se=0.001):
    c = candidate(ids, held_out, sse, values)
    c.full.standard_error.update({n: se for n in values})
    return c


def test_discovered_terms_in_json_and_verdict(tmp_path):
    from dse_runner.cases.robotti_diagnosis import discover

    none = candidate((), [1.0, 1.0], 400.0)
    term = {"vehicle.corr_acc_v": -0.31}
    found = with_terms(("discovered",), [0.04, 0.04], 9.0, term)
    d = Diagnosis(
        tmp_path,
        {"vehicle": "vehicle"},
        baseline=none,
        chosen=found,
        candidates=[found, none],
        floor=noise.NoiseFloor(0.02, 0.025, noise.CLOSE_FIXES, 100),
        discovery=discovery.Discovery(
            none,
            discover.CorrectionSearch(),
            candidates=[found],
            chosen=found,
            resembles=[("wheel_slip", 0.95), ("speed_lag", 0.4)],
        ),
    )
    assert d.verdict == "discovered" and d.discovered
    [entry] = d.effects
    assert entry["id"] == "discovered" and entry["held_out_without"] == 1.0 and entry["held_out_with"] == 0.04
    assert entry["terms"][0]["text"].startswith("d(v)/dt += -0.31·v [")
    assert entry["resembles"]["id"] == "wheel_slip"
    saved = strict_loads(strict_json.dumps(d.to_json()))
    assert saved["case"]["discovery"]["accepted"]
    assert saved["effects"][0]["terms"][0]["variable"] == "corr_acc_v"


def test_a_correction_that_leaves_a_residual_is_partial(tmp_path):
    """Accepted, yet still well above the noise (a payload lowered mid-run, which no
    time-invariant term expresses): verdict partial, the correction itself flagged partial, and
    the report says how much remains."""
    from dse_runner.analysis.diagnose import report
    from dse_runner.cases.robotti_diagnosis import discover
    from dse_runner.cases.robotti_diagnosis import report as robotti_report

    none = candidate((), [1.0, 1.0], 400.0)
    found = with_terms(("discovered",), [0.3, 0.3], 90.0, {"vehicle.corr_acc_s": -0.05})
    d = Diagnosis(
        tmp_path,
        {"vehicle": "vehicle"},
        baseline=none,
        chosen=found,
        candidates=[found, none],
        floor=noise.NoiseFloor(0.02, 0.025, noise.CLOSE_FIXES, 100),
        discovery=discovery.Discovery(
            none,
            discover.CorrectionSearch(),
            candidates=[found],
            chosen=found,
            resembles=[("wheel_slip", 0.6)],
        ),
    )
    assert d.verdict == "partial" and d.discovered
    [entry] = d.effects
    assert entry["id"] == "discovered" and entry["partial"]
    text = report.verdict(d.answer())
    assert text.startswith("**Verdict: partial.**") and "explains part of it" in text
    assert "0.275 m of mean cross-track error remains above the noise" in text
    said = robotti_report.discovery_text(d.answer())  # from the JSON alone, as the report is drawn
    assert f"Accepted: `discovered`; it {discovery.resemblance_words([('wheel_slip', 0.6)])}." in said


def test_a_delay_or_lag_is_fitted_from_inside_its_range_too():
    """Against manoeuvres that repeat, a delay's misfit has minima a period apart: a one-parameter effect in
    seconds starts absent and at a third and two thirds of its range; any other effect starts absent only."""
    from dse_runner.cases.robotti_diagnosis.chain import VehicleEffect

    for hid in ("steering_lag", "speed_lag", "time_offset"):
        (p,) = LIBRARY[hid].parameters
        starts = VehicleEffect.of("vehicle", hid).starts
        span = p.upper - p.lower
        assert starts == ((0.0,), (p.lower + span / 3,), (p.lower + 2 * span / 3,)), hid
    assert VehicleEffect.of("vehicle", "wheel_slip").starts == ((0.0,),)
    assert VehicleEffect.of("vehicle", "antenna_offset").starts == ((0.0, 0.0),)
