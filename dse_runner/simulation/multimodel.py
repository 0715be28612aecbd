"""The multi-model file: which FMUs, how they connect, which values they get.

Our YAML form (docs/multimodel.md)::

    fmus:                      # instance name -> FMU: a .fmu or a source folder, relative to
      controller: bundled:fmus/replay_controller   # this file, or one dse-runner ships (bundled:)
      vehicle: my-fmus/vehicle.fmu
    connections:               # output -> [inputs]; an input may say how to convert
      controller.velocity: [vehicle.velocity]
      ctrl.valve: [tank.valvecontrol]              # Boolean -> Real: 0/1
      plant.level: [{input: ctrl.level_int, round: true}]
    parameters:                # fixed values
      vehicle.mass: 1500
    scenario:                  # values each scenario supplies, by the scenario's field names
      controller.file: steering_inputs
      vehicle.theta0: initial_pose.theta
    instances:                 # how an instance runs, when not as it comes
      plant: {interface: me, solver: cvode, tolerance: 1.0e-6}
    step: null                 # communication step [s]; default: the experiment's or the scenario's

INTO-CPS's ``mm.json`` (keys like ``{fmu}.instance.variable``) is read too and
converted into the same model, so the rest of the tool sees one format.
"""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import (
    BaseModel,
    Discriminator,
    Field,
    PositiveFloat,
    Tag,
    ValidationError,
    field_validator,
)

from .. import bundled
from ..errors import DseError, format_syntax_error, format_validation_error
from ..schema import Strict
from ..yamlfile import shape
from .fmu import FmuWarning, model_identifiers
from .variables import FiniteValue, split_ref


def _check_ref(ref: str) -> str:
    split_ref(ref)
    return ref


class Target(BaseModel):
    """A connection's input with a conversion the rules do not make by themselves (docs/multimodel.md)."""

    model_config = Strict
    input: str
    round: bool = False  # a number feeding an integer: round to the nearest
    threshold: float | None = None  # a number feeding a Boolean: true above this

    @field_validator("input")
    @classmethod
    def _ref(cls, ref: str) -> str:
        return _check_ref(ref)


# An input's name, or {input, round | threshold}: a wrong mapping gets Target's messages only.
ConnectionTarget = Annotated[
    Annotated[Target, Tag("mapping")] | Annotated[str, Tag("scalar")],
    Discriminator(
        shape,
        custom_error_type="connection_target",
        custom_error_message="expected an input's name or {input, ...}",
    ),
]


class InstanceSettings(BaseModel):
    """How one instance runs: its interface, for model exchange the integrator, whether it is told the
    stop time, and whether it must run in a fresh process each time (docs/multimodel.md)."""

    model_config = Strict
    interface: Literal["cs", "me"] | None = None  # default: co-simulation when the FMU offers it
    solver: Literal["cvode", "euler"] = "cvode"  # model exchange: FMPy's CVode, or forward Euler
    tolerance: PositiveFloat | None = None  # relative tolerance (CVode; co-simulation FMUs get it too)
    euler_step: PositiveFloat | None = None  # euler: the integration step; default: the communication step
    set_stop_time: bool = (
        True  # tell the FMU when the experiment stops (FMPy's default); false: leave it open
    )
    lifecycle: Literal["auto", "process"] = "auto"  # process: a fresh process per run (lifecycle.py)


class MultiModel(BaseModel):
    model_config = Strict

    fmus: dict[str, str] = Field(min_length=1)
    connections: dict[str, list[ConnectionTarget]] = {}
    parameters: dict[str, FiniteValue] = {}
    scenario: dict[str, str] = {}  # instance.variable -> a field of each scenario
    instances: dict[str, InstanceSettings] = {}
    step: PositiveFloat | None = None
    # The step size an FMU is told at each communication point: "difference", the difference of two points,
    # as FMPy's simulate_fmu passes it; "nominal", the step itself, as INTO-CPS's master (Maestro) passes it
    # (an INTO-CPS mm.json's default). They differ in the last bit (0.4 - 0.30000000000000004 is
    # 0.09999999999999998), which some FMUs notice: Overture's older controllers refuse any step but
    # their period, and 20-sim's models place internal steps by it.
    step_sizes: Literal["difference", "nominal"] = "difference"
    # Relative FMU paths are relative to the file's folder; ``bundled:`` ones name the package's own.
    base_dir: Path = Field(default=Path("."), exclude=True)

    @field_validator("fmus")
    @classmethod
    def _instance_names(cls, fmus: dict[str, str]) -> dict[str, str]:
        for name in fmus:
            if not name or "." in name:
                raise ValueError(f"instance name {name!r} must be non-empty and contain no '.'")
        return {name: portable(path) for name, path in fmus.items()}  # a file written on Windows runs here

    @field_validator("connections")
    @classmethod
    def _connection_refs(cls, connections: dict[str, list[str | Target]]) -> dict[str, list[str | Target]]:
        for source, targets in connections.items():
            _check_ref(source)
            for target in targets:
                if isinstance(target, str):
                    _check_ref(target)
        return connections

    @field_validator("parameters", "scenario")
    @classmethod
    def _value_refs(cls, values: dict[str, Any]) -> dict[str, Any]:
        for ref in values:
            _check_ref(ref)
        return values

    @field_validator("instances")
    @classmethod
    def _settings_name_instances(
        cls, instances: dict[str, InstanceSettings], info
    ) -> dict[str, InstanceSettings]:
        unknown = sorted(set(instances) - set(info.data.get("fmus", {})))
        if unknown:
            raise ValueError(f"{', '.join(unknown)} is not an instance of 'fmus'")
        return instances

    def fmu_path(self, instance: str) -> Path:
        return bundled.resolve(self.fmus[instance], self.base_dir)

    def targets(self) -> list[tuple[str, Target]]:
        """Every connection as (source, target with its conversion options)."""
        return [
            (source, Target(input=t) if isinstance(t, str) else t)
            for source, targets in self.connections.items()
            for t in targets
        ]

    def settings(self, instance: str) -> InstanceSettings:
        return self.instances.get(instance) or InstanceSettings()


def split_into_cps_id(ref: str) -> tuple[str, str, str]:
    """INTO-CPS's ``{fmu}.instance.variable`` -> (``{fmu}``, instance,
    variable); the variable may hold dots."""
    key, dot, rest = ref.partition("}.")
    try:
        if not ref.startswith("{") or not dot:
            raise ValueError
        instance, variable = split_ref(rest)
    except ValueError:
        raise DseError(f"{ref!r} is not of the form {{fmu}}.instance.variable") from None
    return key + "}", instance, variable


def into_cps_instances(data: dict[str, Any]) -> dict[str, str]:
    """instance -> the ``{fmu}`` key it is named under, for every id of an mm.json. Our names drop the
    key (``instance.variable``), so an instance name may belong to one FMU key only."""
    keys: dict[str, str] = {}
    refs = [
        *data.get("connections", {}),
        *(t for ts in data.get("connections", {}).values() for t in ts),
        *data.get("parameters", {}),
    ]
    for ref in refs:
        try:
            fmu_key, instance, _ = split_into_cps_id(ref)
        except DseError as e:
            raise DseError(f"mm.json: {e}") from None
        if fmu_key not in data.get("fmus", {}):
            raise DseError(f"mm.json: {ref!r} names FMU {fmu_key}, which 'fmus' does not list")
        known = keys.setdefault(instance, fmu_key)
        if known != fmu_key:
            raise DseError(
                f"mm.json: instance {instance!r} belongs to two FMUs, {known} and {fmu_key}; "
                "dse-runner names variables instance.variable, so rename one instance"
            )
    return keys


def portable(path: str) -> str:
    """An FMU path with ``/`` for every ``\\``: INTO-CPS projects made on Windows name FMUs
    ``20-Sim\\MassSpringDamper2.fmu``, and no FMU file name holds a backslash."""
    return path.replace("\\", "/")


def _into_cps_fmu(path: str, base_dir: Path) -> str:
    """INTO-CPS keeps FMUs in the project's ``FMUs`` folder and names them relative to it. A file renamed
    since the multi-model was written is found by its model identifier or its name written otherwise
    (``-`` for ``_``, case), where that points at one FMU of the folder, with a warning."""
    path = portable(path)
    if Path(path).is_absolute():
        return path
    folders = [
        folder / "FMUs" for folder in (base_dir, *list(base_dir.parents)[:3]) if (folder / "FMUs").is_dir()
    ]
    for folder in folders:
        if (folder / path).exists():
            return str((folder / path).resolve())
    for folder in folders[:1]:
        renamed = _renamed(folder, Path(path).stem)
        if renamed is not None:
            warnings.warn(
                FmuWarning(
                    f"{path}: no such FMU in {folder}; using {renamed.relative_to(folder)}, "
                    "the one FMU there of that name or model identifier"
                ),
                stacklevel=2,
            )
            return str(renamed.resolve())
    return path


def _renamed(folder: Path, stem: str) -> Path | None:
    """The one FMU under ``folder`` whose file name or model identifier is ``stem`` written otherwise."""

    def key(name: str) -> str:
        return name.lower().replace("-", "").replace("_", "").replace(" ", "")

    found = {
        fmu for fmu in folder.rglob("*.fmu") if key(fmu.stem) == key(stem) or stem in model_identifiers(fmu)
    }
    return found.pop() if len(found) == 1 else None


def from_into_cps(data: dict[str, Any], base_dir: Path = Path(".")) -> dict[str, Any]:
    """Convert INTO-CPS's mm.json shape into our multi-model's fields."""
    keys = into_cps_instances(data)

    def local(ref: str) -> str:
        return ".".join(split_into_cps_id(ref)[1:])

    instances = {instance: _into_cps_fmu(data["fmus"][key], base_dir) for instance, key in keys.items()}
    connections = {
        local(src): [local(dst) for dst in dsts] for src, dsts in data.get("connections", {}).items()
    }
    parameters = {local(ref): v for ref, v in data.get("parameters", {}).items()}
    ours = {k: v for k, v in data.items() if k in ("scenario", "instances", "step", "step_sizes")}
    return {
        "fmus": instances,
        "connections": connections,
        "parameters": parameters,
        "step_sizes": "nominal",
        **ours,
    }


def is_into_cps(data: dict[str, Any]) -> bool:
    return any(str(k).startswith("{") for k in data.get("fmus", {}))


MODELS = "a model is an .fmu file, an FMU source folder, a multi-model YAML file or INTO-CPS's mm.json"


def not_a_model(path: Path, data: Any = None) -> str | None:
    """What ``path``, given where a model goes, is instead, when it is recognisably one of the other files
    a study has (a recording or signal CSV, a values file, a space, a scenario, INTO-CPS's other configs):
    one line saying what it is, what was expected, and where it goes. None for what may be a multi-model
    with mistakes in it, which validation words better."""
    if path.is_dir():
        if (path / "scenario.yaml").is_file():
            return f"{path}: a scenario folder, not a model ({MODELS}); give it with --scenario"
        return (
            f"{path}: a folder, not a model: no FMU source folder (modelDescription.xml beside C sources); "
            f"{MODELS}"
        )
    if path.suffix.lower() in (".csv", ".tsv") or (isinstance(data, str) and "," in data.partition(" ")[0]):
        header = _first_line(path)
        return (
            f"{path}: a CSV file (columns {header}), not a model ({MODELS}); a recording or input signals "
            "go in a scenario (recorded:, inputs:), given with --scenario"
        )
    if not isinstance(data, dict) or "fmus" in data:
        return None
    keys = set(map(str, data))
    if "multimodel" in keys:
        return f"{path}: a space.yaml, not a model ({MODELS}); its model is the one its 'multimodel' names"
    if "objectiveDefinitions" in keys or "parameterConstraints" in keys:
        return f"{path}: INTO-CPS's DSE config (dse.json), not a model ({MODELS}); dse-runner submit runs it"
    if "algorithm" in keys or "startTime" in keys or "multimodel_path" in keys:
        return f"{path}: INTO-CPS's co-simulation config (coe.json), not a model ({MODELS}); its mm.json is"
    if keys & {"recorded", "inputs", "stop_time", "kind"}:
        return f"{path}: a scenario.yaml, not a model ({MODELS}); give its folder with --scenario"
    if data and all("." in key and not isinstance(v, (dict, list)) for key, v in data.items()):
        return (
            f"{path}: a values file (instance.variable: value lines), not a model ({MODELS}); give it with "
            "--values beside the model"
        )
    return None


def _first_line(path: Path) -> str:
    try:
        with path.open(errors="replace") as file:
            return file.readline().strip()[:80]
    except OSError:
        return "unreadable"


def parse_multimodel(data: Any, source: str, base_dir: Path) -> MultiModel:
    """Validate already-parsed multi-model data; errors name ``source`` and the key path."""
    if not isinstance(data, dict):
        raise DseError(f"{source}: expected a mapping with 'fmus', 'connections', 'parameters'")
    if is_into_cps(data):
        data = from_into_cps(data, base_dir)
    try:
        return MultiModel.model_validate({**data, "base_dir": base_dir})
    except ValidationError as e:
        raise DseError(format_validation_error(source, e)) from None


def load_multimodel(path: str | Path) -> MultiModel:
    """Read a multi-model file: a path, or ``bundled:robotti/multimodel.yaml`` for one that ships with us."""
    path = bundled.bundled_path(str(path)) if bundled.is_bundled(path) else Path(path)
    if path.is_dir() or path.suffix.lower() in (".csv", ".tsv"):
        raise DseError(not_a_model(path))
    try:
        text = path.read_text()
    except OSError as e:
        raise DseError(f"cannot read multi-model {path}: {e.strerror}") from None
    except UnicodeDecodeError:
        raise DseError(
            f"{path}: not a multi-model: it is not text (a model is an .fmu file, an FMU source folder, "
            "a multi-model YAML file or INTO-CPS's mm.json)"
        ) from None
    try:
        data = json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as e:
        raise DseError(
            format_syntax_error(str(path), "JSON" if path.suffix == ".json" else "YAML", e)
        ) from None
    other = not_a_model(path, data)
    if other is not None:
        raise DseError(other)
    return parse_multimodel(data, str(path), path.parent.resolve())


def single_fmu(path: str | Path) -> MultiModel:
    """A multi-model of one FMU, its instance named after the file."""
    path = Path(path).resolve()
    name = re.sub(r"[^A-Za-z0-9_]", "_", path.stem) or "model"
    return MultiModel(fmus={name: str(path)}, base_dir=path.parent)
