"""What the Robotti's scenario kinds share (docs/robotti-model.md): a folder's scenario.yaml header, the
option naming the outputs that are the simulated position, how a folder is opened, and the kinds' views
of a result (:class:`TrackKind`: the simulated track over the reference). Field data (fielddata.py)
and reference paths (paths.py) both use these; the core never imports them."""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict, PositiveFloat, ValidationError

from ..errors import DseError, format_validation_error
from ..schema import Strict
from ..simulation.comparison import Comparison
from ..simulation.scenario import ScenarioKind


class Pose(BaseModel):
    model_config = Strict
    x: float
    y: float
    theta: float


class RunInfo(BaseModel):
    """The contents of a scenario folder's scenario.yaml."""

    model_config = Strict
    name: str
    group: str
    duration: PositiveFloat
    initial_pose: Pose

    @property
    def fields(self) -> dict[str, float]:
        """The scenario fields both kinds set from it: the run's length and where the vehicle starts."""
        pose = self.initial_pose
        return {
            "duration": self.duration,
            "initial_pose.x": pose.x,
            "initial_pose.y": pose.y,
            "initial_pose.theta": pose.theta,
        }


class Position(BaseModel):
    """The outputs that are the simulated position: ``{x: vehicle.x, y: vehicle.y}``."""

    model_config = ConfigDict(extra="forbid")
    x: str
    y: str


OptionsModel = TypeVar("OptionsModel", bound=BaseModel)


def open_folder(
    folder: str | Path, names: Sequence[str], options: Mapping[str, Any] | None, schema: type[OptionsModel]
) -> tuple[dict[str, Path], OptionsModel]:
    """A scenario folder's files ``names`` (resolved) by name, each checked present, and the space's
    options for it checked against ``schema``: both kinds refuse a missing folder or file, or a wrong
    option, in the same words, before any FMU reads a file."""
    folder = Path(folder).resolve()
    if not folder.is_dir():
        raise DseError(f"scenario folder not found: {folder}")
    files = {name: folder / name for name in names}
    for path in files.values():
        if not path.is_file():
            raise DseError(f"scenario {folder}: missing {path.name}")
    try:
        settings = schema.model_validate(dict(options or {}))
    except ValidationError as e:
        raise DseError(format_validation_error(f"scenario {folder}", e)) from None
    return files, settings


XY = tuple[np.ndarray, np.ndarray]


class TrackKind(ScenarioKind):
    """A Robotti kind: a run is a track in the plane, and both views of a result show the simulated
    track over the scenario's reference (the recorded GPS fixes, the path to follow). A subclass says
    what the two tracks are (:meth:`tracks`), how the reference is drawn and which objective
    simulate's title quotes."""

    reference_style: ClassVar[tuple[str, dict[str, Any]]]  # the reference's matplotlib format and keywords
    title_error: ClassVar[tuple[str, str]]  # the objective [m] simulate's title quotes, and its words

    @abstractmethod
    def tracks(self, result) -> tuple[XY, XY]:
        """The reference and the simulated position over the whole run, each as x and y [m]."""

    def draw(self, result, ax) -> bool:
        """simulate's plot: the simulated track and its start over the reference, equal axes."""
        reference, (x, y) = self.tracks(result)
        fmt, style = self.reference_style
        ax.plot(*reference, fmt, **style)
        ax.plot(x, y, "-", lw=1.6, color="tab:blue", label="simulated")
        ax.plot([x[0]], [y[0]], "o", color="tab:green", label="start")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        objective, words = self.title_error
        error = result.objectives.get(objective)
        ax.set_title(result.scenario.name + (f": {words} {error:.3f} m" if error is not None else ""))
        ax.grid(alpha=0.3)
        ax.legend(loc="best")
        return True

    def compare(self, result) -> Comparison:
        """The dashboard's and report's view: the simulated track over the reference."""
        reference, simulated = self.tracks(result)
        return Comparison(reference, simulated, "x [m]", "y [m]", equal_axes=True)
