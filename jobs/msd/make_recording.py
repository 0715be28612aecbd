"""Make the mass-spring-damper's "measured" position: recording/position.csv.

The truth is the msd FMU (fmus/msd) at m = 1 kg, k = 14 N/m, c = 0.8 N s/m,
x0 = 0.1 m, v0 = 0 m/s, F = 0 N: released from 0.1 m, it rings down at about
0.6 Hz. The FMU's defaults are k = 10 and c = 0.5, so a design-space
exploration over k and c against this recording should recover k = 14 and
c = 0.8 (within what the noise allows).

The position is sampled every 0.05 s from 0 to 10 s and Gaussian noise of
sigma 2 mm (a fixed seed, so the file is reproducible) is added, like a
position sensor's. Run with dse-runner importable, e.g. from the repository:
``PYTHONPATH=. python jobs/msd/make_recording.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from fmpy import simulate_fmu

from dse_runner.simulation.build import build_fmu

HERE = Path(__file__).resolve().parent
TRUTH = {"m": 1.0, "k": 14.0, "c": 0.8, "x0": 0.1, "v0": 0.0}
SAMPLE_INTERVAL = 0.05  # s
DURATION = 10.0  # s
NOISE_SIGMA = 0.002  # m
SEED = 20240611


def simulate_truth() -> tuple[np.ndarray, np.ndarray]:
    """The noise-free position at the sample times, solved far tighter than the noise."""
    fmu = build_fmu(HERE / "fmus" / "msd")
    result = simulate_fmu(
        str(fmu),
        stop_time=DURATION,
        solver="CVode",
        relative_tolerance=1e-9,
        output_interval=SAMPLE_INTERVAL,
        start_values=TRUTH,
        output=["x"],
    )
    return result["time"], result["x"]


def main() -> None:
    time, x = simulate_truth()
    noisy = x + np.random.default_rng(SEED).normal(0.0, NOISE_SIGMA, size=x.shape)
    target = HERE / "recording" / "position.csv"
    target.parent.mkdir(exist_ok=True)
    rows = "".join(f"{t:.2f},{value:.5f}\n" for t, value in zip(time, noisy))
    target.write_text("time,x\n" + rows)
    print(f"wrote {target}: {len(time)} samples, truth {TRUTH}, noise sigma {NOISE_SIGMA} m")


if __name__ == "__main__":
    main()
