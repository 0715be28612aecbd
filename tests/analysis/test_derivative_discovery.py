"""Derivative discovery: a term a model-exchange FMU's equations lack is proposed, fitted and proven from the
recordings alone (jobs/msd and jobs/pendulum's generators conceal one), and nothing is claimed where
nothing is missing."""

from __future__ import annotations

import importlib.util
import math
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO

from dse_runner.analysis.diagnose import explain
from dse_runner.analysis.diagnose.derivative_discovery import (
    Discovered,
    NotDiscovered,
    baseline_candidate,
    discover_derivatives,
)
from dse_runner.analysis.diagnose.derivative_discovery.library import (
    candidate_terms,
    model_exchange_instances,
)
from dse_runner.analysis.diagnose.derivative_discovery.propose import Regression, propose
from dse_runner.analysis.diagnose.noise import sigma_from_differences
from dse_runner.simulation.run import simulate
from dse_runner.sweeps.cluster import connect
from dse_runner.sweeps.fit import FitResult, Parameter
from dse_runner.sweeps.spec import load_space


def _generator(job: str):
    """A job's make_discovery_runs.py, imported from its file."""
    spec = importlib.util.spec_from_file_location(
        f"{job}_discovery", REPO / "jobs" / job / "make_discovery_runs.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _noise(space, column: str) -> float:
    """σ of the recordings' noise from their fourth differences (the signals
    are smooth at the sampling step)."""
    return float(
        np.median(
            [sigma_from_differences(np.diff(s.recorded.samples(column)[1], n=4), 4) for s in space.scenarios]
        )
    )


def _diagnose(
    space_path: Path, address: str, column: str, objective: str, ranges: dict[str, tuple[float, float]]
):
    """What a diagnosis would hand over: the calibration fitted from the middle of its ranges and
    cross-validated (one scenario per fold), then discovery on top of it. Reads only the recordings."""
    space = load_space(space_path).with_overrides(output=space_path.parent / "out", address=address)
    scales = {objective: 1.0 / _noise(space, column)}
    freed = [
        Parameter(name, 0.5 * (low + high), low, high, 0.01 * (high - low))
        for name, (low, high) in ranges.items()
    ]
    folds = explain.folds(space.scenarios, len(space.scenarios))
    base = {name: values[0] for name, values in space.parameters.items() if name not in ranges}
    base.update({p.name: p.start for p in freed})
    with connect(space.spec.cluster) as client:
        started = time.perf_counter()
        chosen = baseline_candidate(space, client, freed, base, scales, folds)
        calibrated = time.perf_counter()
        found = discover_derivatives(space, client, chosen, freed, scales, folds)
        print(
            f"{space_path.parent.name}: calibration {calibrated - started:.0f} s, discovery "
            f"{time.perf_counter() - calibrated:.0f} s {found.seconds}: {found.to_json()}"
        )
    return found


MSD_RANGES = {"msd.k": (6.0, 20.0), "msd.c": (0.1, 1.5)}
PENDULUM_RANGES = {"pendulum.l": (0.5, 1.2), "pendulum.b": (0.0, 0.3)}


@pytest.mark.slow
def test_a_concealed_cubic_spring_is_discovered_with_its_coefficient(tmp_path, dask_scheduler):
    space = _generator("msd").make("cubic", tmp_path / "cubic")
    found = _diagnose(space, dask_scheduler, "x", "position", MSD_RANGES)
    assert isinstance(found, Discovered), found.reason
    (effect,) = found.effects()
    assert (effect["id"], effect["target"], list(effect["terms"])) == ("discovered", "msd.der(v)", ["x^3"])
    low, high = effect["intervals"]["x^3"]
    assert low <= -60.0 <= high  # the generator's truth: der(v) += -60·x³
    assert effect["readable"].startswith("der(v) += -")
    before, after = found.held_out
    assert after < 1.5 and before > 10.0  # noise floors: down to about the noise


@pytest.mark.slow
def test_a_concealed_pendulum_drag_is_discovered_with_its_coefficient(tmp_path, dask_scheduler):
    space = _generator("pendulum").make("drag", tmp_path / "drag")
    found = _diagnose(space, dask_scheduler, "theta", "angle", PENDULUM_RANGES)
    assert isinstance(found, Discovered), found.reason
    (effect,) = found.effects()
    assert (effect["target"], list(effect["terms"])) == ("pendulum.der(w)", ["w*abs(w)"])
    low, high = effect["intervals"]["w*abs(w)"]
    assert low <= -0.125 <= high  # the generator's truth: der(w) += -0.08 / (1 kg · 0.8² m²) · w·|w|
    before, after = found.held_out
    assert after < 1.5 and after < 0.5 * before


@pytest.mark.slow
def test_recordings_with_nothing_concealed_discover_nothing(tmp_path, dask_scheduler):
    space = _generator("msd").make("none", tmp_path / "none")
    found = _diagnose(space, dask_scheduler, "x", "position", MSD_RANGES)
    assert isinstance(found, NotDiscovered)
    assert found.to_json()["effects"] == [] and found.reason


# ---- the parts, without a cluster --------------------------------------------------------------------------


def test_the_library_offers_terms_on_physics_not_on_kinematics(tmp_path):
    space = load_space(_generator("msd").make("none", tmp_path / "none"))
    (instance,) = model_exchange_instances(space.plan)
    assert (instance.states, instance.derivatives, instance.inputs) == (
        ("x", "v"),
        ("der(x)", "der(v)"),
        ("F",),
    )
    plan = space.plan.recording(instance.recorded)
    runs = [
        simulate(plan, s, {"msd.k": 12.0}, objectives={}, experiment=space.experiment).outputs
        for s in space.scenarios
    ]
    terms = candidate_terms(instance, runs)
    assert {t.target for t in terms} == {"msd.der(v)"}  # der(x) = v on every run: a definition
    texts = {t.term.text for t in terms}
    assert {"1", "x", "x^3", "x^2*v", "v*abs(v)", "F*abs(F)"} <= texts
    assert any(text.startswith("tanh(v/") for text in texts)
    assert all(t.scale > 0 and math.isfinite(t.scale) for t in terms)


def test_the_proposal_finds_the_sparse_columns_and_ignores_what_the_fit_already_covers():
    rng = np.random.default_rng(3)
    rows, runs = 200, 4
    run = np.repeat(np.arange(runs), rows)
    fitted = rng.normal(size=(rows * runs, 1))
    terms = rng.normal(size=(rows * runs, 5))
    terms[:, 4] = 2.0 * fitted[:, 0]  # a term that only repeats the fitted parameter
    target = 3.0 * terms[:, 1] - 1.5 * terms[:, 3] + 0.7 * fitted[:, 0] + rng.normal(0.0, 0.1, rows * runs)
    names = tuple(f"t{k}" for k in range(5))
    proposal = propose(
        Regression(target, terms, fitted, run, names), max_terms=3, bootstrap=20, inclusion=0.7, seed=0
    )
    assert set(proposal.terms) == {"t1", "t3"} and "t4" in proposal.dropped
    assert proposal.terms["t1"] == pytest.approx(3.0, rel=0.05) and proposal.terms["t3"] == pytest.approx(
        -1.5, rel=0.05
    )
    noise_only = propose(Regression(rng.normal(size=rows * runs), terms, fitted, run, names), 3, 20, 0.7, 0)
    assert noise_only.empty


def test_cosimulation_models_are_told_that_only_their_signals_can_be_corrected():
    space = load_space(REPO / "jobs" / "watertank" / "space.yaml")
    fit = FitResult("none", [], {}, 1.0, 1, 0, True, {}, [], {})
    found = discover_derivatives(space, None, explain.Candidate((), fit), [], {}, [])
    assert isinstance(found, NotDiscovered)
    assert "no model-exchange instance" in found.reason and "points inside them" in found.reason


@pytest.mark.slow
def test_diagnose_space_names_the_cubic_spring_inside_the_model_over_its_look_alike(tmp_path, dask_scheduler):
    """The whole command's path: the space (a grid calibration), a signal effect and two terms inside the
    model that both stiffen a spring (x³ and x·|x|), each fitted by simulating the whole model; the answer
    carries the cubic, in words, and the diagnosed values replay it. Only those three hypotheses are tried
    (--hypothesis), so that the test stays short."""
    from dse_runner.analysis.diagnose.signal_library import diagnose_space
    from dse_runner.simulation.values import read_values

    space = _generator("msd").make("cubic", tmp_path / "cubic")
    cubic, square = "derivative_term(msd.der(v), x^3)", "derivative_term(msd.der(v), x*abs(x))"
    result = diagnose_space(
        space, out=tmp_path / "out", address=dask_scheduler, only=["output_offset(msd.x)", cubic, square]
    )
    found = result.to_json()
    terms = [e for e in found["effects"] if e.get("term")]
    assert [(e["target"], e["term"], e["law"]) for e in terms] == [("msd.der(v)", "x^3", "cubic")], found[
        "candidates"
    ]
    low, high = terms[0]["interval"]["coefficient"]
    assert low <= -60.0 <= high
    assert terms[0]["readable"][0].startswith("der(msd.v) += −k3·x^3: a spring that hardens, k3 = ")
    assert (
        found["verdict"] in ("discovered", "partial")
        and found["held_out_after"] < 0.2 * found["held_out_before"]
    )
    assert found["validation"] == {"by": "scenarios", "folds": 3, "record": None}
    values = read_values(found["files"]["values"])
    assert values[cubic] == pytest.approx(terms[0]["parameters"]["coefficient"])
    assert all(Path(f).is_file() for f in found["files"]["figures"]) and len(found["files"]["figures"]) == 4
