"""Why no noise floor read from a recording alone can be right about coloured noise: one record, two truths.

    PYTHONPATH=. python3 benchmarks/coloured_noise.py [--rho 0.9] [--sigma 0.002] [--seed 1]

Issue 49 asked that the floor not collapse on coloured recordings (AR(1) noise with ρ = 0.9 read about 3.6×
too low). This builds one recording two ways and shows that the two ways are the same numbers:

* **A**: a smooth signal plus AR(1) *noise* of σ and ρ (a sensor whose errors are correlated): the right
  floor is σ;
* **B**: a process whose state wanders, the same smooth signal plus an Ornstein-Uhlenbeck *component of the
  process* (the AR(1) recurrence sampled: the commonest model of a slow random disturbance), recorded by a
  perfect sensor that rounds to the recording's decimals: the right floor is that rounding, step/√12.

The OU component is given the very realisation that A's noise has, so the two records agree to the last bit.
Any estimate computed from the record alone (differences, spectra, a variogram, a learned model) returns one
number for both, so it is wrong for one of them: at best (the geometric middle of the two right answers) by
√(σ / (step/√12)) for both, 83× for ρ = 0.9, σ = 2 mm and 6 decimals; the shipped estimate reads 0.24 σ, right
for neither. What can tell them apart is not the record but a model: if the model explains the record,
its residual shows whether what is left is white. That is what the diagnosis does (noise.whiteness, and a
verdict that is never `explained` over a residual that is not white), and why its floor states that it
assumes white noise (noise.NoiseEstimate.assumptions).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from dse_runner.analysis.diagnose.noise import estimate_noise, quantum_of

N, DT, DECIMALS = 2000, 0.05, 6


def ar1(rng: np.random.Generator, rho: float, sigma: float, n: int) -> np.ndarray:
    """AR(1) of stationary σ ``sigma`` and lag-1 correlation ``rho``: the
    Ornstein-Uhlenbeck process sampled."""
    w = rng.normal(0.0, sigma * math.sqrt(1 - rho**2), n)
    e = np.empty(n)
    e[0] = rng.normal(0.0, sigma)
    for k in range(1, n):
        e[k] = rho * e[k - 1] + w[k]
    return e


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rho", type=float, default=0.9)
    parser.add_argument("--sigma", type=float, default=0.002)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    t = np.arange(N) * DT
    smooth = 0.3 * np.sin(2 * np.pi * 0.05 * t) + 0.1 * np.sin(2 * np.pi * 0.13 * t + 1.0)
    disturbance = ar1(np.random.default_rng(args.seed), args.rho, args.sigma, N)
    record_a = np.round(
        smooth + disturbance, DECIMALS
    )  # A: signal + coloured sensor noise, written to 6 decimals
    process_b = smooth + disturbance  # B: the process itself wanders by the OU component ...
    record_b = np.round(process_b, DECIMALS)  # ... and a perfect sensor writes it to 6 decimals
    same = record_a.tobytes() == record_b.tobytes()
    estimate = estimate_noise(record_a)
    right_a, right_b = args.sigma, quantum_of(record_b) / math.sqrt(12.0)
    print(f"records A and B identical to the last bit: {same}")
    print(f"the floor read from the record (either): {estimate.sigma:.3g} ({estimate.method})")
    print(
        f"right floor for A (coloured sensor noise, ρ = {args.rho:g}): {right_a:.3g}; read/right = "
        f"{estimate.sigma / right_a:.2f}"
    )
    print(
        f"right floor for B (a wandering process, perfect sensor): {right_b:.3g}; read/right = "
        f"{estimate.sigma / right_b:.3g}"
    )
    print(
        f"any record-only estimate is wrong for A or for B by a factor of at least "
        f"{math.sqrt(right_a / right_b):.3g} (the geometric middle of the two right answers)"
    )


if __name__ == "__main__":
    main()
