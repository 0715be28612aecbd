"""Writes plants.yaml: the robustness set of the control study, drawn from the diagnosis.

    python jobs/robotti-control/make_plants.py [--plants 5]
        [--diagnosis docs/diagnosis-robotti/diagnosis.json]

Each controller point is scored on every path over a few plants: vehicles whose mass and wheel
slip are drawn, by a Latin hypercube with a fixed seed, from the ~95 % intervals that
`dse-runner diagnose` fitted on the recorded runs (its diagnosis.json, "fitted"). The other
parameters stay at their fitted values in multimodel.yaml. The space files name plants.yaml as
their scenarios' `variants`.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import yaml
from scipy.stats import qmc

HERE = Path(__file__).resolve().parent
VARIED = ("vehicle.mass", "vehicle.wheel_slip")
SEED = 1


def plants(fitted: dict, n: int) -> list[dict]:
    """n plants spread over the intervals of the VARIED parameters."""
    lows = [fitted["interval"][ref][0] for ref in VARIED]
    highs = [fitted["interval"][ref][1] for ref in VARIED]
    samples = qmc.scale(qmc.LatinHypercube(d=len(VARIED), seed=SEED).random(n), lows, highs)
    return [
        {"name": f"plant{i + 1}", "parameters": {ref: float(f"{v:.6g}") for ref, v in zip(VARIED, row)}}
        for i, row in enumerate(samples)
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--diagnosis", type=Path, default=HERE.parents[1] / "docs" / "diagnosis-robotti" / "diagnosis.json"
    )
    parser.add_argument("--plants", type=int, default=5)
    args = parser.parse_args()
    fitted = json.loads(args.diagnosis.read_text())["fitted"]
    header = (
        f"# Written by make_plants.py: {args.plants} plants, mass and wheel slip drawn (Latin "
        f"hypercube, seed {SEED}) from the\n# ~95 % intervals of {args.diagnosis.name}: "
        + ", ".join(
            f"{ref} [{fitted['interval'][ref][0]:.6g}, {fitted['interval'][ref][1]:.6g}]" for ref in VARIED
        )
        + "\n"
    )
    (HERE / "plants.yaml").write_text(header + yaml.safe_dump(plants(fitted, args.plants), sort_keys=False))


if __name__ == "__main__":
    main()
