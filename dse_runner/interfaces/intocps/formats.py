"""INTO-CPS's file formats, read as they are (convert.py makes them a space).

An INTO-CPS project keeps a DSE config ``DSEs/<name>/<name>.dse.json``, a
multi-model ``Multi-models/<mm>/<mm>.mm.json`` (or ``mm.json``) and a
co-simulation config ``Multi-models/<mm>/<config>/<config>.coe.json``. The
mm.json is read where every multi-model is (simulation/multimodel.py,
``from_into_cps``); the two others are these pydantic models, the single
source of truth for what dse-runner reads from them.
docs/research/intocps-formats.md records where each field was learnt from
INTO-CPS's own sources. Names follow INTO-CPS's JSON keys, so the models read
like the files. Ids are ``{fmuKey}.instance.variable``
(multimodel.split_into_cps_id takes one apart).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    field_validator,
)

from ...errors import DseError, format_validation_error
from ...schema import Extensible, Strict
from ...simulation.variables import FiniteValue

Loose = Extensible  # INTO-CPS writes keys we read past (graphs, livestream...)


class IntoCpsWarning(UserWarning):
    """Something of the INTO-CPS files that dse-runner does differently; the message says what."""


# ---- *.dse.json ------------------------------------------------------------------------------------


class Algorithm(BaseModel):
    """``{"type": "exhaustive"}`` or ``{"type": "genetic", ...options}``; missing or ``{}`` is exhaustive."""

    model_config = Loose
    type: str = "exhaustive"

    @property
    def options(self) -> dict[str, Any]:
        return dict(self.model_extra or {})


class InternalFunction(BaseModel):
    """An objective INTO-CPS computes itself: max, min or mean of one results column."""

    model_config = Strict
    columnID: str
    objectiveType: Literal["max", "min", "mean"]


def _portable(path: str | None) -> str | None:
    """Projects made on Windows write paths with ``\\``; they name the same files here with ``/``."""
    return path.replace("\\", "/") if path is not None else None


class ExternalScript(BaseModel):
    """A user's Python script in ``userMetricScripts/``; its parameters are passed in key order."""

    model_config = Strict
    scriptFile: Annotated[str, AfterValidator(_portable)]
    scriptParameters: dict[str, str] = {}

    @field_validator("scriptParameters", mode="before")
    @classmethod
    def _as_text(cls, value: Any) -> Any:
        """INTO-CPS passes every parameter as text on the command line."""
        return {str(k): str(v) for k, v in value.items()} if isinstance(value, dict) else value


class ObjectiveDefinitions(BaseModel):
    model_config = Strict
    internalFunctions: dict[str, InternalFunction] = {}
    externalScripts: dict[str, ExternalScript] = {}


class DseConfig(BaseModel):
    """A ``*.dse.json``."""

    model_config = Loose  # e.g. "simulation", which INTO-CPS itself ignores (the coe.json decides)
    algorithm: Algorithm = Algorithm()
    parameters: dict[str, Annotated[list[FiniteValue], Field(min_length=1)]]
    parameterConstraints: list[str] = []
    objectiveDefinitions: ObjectiveDefinitions = ObjectiveDefinitions()
    objectiveConstraints: list[str] = []
    ranking: dict[str, dict[str, Literal["+", "-"]]] = {}  # {"pareto": {objective: "-" (min) | "+" (max)}}
    scenarios: list[str] = []  # folders of userMetricScripts/ handed to the external scripts
    geneticArguments: dict[str, Any] | None = None

    @field_validator("objectiveConstraints", mode="before")
    @classmethod
    def _empty_object(cls, value: Any) -> Any:
        """INTO-CPS writes an empty ``{}`` as often as ``[]``."""
        return [] if value == {} else value

    @field_validator("algorithm", mode="before")
    @classmethod
    def _empty_algorithm(cls, value: Any) -> Any:
        return {} if value is None else value


# ---- *.coe.json ------------------------------------------------------------------------------------


class FixedStep(BaseModel):
    model_config = Loose
    type: Literal["fixed-step"]
    size: float = Field(gt=0)


class VariableStep(BaseModel):
    """INTO-CPS's variable-step algorithm; dse-runner steps at a fixed size and says so."""

    model_config = Loose
    type: Literal["var-step"]
    initsize: float = Field(gt=0)
    size: tuple[float, float]
    constraints: dict[str, Any] = {}


def _step_kind(value: Any) -> str | None:
    kind = value.get("type") if isinstance(value, dict) else getattr(value, "type", None)
    return kind if kind in ("fixed-step", "var-step") else None


StepAlgorithm = Annotated[
    Annotated[FixedStep, Tag("fixed-step")] | Annotated[VariableStep, Tag("var-step")],
    Discriminator(
        _step_kind,
        custom_error_type="algorithm",
        custom_error_message="expected {type: fixed-step, size} or {type: var-step, initsize, size}",
    ),
]


class CoeConfig(BaseModel):
    """A ``*.coe.json``: the experiment's times and step, and (in newer files) where the mm.json is."""

    model_config = Loose
    startTime: float = 0.0
    endTime: float
    algorithm: StepAlgorithm
    # relative to the project; older files do not have it
    multimodel_path: Annotated[str | None, AfterValidator(_portable)] = None


def read_json(path: str | Path) -> Any:
    """An INTO-CPS file's JSON; errors name the file (and the line and column)."""
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except OSError as e:
        raise DseError(f"cannot read {path}: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise DseError(f"{path} line {e.lineno}, column {e.colno}: not JSON: {e.msg}") from None


def read(path: str | Path, model: type[BaseModel]) -> Any:
    """One INTO-CPS file, validated; errors name the file, the key path and the reason."""
    data = read_json(path)
    try:
        return model.model_validate(data)
    except ValidationError as e:
        raise DseError(format_validation_error(str(path), e)) from None
