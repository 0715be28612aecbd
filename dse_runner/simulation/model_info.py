"""What a model offers, named as every command names it: ``dse-runner describe MODEL``.

Why: first contact with an FMU is the question "what can I set and what can I score?". FMPy's
``fmpy info`` answers it for one archive with the FMU's own names; a study needs the names a space, a
values file and ``--set`` use (``instance.variable``, the instance named after the file), for an
``.fmu``, a source folder or a multi-model alike, with what the master may set (parameters, inputs,
outputs whose start is settable) told apart from what it records, and from the inputs a connection
sets at every step, whatever a value set before would say.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from pydantic import BaseModel

from .fmu import describe
from .plan import Plan
from .run import as_plan
from .variables import Variable


class VariableInfo(BaseModel):
    """One variable as ``--set``, a space's parameters and its objectives name it."""

    name: str  # instance.variable
    causality: str
    type: str
    start: str | None = None
    unit: str | None = None
    description: str | None = None
    settable: bool  # the master may set it before initialisation (a parameter, an unconnected input, a start)
    fed_by: str | None = None  # a connected input: the output the master sets it from at every step


class InstanceInfo(BaseModel):
    """One instance of the model: its FMU and the variables a study uses."""

    instance: str
    fmu: str
    model_name: str
    fmi_version: str
    interface: str  # cs or me, as the master runs it
    start_time: float | None = None  # the FMU's default experiment
    stop_time: float | None = None
    step: float | None = None
    variables: list[VariableInfo]


SHOWN = ("parameter", "calculatedParameter", "input", "output")  # locals and independents: only on request


def model_info(model: str | Path | Plan, every: bool = False) -> list[InstanceInfo]:
    """Each instance's parameters, inputs and outputs (``every``: all its variables)."""
    plan = as_plan(model)
    fed = plan.fed_by
    found = []
    for instance, path in plan.fmu_paths.items():
        description = describe(Path(path))
        experiment = description.defaultExperiment
        variables = [
            VariableInfo(
                name=f"{instance}.{v.name}",
                causality=v.causality,
                type=v.type,
                start=None if v.start is None else str(v.start),
                unit=_unit(v),
                description=v.description or None,
                settable=_settable(plan.variables[instance].get(v.name), fed),
                fed_by=fed.get(f"{instance}.{v.name}"),
            )
            for v in description.modelVariables
            if every or v.causality in SHOWN
        ]
        found.append(
            InstanceInfo(
                instance=instance,
                fmu=str(path),
                model_name=description.modelName,
                fmi_version=description.fmiVersion,
                interface=plan.interfaces[instance],
                start_time=_number(experiment, "startTime"),
                stop_time=_number(experiment, "stopTime"),
                step=_number(experiment, "stepSize"),
                variables=variables,
            )
        )
    return found


def _settable(variable: Variable | None, fed: Mapping[str, str]) -> bool:
    """A parameter, an input no connection feeds, or a variable whose start may be set."""
    if variable is None or variable.ref in fed:
        return False
    return variable.causality in ("parameter", "input") or variable.start


def _unit(variable) -> str | None:
    unit = variable.unit or (variable.declaredType.unit if variable.declaredType is not None else None)
    return unit or None


def _number(experiment, field: str) -> float | None:
    value = getattr(experiment, field, None) if experiment is not None else None
    return None if value in (None, "") else float(value)
