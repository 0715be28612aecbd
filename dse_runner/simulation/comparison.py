"""What the dashboard and the report show of one simulation next to its scenario's recording.

A scenario's kind may say (field data: the simulated track over the GPS
fixes, x against y); otherwise it is the signal the ranking objective reads,
against time, over the recorded column it is compared with if any.
"""

from __future__ import annotations

import numpy as np

from . import objectives as objs
from .scenario import Comparison, Simulated, kind


def compare(result: Simulated, objective: objs.ObjectiveSpec | None = None) -> Comparison:
    """The kind's comparison, or the objective's signal over time."""
    own = kind(result.scenario.kind).compare(result)
    if own is not None:
        return own
    signal = objective.signal if isinstance(objective, (objs.Reduce, objs.Fit)) else None
    signal = signal or (result.trajectory.names[0] if result.trajectory.names else None)
    if signal is None:
        return Comparison(None, (result.time, np.zeros_like(result.time)), "time [s]", "no numeric output")
    recorded = None
    if isinstance(objective, objs.Fit) and result.scenario.recorded is not None:
        recorded = result.scenario.recorded.samples(objective.recorded)
    return Comparison(recorded, (result.time, result.trajectory.column(signal)), "time [s]", signal)
