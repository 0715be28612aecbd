"""The multi-model file: which FMUs, how they connect, which values they get.

Our YAML form::

    fmus:                      # instance name -> FMU: a .fmu or a source folder, relative to
      controller: bundled:fmus/replay_controller   # this file, or one dse-runner ships (bundled:)
      vehicle: my-fmus/vehicle.fmu
    connections:               # output -> [inputs]
      controller.velocity: [vehicle.velocity]
    parameters:                # fixed values
      vehicle.mass: 1500
    scenario:                  # values taken from each scenario
      controller.file: steering_inputs
      vehicle.theta0: initial_pose.theta
    track: {x: vehicle.x, y: vehicle.y}   # the outputs compared with GPS
    step: null                 # communication step [s]; default: the control log's period

INTO-CPS's ``mm.json`` (keys like ``{fmu}.instance.variable``) is read too and
converted into the same model, so the rest of the tool sees one format.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Any

import yaml
from pydantic import (BaseModel, BeforeValidator, ConfigDict, Field, PositiveFloat, ValidationError,
                      field_validator)

from . import bundled
from .errors import DseError, format_syntax_error, format_validation_error
from .scenario import ScenarioField

Value = float | int | bool | str


def _finite(value: Any) -> Any:
    """NaN and infinity are no value to give an FMU (checked before the union, for one clear message)."""
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{value} is not a finite number")
    return value


FiniteValue = Annotated[Value, BeforeValidator(_finite)]  # a value as files give it


def split_ref(ref: str) -> tuple[str, str]:
    """'vehicle.mass' -> ('vehicle', 'mass'); variable names may hold dots themselves."""
    instance, dot, variable = ref.partition(".")
    if not dot or not instance or not variable:
        raise ValueError(f"{ref!r} is not of the form instance.variable")
    return instance, variable


def _check_ref(ref: str) -> str:
    split_ref(ref)
    return ref


class TrackOutputs(BaseModel):
    """The FMU outputs that are the simulated position compared with GPS fixes."""

    model_config = ConfigDict(extra="forbid")
    x: str
    y: str

    @field_validator("x", "y")
    @classmethod
    def _refs(cls, ref: str) -> str:
        return _check_ref(ref)


class MultiModel(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    fmus: dict[str, str] = Field(min_length=1)
    connections: dict[str, list[str]] = {}
    parameters: dict[str, FiniteValue] = {}
    scenario: dict[str, ScenarioField] = {}
    track: TrackOutputs | None = None
    step: PositiveFloat | None = None
    # Relative FMU paths are relative to the file's folder; ``bundled:`` ones name the package's own.
    base_dir: Path = Field(default=Path("."), exclude=True)

    @field_validator("fmus")
    @classmethod
    def _instance_names(cls, fmus: dict[str, str]) -> dict[str, str]:
        for name in fmus:
            if not name or "." in name:
                raise ValueError(f"instance name {name!r} must be non-empty and contain no '.'")
        return fmus

    @field_validator("connections")
    @classmethod
    def _connection_refs(cls, connections: dict[str, list[str]]) -> dict[str, list[str]]:
        for source, targets in connections.items():
            _check_ref(source)
            for target in targets:
                _check_ref(target)
        return connections

    @field_validator("parameters", "scenario")
    @classmethod
    def _value_refs(cls, values: dict[str, Any]) -> dict[str, Any]:
        for ref in values:
            _check_ref(ref)
        return values

    def fmu_path(self, instance: str) -> Path:
        return bundled.resolve(self.fmus[instance], self.base_dir)


def from_into_cps(data: dict[str, Any]) -> dict[str, Any]:
    """Convert INTO-CPS's mm.json shape into our multi-model's fields."""

    def local(ref: str) -> tuple[str, str]:
        key, dot, rest = ref.partition("}.")
        if not ref.startswith("{") or not dot:
            raise DseError(f"mm.json: {ref!r} is not of the form {{fmu}}.instance.variable")
        instance, variable = split_ref(rest)
        fmu_key = key + "}"
        if fmu_key not in data.get("fmus", {}):
            raise DseError(f"mm.json: {ref!r} names FMU {fmu_key}, which 'fmus' does not list")
        instances.setdefault(instance, data["fmus"][fmu_key])
        return instance, variable

    instances: dict[str, str] = {}
    connections = {
        ".".join(local(src)): [".".join(local(dst)) for dst in dsts]
        for src, dsts in data.get("connections", {}).items()
    }
    parameters = {".".join(local(ref)): v for ref, v in data.get("parameters", {}).items()}
    ours = {k: v for k, v in data.items() if k in ("scenario", "track", "step")}
    return {"fmus": instances, "connections": connections, "parameters": parameters, **ours}


def is_into_cps(data: dict[str, Any]) -> bool:
    return any(str(k).startswith("{") for k in data.get("fmus", {}))


def parse_multimodel(data: Any, source: str, base_dir: Path) -> MultiModel:
    """Validate already-parsed multi-model data; errors name ``source`` and the key path."""
    if not isinstance(data, dict):
        raise DseError(f"{source}: expected a mapping with 'fmus', 'connections', 'parameters'")
    if is_into_cps(data):
        data = from_into_cps(data)
    try:
        return MultiModel.model_validate({**data, "base_dir": base_dir})
    except ValidationError as e:
        raise DseError(format_validation_error(source, e)) from None


def load_multimodel(path: str | Path) -> MultiModel:
    """Read a multi-model file: a path, or ``bundled:robotti/multimodel.yaml`` for one that ships with us."""
    path = bundled.bundled_path(str(path)) if bundled.is_bundled(path) else Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise DseError(f"cannot read multi-model {path}: {e.strerror}") from None
    try:
        data = json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as e:
        raise DseError(format_syntax_error(str(path), "JSON" if path.suffix == ".json" else "YAML", e)) from None
    return parse_multimodel(data, str(path), path.parent.resolve())
