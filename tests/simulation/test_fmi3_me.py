"""An FMI 3.0 model-exchange FMU (tests/fmus/msd3, built with the me3.c layer) runs through our
master's model-exchange path and matches FMPy's own ME simulation and the FMI 2.0 msd."""

from __future__ import annotations

import zipfile

import fmpy
import numpy as np
from conftest import REPO
from fmpy.validation import validate_fmu

from dse_runner import simulate
from dse_runner.simulation import build
from dse_runner.simulation.build import build_fmu
from dse_runner.simulation.run import as_plan

MSD3 = REPO / "tests" / "fmus" / "msd3"
MSD2 = REPO / "jobs" / "msd" / "fmus" / "msd"
VALUES = {"k": 14.0, "c": 0.8}


def x_of(result) -> np.ndarray:
    (name,) = [n for n in result.trajectory.names if n.endswith(".x")]
    return result.trajectory.column(name)


def test_msd3_builds_with_the_fmi3_me_layer():
    assert build.layer_of(MSD3) is build.ME3
    path = build_fmu(MSD3)
    assert validate_fmu(str(path)) == []
    with zipfile.ZipFile(path) as fmu:
        names = set(fmu.namelist())
    assert {"binaries/x86_64-linux/msd3.so", "sources/model.c", "sources/me3.c", "sources/me3.h"} <= names
    assert not names & {"sources/slave3.c", "sources/me2.c", "sources/slave.c"}


def test_fmi3_me_matches_fmpy_and_the_fmi2_msd():
    path = build_fmu(MSD3)
    plan = as_plan(path)
    assert set(plan.interfaces.values()) == {"me"} and len(plan.interfaces) == 1
    result = simulate(path, stop_time=5, step=0.01, values=VALUES)
    x = x_of(result)
    reference = fmpy.simulate_fmu(str(path), stop_time=5, output_interval=0.01, start_values=VALUES)
    assert len(x) == len(reference) == 501
    np.testing.assert_allclose(result.time, reference["time"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(x, reference["x"], rtol=0, atol=1e-9)
    fmi2 = x_of(simulate(build_fmu(MSD2), stop_time=5, step=0.01, values=VALUES))
    np.testing.assert_allclose(x, fmi2, rtol=0, atol=1e-6)
    assert abs(x).max() > 0.05 and abs(x[-1]) < abs(x[0])  # it oscillates and decays


def test_fmi3_me_runs_are_repeatable():
    """The master reuses instances (fmi3Reset restores the start values)."""
    path = build_fmu(MSD3)
    first = x_of(simulate(path, stop_time=2, step=0.01, values=VALUES))
    default = x_of(simulate(path, stop_time=2, step=0.01))
    again = x_of(simulate(path, stop_time=2, step=0.01, values=VALUES))
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first, default)
