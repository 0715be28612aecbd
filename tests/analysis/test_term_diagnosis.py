"""Terms inside a model, found by simulating it: a term a model-exchange FMU's equations lack (jobs/msd's
generator conceals a hardening spring) is named by the whole command's path, over its look-alike; and what a
model-exchange instance offers terms (derivatives.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from conftest import REPO

from dse_runner.analysis.diagnose.derivatives import kinematic_pairs, model_exchange_instances, observe
from dse_runner.sweeps.spec import load_space


def _generator(job: str):
    """A job's make_discovery_runs.py, imported from its file."""
    spec = importlib.util.spec_from_file_location(
        f"{job}_discovery", REPO / "jobs" / job / "make_discovery_runs.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_an_instance_offers_terms_on_physics_not_on_kinematics(tmp_path):
    """The msd's states, derivatives and input as terms see them; der(x) = v on every run is a definition,
    so no term goes on it."""
    space = load_space(_generator("msd").make("none", tmp_path / "none"))
    (instance,) = model_exchange_instances(space.plan)
    assert (instance.states, instance.derivatives, instance.inputs) == (
        ("x", "v"),
        ("der(x)", "der(v)"),
        ("F",),
    )
    runs = observe(space, {"msd.k": 12.0}, [instance])
    assert len(runs) == len(space.scenarios)
    assert kinematic_pairs(instance, runs) == {"x": "v"}


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
