"""The combination screens (analysis/diagnose/screens/): one contract test over every registered strategy, as
Optuna tests every sampler; a strategy chosen by a name that does not exist is told before anything runs."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from dse_runner.analysis.diagnose import Request, explain, screens
from dse_runner.analysis.diagnose.screens import mixed
from dse_runner.cases.robotti_diagnosis import DiagnosisSettings
from dse_runner.errors import DseError
from dse_runner.sweeps.fit import FitProblem, FitResult, LevenbergMarquardt, Parameter

BASE = (Parameter("plant.k", 2.0, 1.0, 3.0, 0.01), Parameter("plant.d", 0.5, 0.1, 0.9, 0.005))
EFFECTS = {  # id -> its parameters; "a" and "b" mask each other, "c_also" acts on c's own parameter
    "a": (Parameter("fx.a", 0.0, 0.0, 1.0, 0.001),),
    "b": (Parameter("fx.b", 0.0, 0.0, 1.0, 0.001),),
    "c": (Parameter("fx.c", 0.0, -1.0, 1.0, 0.001),),
    "c_also": (Parameter("fx.c", 0.0, -1.0, 1.0, 0.001), Parameter("fx.e", 0.0, -1.0, 1.0, 0.001)),
    "d": (Parameter("fx.d", 0.0, -1.0, 1.0, 0.001),),
}
TRUTH = {"plant.k": 1.6, "plant.d": 0.4, "fx.a": 0.3, "fx.b": 0.5}
NAMES = [p.name for p in BASE] + sorted({p.name for ps in EFFECTS.values() for p in ps})


def masked(runs: int = 3, samples: int = 200, seed: int = 1):
    """Residuals linear in every parameter in which ``a`` and ``b`` mask each other: each one's signature is
    mostly a common part ``w`` the other cancels, so neither alone explains much and both together all."""
    rng = np.random.default_rng(seed)
    columns = {}
    for s in range(runs):
        w = rng.normal(0, 1.0, samples)
        per_unit = {n: rng.normal(0, 1.0, samples) for n in NAMES}
        per_unit["fx.a"] = (w + rng.normal(0, 0.05, samples)) / TRUTH["fx.a"]
        per_unit["fx.b"] = (-w + rng.normal(0, 0.05, samples)) / TRUTH["fx.b"]
        columns[f"run{s}"] = (np.column_stack([per_unit[n] for n in NAMES]), rng.normal(0, 0.01, samples))

    def residuals(point: dict[str, float], scenario: str) -> np.ndarray:
        jacobian, noise = columns[scenario]
        return jacobian @ np.array([point.get(n, 0.0) - TRUTH.get(n, 0.0) for n in NAMES]) + noise

    return residuals, tuple(columns)


@dataclass
class Synthetic:
    """What a screen reads of the engine's fits (engine.Fits), on residuals computed here: no cluster."""

    residuals: Any
    scenarios: tuple[str, ...]
    base: tuple[Parameter, ...] = BASE
    library: dict[str, Any] = field(
        default_factory=lambda: {h: SimpleNamespace(parameters=ps) for h, ps in EFFECTS.items()}
    )
    look_alikes: dict[str, tuple[str, ...]] = field(default_factory=lambda: {"b": ("d",)})
    asked: list[int] = field(default_factory=list)  # points per sweep

    def shares(self, a: str, b: str) -> bool:
        return bool({p.name for p in EFFECTS[a]} & {p.name for p in EFFECTS[b]})

    def evaluate(self, points):
        self.asked.append(len(points))
        return self.residuals


def fitted(ids: tuple[str, ...], residuals, scenarios) -> FitResult:
    """A real Levenberg-Marquardt fit (fit.py's ask/tell machine), told the synthetic residuals."""
    freed = BASE + tuple(p for h in ids for p in EFFECTS[h])
    fixed = {n: 0.0 for n in NAMES if n not in {p.name for p in freed}}
    solver = LevenbergMarquardt(FitProblem("+".join(ids) or "none", freed, fixed, scenarios, 30))
    while not solver.done:
        solver.ask()
        solver.tell(residuals)
    return solver.result()


@pytest.fixture(scope="module")
def singles():
    residuals, scenarios = masked()
    return (
        residuals,
        scenarios,
        {ids: fitted(ids, residuals, scenarios) for ids in [(), *((h,) for h in EFFECTS)]},
    )


@pytest.mark.parametrize("name", screens.names())
@pytest.mark.parametrize("triples", [0, 2])
def test_every_strategy_shortlists_the_masked_pair_from_the_library_hypotheses(name, triples, singles):
    residuals, scenarios, full = singles
    none = full[()]
    for h in ("a", "b"):  # masked: neither passes the BIC half of the gate alone
        assert explain.bic(full[(h,)]) > explain.bic(none) - explain.BIC_MARGIN
    fits = Synthetic(residuals, scenarios)
    found = screens.strategy(name).run(fits, full, screens.ScreenSettings(pairs=3, triples=triples, limit=6))
    assert found.strategy == name and found.predicted >= len(found.screened) > 0
    assert all(set(x.ids) <= set(EFFECTS) and len(set(x.ids)) == len(x.ids) for x in found.screened)
    assert not any({"c", "c_also"} <= set(x.ids) for x in found.screened)  # they act on one parameter
    assert {len(x.ids) for x in found.screened} == ({2, 3} if triples else {2})
    assert [x.bic for x in found.screened] == sorted(x.bic for x in found.screened)  # best first
    assert found.screened[0].ids in {("a", "b"), ("b", "a")}
    assert found.screened[0].sse < 0.05 * none.sse
    short = [frozenset(x.ids) for x in found.shortlist]
    assert short[0] == {"a", "b"} and len(short) <= 6
    assert all(x in found.screened for x in found.shortlist)
    assert frozenset({"a", "d"}) in short  # b's declared look-alike swapped in, fitted beside it
    start = found.screened[0].start  # the real fit of the pair starts near the truth
    assert start["fx.a"] == pytest.approx(0.3, rel=0.05) and start["fx.b"] == pytest.approx(0.5, rel=0.05)


def test_a_pair_is_predicted_from_the_two_singles_changes():
    rng = np.random.default_rng(0)
    u, v = rng.normal(size=50), rng.normal(size=50)
    point = {"a": 0.0, "b": 0.0}

    def fit(label, residuals, at):
        return FitResult(
            label, [], {}, float(residuals @ residuals), 50, 1, True, {}, [], at, [], [residuals]
        )

    none = fit("none", u + v, point)
    only_a = fit("a", v, {"a": 2.0, "b": 0.0})  # a's fit took u away, b's would take v
    only_b = fit("b", u, {"a": 0.0, "b": 3.0})
    coefficients, predicted = mixed.prediction(none, [only_a, only_b])
    assert np.allclose(coefficients, [1.0, 1.0]) and predicted < 1e-20
    assert mixed.mixed(none, [only_a, only_b], coefficients, {}) == pytest.approx({"a": 2.0, "b": 3.0})


def test_an_unknown_screen_is_named_with_the_known_ones_before_anything_runs():
    for ask in (
        lambda: Request(screen="newton"),
        lambda: DiagnosisSettings(screen="newton"),
        lambda: screens.strategy("newton"),
    ):
        with pytest.raises(DseError, match=r"--screen 'newton'.*known: linearised, mixed"):
            ask()
    assert Request(screen="linearised").screen == "linearised"


PAIRS_ONLY = """
from dse_runner.analysis.diagnose.screens import ScreenStrategy


class NoScreen(ScreenStrategy):
    name = "nothing"

    def screened(self, fits, singles, settings):
        return [], 0


class Duck:
    name = "duck"
"""


def test_an_installed_screen_is_chosen_by_name_as_the_built_in_ones_are(tmp_path, monkeypatch):
    from support.plugins import register

    register(
        monkeypatch,
        tmp_path / "plugin",
        "my_screens",
        PAIRS_ONLY,
        {"dse_runner.screens": {"nothing": "my_screens:NoScreen", "duck": "my_screens:Duck"}},
    )
    assert screens.names() == ["duck", "linearised", "mixed", "nothing"]
    assert Request(screen="nothing").screen == "nothing"
    found = screens.strategy("nothing").run(SimpleNamespace(look_alikes={}), {}, screens.ScreenSettings())
    assert (found.strategy, found.screened, found.shortlist) == ("nothing", [], [])
    with pytest.raises(DseError, match=r"screen 'duck' \(my_screens:Duck\) is not a subclass"):
        screens.strategy("duck")


def test_each_library_screens_with_its_declared_default_unless_the_request_names_another():
    from dse_runner.analysis.diagnose.signal_library import SignalEffects
    from dse_runner.cases.robotti_diagnosis import RobottiLibrary

    assert SignalEffects().screen_for(Request()) == "mixed"
    assert RobottiLibrary().screen_for(Request()) == "linearised" == DiagnosisSettings().screen
    assert RobottiLibrary().screen_for(Request(screen="mixed")) == "mixed"
    assert all(library.screen in screens.names() for library in (SignalEffects(), RobottiLibrary()))


@pytest.fixture(scope="module")
def msd_singles(tmp_path_factory, dask_scheduler):
    """The mass-spring-damper's recordings with a sensor's gain and offset concealed together
    (jobs/msd/make_diagnosis_runs.py), calibrated and each signal effect fitted alone: one diagnosis' singles,
    which every strategy then screens."""
    import importlib.util

    from conftest import REPO
    from distributed import Client

    from dse_runner.analysis.diagnose.engine import singles
    from dse_runner.analysis.diagnose.library import space_with
    from dse_runner.analysis.diagnose.signal_library import calibrated_fits, compared_signals

    spec = importlib.util.spec_from_file_location("runs", REPO / "jobs" / "msd" / "make_diagnosis_runs.py")
    generator = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(generator)
    folder = tmp_path_factory.mktemp("sensor-gain-offset")
    space = space_with(
        generator.make("sensor-gain-offset", folder), None, folder / "out", address=dask_scheduler
    )
    with Client(dask_scheduler) as client:
        fits, _ = calibrated_fits(space, compared_signals(space), client, lambda line: None, discover=False)
        _, full = singles(fits)
        yield fits, full


@pytest.mark.slow
@pytest.mark.parametrize("name", screens.names())
def test_every_strategy_shortlists_a_concealed_sensor_gain_and_offset_on_a_real_fmu(name, msd_singles):
    fits, full = msd_singles
    found = screens.strategy(name).run(fits, full, screens.ScreenSettings(pairs=3, triples=2, limit=5))
    assert found.screened and all(set(x.ids) <= set(fits.library) for x in found.screened)
    assert [x.bic for x in found.screened] == sorted(x.bic for x in found.screened)  # best first
    assert {len(x.ids) for x in found.screened} == {2, 3}  # the settings ask for triples
    concealed = {"output_gain(msd.x)", "output_offset(msd.x)"}
    assert concealed in [set(x.ids) for x in found.shortlist], [x.label for x in found.shortlist]
