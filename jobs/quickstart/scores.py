"""Objectives of our own for the quickstart's design study (docs/quickstart.md): a plain function of the
simulated trajectory, found beside the space without PYTHONPATH."""

import numpy as np


def overshoot(trajectory, scenario):
    """How far the mass swings past rest to the other side after its release [m]."""
    return float(max(0.0, -np.min(trajectory.column("msd.x"))))
