"""What the Robotti's scenario kinds share (docs/robotti-model.md): a folder's scenario.yaml header, and the
option naming the outputs that are the simulated position. Field data (fielddata.py) and reference paths
(paths.py) both read these; the core never imports them."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, PositiveFloat

Finite = ConfigDict(extra="forbid", allow_inf_nan=False)


class Pose(BaseModel):
    model_config = Finite
    x: float
    y: float
    theta: float


class RunInfo(BaseModel):
    """The contents of a scenario folder's scenario.yaml."""

    model_config = Finite
    name: str
    group: str
    duration: PositiveFloat
    initial_pose: Pose


class Position(BaseModel):
    """The outputs that are the simulated position: ``{x: vehicle.x, y: vehicle.y}``."""

    model_config = ConfigDict(extra="forbid")
    x: str
    y: str
