"""The vanderpol FMU of the master-overhead benchmark (benchmarks/fmus/vanderpol) computes what its
model.c says: forward Euler at 1e-2 s on the Van der Pol equations, whoever drives it.

Our master and FMPy's simulate_fmu agree on it, and both agree with the same Euler recurrence written
here with numpy, to 1e-12 over its whole default experiment (0..20 s, 2000 steps).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import REPO
from fmpy import simulate_fmu

from dse_runner.simulation.build import build_fmu
from dse_runner.simulation.run import simulate

VANDERPOL = REPO / "benchmarks" / "fmus" / "vanderpol"
STOP, STEP = 20.0, 1e-2  # its DefaultExperiment, and its internal Euler step
TOLERANCE = 1e-12


@pytest.fixture(scope="module")
def fmu() -> Path:
    return build_fmu(VANDERPOL)


def euler(mu: float, x0: float = 2.0, x1: float = 0.0, n: int = 2000, h: float = STEP) -> np.ndarray:
    """x0, x1 at every step of forward Euler on der(x0) = x1, der(x1) = mu (1 - x0^2) x1 - x0."""
    states = np.empty((n + 1, 2))
    states[0] = x0, x1
    for k in range(n):
        der_x0 = x1
        der_x1 = mu * ((1.0 - x0 * x0) * x1) - x0
        x0, x1 = x0 + h * der_x0, x1 + h * der_x1
        states[k + 1] = x0, x1
    return states


def ours(fmu: Path, mu: float) -> np.ndarray:
    result = simulate(fmu, values={"mu": mu}, stop_time=STOP, step=STEP)
    (x0,) = [v for name, v in result.outputs.items() if name.endswith(".x0")]
    (x1,) = [v for name, v in result.outputs.items() if name.endswith(".x1")]
    assert len(result.time) == 2001 and result.time[-1] == pytest.approx(STOP)
    return np.column_stack([x0, x1])


def fmpy_trajectory(fmu: Path, mu: float) -> np.ndarray:
    result = simulate_fmu(
        str(fmu),
        stop_time=STOP,
        step_size=STEP,
        output_interval=STEP,
        start_values={"mu": mu},
        output=["x0", "x1"],
    )
    return np.column_stack([result["x0"], result["x1"]])


@pytest.mark.parametrize("mu", [1.0, 1.5])
def test_master_fmpy_and_euler_agree(fmu, mu):
    mine, theirs, expected = ours(fmu, mu), fmpy_trajectory(fmu, mu), euler(mu)
    assert theirs.shape == mine.shape == expected.shape
    np.testing.assert_allclose(mine, theirs, rtol=0, atol=TOLERANCE)
    np.testing.assert_allclose(mine, expected, rtol=0, atol=TOLERANCE)


def test_default_experiment_and_start_values(fmu):
    """Unset, it runs the Reference FMU's experiment: 0..20 s by 1e-2 s from x0 = 2, x1 = 0, mu = 1."""
    result = simulate(fmu)
    assert (result.times.start, result.times.stop, result.times.step) == (0.0, STOP, STEP)
    trajectory = np.column_stack(list(result.outputs.values()))  # x0, x1: the outputs in declared order
    np.testing.assert_allclose(trajectory, euler(1.0), rtol=0, atol=TOLERANCE)


def test_mu_changes_the_trajectory(fmu):
    assert np.max(np.abs(ours(fmu, 1.0) - ours(fmu, 1.5))) > 0.1
