"""Uncertainty propagation (sweeps/uncertainty.py, the spec's ``uncertain:`` block, rank.py's statistics over
the draws and robust ranking), proved on the Ishigami function as an FMU (jobs/ishigami, C built on first
use) on the real cluster: a Dask scheduler and two worker processes, results through the Parquet store.

With x1, x2, x3 uniform on [-pi, pi] and y = sin x1 + a sin^2 x2 + b x3^4 sin x1, the mean and variance are
known in closed form (computed below, never pasted): E y = a / 2 and
Var y = a^2 / 8 + b pi^4 / 5 + b^2 pi^8 / 18 + 1 / 2. The design parameters are a and b; x1..x3 are uncertain.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from conftest import REPO, dse_runner, strict_loads, write_msd_search

from dse_runner.errors import DseError
from dse_runner.sweeps import uncertainty
from dse_runner.sweeps.closed_loop import over_draws
from dse_runner.sweeps.expand import expand
from dse_runner.sweeps.rank import load_sweep_spec, rank, write_ranking
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit
from dse_runner.sweeps.uncertainty import Robust

ISHIGAMI = REPO / "jobs" / "ishigami"
PI = math.pi
UNIFORM = {"distribution": "uniform", "low": -PI, "high": PI}
XS = ("ishigami.x1", "ishigami.x2", "ishigami.x3")
SAMPLES = 256
# Three designs on a line through (a, b): the lowest mean has the widest spread, so the robust ranking
# (mean + 1 std) must pick another than the mean's.
DESIGN = {
    "parameters": {"ishigami.a": [-4.0, -3.0, -2.0], "ishigami.b": [0.0, 0.1, 0.2]},
    "constraints": ["ishigami.a + 10 * ishigami.b == -2"],
}


def mean(a: float, b: float) -> float:
    return a / 2


def variance(a: float, b: float) -> float:
    return a**2 / 8 + b * PI**4 / 5 + b**2 * PI**8 / 18 + 1 / 2


def ishigami(x: np.ndarray, a: float, b: float) -> np.ndarray:
    return np.sin(x[:, 0]) + a * np.sin(x[:, 1]) ** 2 + b * x[:, 2] ** 4 * np.sin(x[:, 0])


def write(folder, address: str | None = None, **changes):
    """The example study (jobs/ishigami/robust.yaml) in ``folder``, its store there; ``changes`` replace
    top-level keys."""
    spec = yaml.safe_load((ISHIGAMI / "robust.yaml").read_text())
    spec["multimodel"]["fmus"]["ishigami"] = str(ISHIGAMI / spec["multimodel"]["fmus"]["ishigami"])
    spec |= {"output": str(folder / "out"), "cluster": {"address": address} if address else {"n_workers": 1}}
    spec.update(changes)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "space.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


# --- the spec, without a cluster ----------------------------------------------------------------------------


def test_each_scenario_runs_once_per_draw_with_stable_task_ids(tmp_path):
    space = load_space(write(tmp_path))
    assert [s.name for s in space.scenarios][:3] == ["nominal~u0", "nominal~u1", "nominal~u2"]
    assert len(space.scenarios) == SAMPLES and space.draws.shape == (SAMPLES, 3)
    first = space.scenarios[5].parameters
    assert first == {x: float(space.draws.loc[5, x]) for x in XS}
    assert all(-PI <= v <= PI for v in space.draws.to_numpy().ravel())
    tasks = [t.task_id for t in expand(space)]
    assert len(tasks) == 3 * SAMPLES == len(set(tasks))
    assert [t.task_id for t in expand(load_space(write(tmp_path)))] == tasks  # the same ids: resumable


def test_more_sobol_samples_keep_the_first_draws_and_the_model(tmp_path):
    small, large = (
        load_space(write(tmp_path / "a")),
        load_space(
            write(tmp_path / "b", uncertain={"samples": 2 * SAMPLES, "parameters": {x: UNIFORM for x in XS}})
        ),
    )
    assert np.array_equal(large.draws.head(SAMPLES).to_numpy(), small.draws.to_numpy())
    assert small.model_key == large.model_key
    other = load_space(
        write(
            tmp_path / "c", uncertain={"samples": SAMPLES, "seed": 1, "parameters": {x: UNIFORM for x in XS}}
        )
    )
    assert other.model_key != small.model_key  # another seed: other values under the same scenario names


def test_distributions_are_scipys_at_the_drawn_quantiles(tmp_path):
    from scipy import stats

    parameters = {
        "ishigami.x1": {"distribution": "normal", "mean": 0.5, "std": 0.2},
        "ishigami.x2": {"distribution": "lognormal", "median": 1.5, "std_log": 0.1},
        "ishigami.x3": {"distribution": "triangular", "low": -1, "mode": 0.5, "high": 2},
    }
    space = load_space(
        write(
            tmp_path,
            uncertain={"samples": 512, "sampling": "latin_hypercube", "seed": 3, "parameters": parameters},
        )
    )
    units = uncertainty.unit_sample(512, 3, "latin_hypercube", 3)
    expected = [
        stats.norm(0.5, 0.2).ppf(units[:, 0]),
        stats.lognorm(s=0.1, scale=1.5).ppf(units[:, 1]),
        stats.triang(c=1.5 / 3, loc=-1, scale=3).ppf(units[:, 2]),
    ]
    for x, values in zip(XS, expected):
        assert np.allclose(space.draws[x].to_numpy(), values, rtol=0, atol=1e-12)
    # a Latin hypercube puts one draw in each of the 512 equal-probability strata of each parameter
    strata = np.floor(stats.norm(0.5, 0.2).cdf(space.draws["ishigami.x1"]) * 512)
    assert sorted(strata) == list(range(512))


def test_a_diagnosis_interval_is_read_as_a_normal_of_half_width_1_96_sigma(tmp_path):
    """Both shapes a diagnosis writes: the fitted calibration (qualified names) and an effect (bare names);
    and the repository's Robotti diagnosis, read as the file says."""
    found = {
        "fitted": {"parameters": {"ishigami.x1": 0.5}, "interval": {"ishigami.x1": [0.3, 0.7]}},
        "effects": [
            {"id": "quartic", "parameters": {"x3": 1.0}, "interval": {"x3": [0.9, 1.3]}},
            {
                "id": "lag",
                "target": "ishigami.x2",
                "parameters": {"delay": 0.2},
                "intervals": {"delay": [0.1, 0.3]},
            },
        ],
    }
    (tmp_path / "diagnosis.json").write_text(json.dumps(found))
    space = load_space(
        write(
            tmp_path,
            uncertain={
                "samples": 8,
                "parameters": {
                    "ishigami.x1": {"from_diagnosis": "diagnosis.json"},
                    "ishigami.x2": {"from_diagnosis": "diagnosis.json", "effect": "lag"},
                    "ishigami.x3": {"from_diagnosis": "diagnosis.json", "effect": "quartic"},
                },
            },
        )
    )
    for name, (value, low, high) in {
        "ishigami.x1": (0.5, 0.3, 0.7),
        "ishigami.x2": (0.2, 0.1, 0.3),
        "ishigami.x3": (1.0, 0.9, 1.3),
    }.items():
        d = space.distributions[name]
        assert d.distribution == "normal" and d.mean == value
        assert math.isclose(d.std * 1.959963984540054, (high - low) / 2)
    robotti = REPO / "docs" / "diagnosis-robotti" / "diagnosis.json"
    effect = json.loads(robotti.read_text())["effects"][0]
    entry = load_space(
        write(
            tmp_path / "r",
            uncertain={
                "samples": 4,
                "parameters": {"ishigami.x1": {"from_diagnosis": str(robotti), "effect": effect["id"]}},
            },
        )
    ).distributions["ishigami.x1"]
    ((low, high),) = effect["interval"].values()
    assert entry.mean == next(iter(effect["parameters"].values()))
    assert math.isclose(entry.std, (high - low) / 2 / 1.959963984540054)


@pytest.mark.parametrize(
    "uncertain, message",
    [
        ({"parameters": {"ishigami.x9": UNIFORM}}, "x9"),
        ({"parameters": {"ishigami.x1": {"distribution": "normal", "mean": 0, "std": -1}}}, "std"),
        (
            {"parameters": {"ishigami.x1": {"distribution": "triangular", "low": 0, "mode": 3, "high": 2}}},
            "mode",
        ),
        (
            {"parameters": {"ishigami.x1": {"distribution": "uniform", "low": 1, "high": 1}}},
            "'high' (1) must be above",
        ),
        (
            {"parameters": {"ishigami.x1": {"distribution": "weibull", "k": 1}}},
            "uniform | normal | lognormal",
        ),
        ({"parameters": {"ishigami.a": UNIFORM}}, "either swept"),
        ({"parameters": {"ishigami.x1": {"from_diagnosis": "nowhere.json"}}}, "no such file"),
        ({"samples": 0, "parameters": {"ishigami.x1": UNIFORM}}, "samples"),
        ({"quantiles": [1.5], "parameters": {"ishigami.x1": UNIFORM}}, "quantiles"),
        (
            {"parameters": {"sample": UNIFORM}},
            "uncertain.parameters.sample: the name is a column of the ranking's draws",
        ),
        (
            {"parameters": {"y": UNIFORM}},
            "uncertain.parameters.y: the name is a column of the ranking's draws",
        ),
    ],
)
def test_bad_uncertain_blocks_name_the_culprit(tmp_path, uncertain, message):
    with pytest.raises(DseError) as caught:
        load_space(write(tmp_path, uncertain=uncertain))
    assert message in str(caught.value) and "space.yaml" in str(caught.value)
    assert "uncertain" in str(caught.value)


def test_a_diagnosis_without_the_effect_lists_what_it_has(tmp_path):
    (tmp_path / "d.json").write_text(
        json.dumps({"effects": [{"id": "slip", "parameters": {"s": 1}, "interval": {"s": [0, 2]}}]})
    )
    with pytest.raises(
        DseError, match=r"uncertain.parameters.ishigami.x1: .* no effect 'drag' \(it has slip\)"
    ):
        load_space(
            write(
                tmp_path,
                uncertain={"parameters": {"ishigami.x1": {"from_diagnosis": "d.json", "effect": "drag"}}},
            )
        )


def test_robust_ranking_needs_draws_and_one_figure(tmp_path):
    with pytest.raises(DseError, match="ranking.robust ranks over uncertain samples"):
        load_space(write(tmp_path, uncertain=None))
    with pytest.raises(DseError, match="exactly one of 'sigmas'"):
        load_space(write(tmp_path, ranking={"robust": {"sigmas": 1, "quantile": 0.9}}))


def test_a_draw_outside_the_variables_bounds_names_the_draw(tmp_path):
    """msd.k is declared min 0: a normal reaching below it is refused before anything runs."""
    path = write_msd_search(
        tmp_path,
        {"strategy": "exhaustive"},
        parameters={"msd.c": [0.5, 1.0]},
        uncertain={"samples": 16, "parameters": {"msd.k": {"distribution": "normal", "mean": 1, "std": 5}}},
    )
    with pytest.raises(
        DseError, match=r"uncertain.parameters.msd.k: draw \d+ \(-[\d.]+\): .*narrow its distribution"
    ):
        load_space(path)


def test_a_search_is_told_the_draws_mean_or_robust_figure():
    per = {f"s{j}~u{k}": {"y": float(k + j)} for k in range(4) for j in range(2)}  # two scenarios, four draws
    totals = np.array([2 * k + 1 for k in range(4)], dtype=float)  # summed over the scenarios per draw
    told = over_draws(per, ["y"], "sum", ("y", "min", Robust(sigmas=2)))
    assert math.isclose(told["y"], totals.mean() + 2 * totals.std(ddof=1))
    assert math.isclose(over_draws(per, ["y"], "sum", ("y", "min", None))["y"], totals.mean())
    assert math.isclose(
        over_draws(per, ["y"], "sum", ("y", "max", Robust(quantile=0.25)))["y"],
        float(np.quantile(totals, 0.25)),
    )


# --- on the real cluster ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def study(tmp_path_factory, dask_scheduler):
    space = load_space(write(tmp_path_factory.mktemp("uncertainty"), dask_scheduler))
    assert space.spec.uncertain.samples == SAMPLES and list(space.draws.columns) == list(XS)
    assert {k: space.parameters[k] for k in DESIGN["parameters"]} == DESIGN["parameters"]
    assert space.spec.constraints == DESIGN["constraints"]
    report = submit(space)
    assert (report.ok, report.failed) == (3 * SAMPLES, 0)
    return space


def test_mean_and_std_over_the_draws_match_the_closed_form(study):
    """At 256 scrambled Sobol' draws: each point's mean within 3 standard errors of E y (sigma / sqrt(n), the
    Monte Carlo bound, which quasi-random draws beat), its std within 3 standard errors of the std's estimate
    (from the draws' own fourth moment)."""
    ranking = rank(study.output)
    assert len(ranking.totals) == 3 and ranking.uncertainty["samples"] == SAMPLES
    for row in ranking.totals.to_dict("records"):
        a, b = row["ishigami.a"], row["ishigami.b"]
        sigma = math.sqrt(variance(a, b))
        draws = ranking.draws[(ranking.draws["ishigami.a"] == a) & (ranking.draws["ishigami.b"] == b)]["y"]
        assert len(draws) == SAMPLES
        assert abs(row["y"] - mean(a, b)) < 3 * sigma / math.sqrt(SAMPLES), (a, b, row["y"], mean(a, b))
        kurtosis = float(np.mean((draws - draws.mean()) ** 4) / draws.var(ddof=0) ** 2)
        std_error = sigma * math.sqrt((kurtosis - 1) / (4 * SAMPLES))
        assert abs(row["y_std"] - sigma) < 3 * std_error, (a, b, row["y_std"], sigma, std_error)
        assert row["y_q5"] < row["y_q50"] < row["y_q95"]
        assert math.isclose(row["y_robust"], row["y"] + row["y_std"])


def test_the_stored_rows_are_the_function_at_each_draw(study):
    """draws.csv alone says what each draw ran with (the rows only number the draws): beside each point's
    objectives per draw, the values of the space's sample, at which y is the function."""
    import pandas as pd

    draws = pd.read_csv(write_ranking(rank(study.output), study.output, study.name)["draws"])
    assert list(draws.columns) == ["ishigami.a", "ishigami.b", "sample", *XS, "y"]
    x = study.draws[list(XS)].to_numpy()
    for (a, b), rows in draws.groupby(["ishigami.a", "ishigami.b"]):
        rows = rows.sort_values("sample")
        assert np.array_equal(rows[list(XS)].to_numpy(), x)
        assert np.allclose(rows["y"].to_numpy(), ishigami(x, a, b), rtol=0, atol=1e-12)


def test_robust_ranking_picks_the_analytic_best_not_the_means(study):
    """mean + 1 std picks the point the closed form says, which is not the point of the best mean; a 0.9
    quantile ranking picks the point a large Monte Carlo sample of the formula says."""
    points = [(r["ishigami.a"], r["ishigami.b"]) for r in rank(study.output).totals.to_dict("records")]
    robust = rank(study.output)
    analytic = min(points, key=lambda p: mean(*p) + math.sqrt(variance(*p)))
    assert (robust.best["ishigami.a"], robust.best["ishigami.b"]) == analytic
    settings = load_sweep_spec(study.output, study.name).ranking
    by_mean = rank(study.output, settings=settings.model_copy(update={"robust": None}))
    assert (by_mean.best["ishigami.a"], by_mean.best["ishigami.b"]) == min(points, key=lambda p: mean(*p))
    assert by_mean.best != robust.best and by_mean.ranked_by == "y"
    reference = np.random.default_rng(0).uniform(-PI, PI, (1_000_000, 3))
    q90 = {p: float(np.quantile(ishigami(reference, *p), 0.9)) for p in points}
    by_quantile = rank(study.output, settings=settings.model_copy(update={"robust": Robust(quantile=0.9)}))
    assert (by_quantile.best["ishigami.a"], by_quantile.best["ishigami.b"]) == min(points, key=q90.get)
    found = by_quantile.totals.set_index(["ishigami.a", "ishigami.b"])["y_robust"]
    for p, value in q90.items():  # within a tenth of the point's std of the reference quantile
        assert abs(found.loc[p] - value) < 0.1 * math.sqrt(variance(*p)), (p, found.loc[p], value)


def test_rank_json_is_strict_and_a_resubmission_runs_nothing(study, tmp_path):
    done = dse_runner("rank", str(study.output), "--json")
    assert done.returncode == 0, done.stderr
    found = strict_loads(done.stdout)
    assert found["ranked_by"] == "y_robust" and found["uncertainty"]["ranked_by"] == "mean+1sd"
    assert set(found["top"][0]) >= {"y", "y_std", "y_q5", "y_q50", "y_q95", "y_robust"}
    assert "draws" in found["files"]
    printed = dse_runner("rank", str(study.output)).stdout  # the groups' best is by the mean: said so
    assert "best per group, by the mean over the draws of total y:" in printed, printed
    again = submit(study)
    assert (again.skipped, again.ran) == (3 * SAMPLES, 0)


def test_twice_the_draws_run_only_the_new_ones(study, tmp_path):
    """Sobol' draws keep their first values when more are asked: the old rows are reused, and ranking with
    the smaller sample afterwards still uses only its own draws."""
    spec = yaml.safe_load(study.path.read_text())
    spec["uncertain"]["samples"] = 2 * SAMPLES
    path = tmp_path / "space.yaml"
    path.write_text(yaml.safe_dump(spec))
    report = submit(load_space(path))
    assert (report.skipped, report.ran, report.failed) == (3 * SAMPLES, 3 * SAMPLES, 0)
    assert rank(study.output).uncertainty["samples"] == 2 * SAMPLES
    submit(study)  # back to the first sample: saves its spec again, runs nothing
    assert len(rank(study.output).draws) == 3 * SAMPLES
