"""A multi-model checked against its FMUs: the :class:`Plan` the master (cosim.py) runs.

:func:`make_plan` resolves a multi-model against its FMUs' model descriptions, once: every
``instance.variable`` named in connections and values is checked (unknown names get close matches
suggested), each connection's conversion is fixed by the rules of variables.py, and value
references are looked up. Everything downstream (running, lifecycle probes, sweeps) takes a plan.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..errors import DseError, close_names, did_you_mean
from . import fmu as fmus
from .build import resolve_fmu
from .multimodel import MultiModel
from .variables import (
    Conversion,
    Variable,
    check_settable,
    check_value,
    conversion,
    describe_variable,
    split_ref,
    with_article,
)


@dataclass(frozen=True)
class Link:
    """A connection, resolved: which output feeds which input, converted how."""

    source: Variable
    target: Variable
    conversion: Conversion = field(default_factory=Conversion)


@dataclass(frozen=True)
class Plan:
    """A multi-model whose every name has been checked against its FMUs."""

    multimodel: MultiModel
    fmu_paths: dict[str, Path]
    interfaces: dict[str, str]  # instance -> "cs" | "me"
    variables: dict[str, dict[str, Variable]]  # instance -> name -> variable, read once
    models: dict[str, str]  # instance -> model name, for messages
    outputs: dict[str, tuple[Variable, ...]]  # numeric variables recorded, per instance
    texts: dict[str, tuple[Variable, ...]]  # string outputs recorded, per instance
    links: tuple[Link, ...]
    defaults: tuple[float | None, float | None, float | None] = (None, None, None)  # one FMU's experiment
    # the variables looked up so far: a sweep looks up the same names at every run (a mutable cache, not
    # part of what the plan is: each copy starts its own)
    _found: dict[str, Variable] = field(default_factory=dict, init=False, repr=False, compare=False)

    @functools.cached_property
    def recorded(self) -> tuple[str, ...]:
        return tuple(v.ref for vs in self.outputs.values() for v in vs)

    @property
    def connections(self) -> tuple[tuple[Variable, Variable], ...]:
        return tuple((link.source, link.target) for link in self.links)

    def variable(self, ref: str, purpose: str) -> Variable:
        variable = self._found.get(ref)
        if variable is None:
            variable = self._found[ref] = lookup(self.variables, self.models, ref, purpose)
        return variable

    @functools.cached_property
    def fed_by(self) -> dict[str, str]:
        """Input -> the output a connection sets it from at every step (``instance.variable`` both)."""
        return {link.target.ref: link.source.ref for link in self.links}

    def check_not_fed(self, variable: Variable) -> None:
        """An input a connection feeds takes no value: the connection overwrites it before the first step.
        (Checked at every run's values: anything but an input is passed at once.)"""
        source = self.fed_by.get(variable.ref) if variable.causality == "input" else None
        if source is not None:
            raise DseError(
                f"{variable.ref} is fed by the connection from {source}, which overwrites a value given to "
                "it; give one to what feeds it instead"
            )

    def recording(self, refs: Iterable[str], purpose: str = "objective") -> Plan:
        """The plan also recording ``refs`` (e.g. a local variable an objective reads)."""
        outputs = {name: list(vs) for name, vs in self.outputs.items()}
        for ref in refs:
            variable = self.variable(ref, purpose)
            if variable.family == "string" or not variable.numeric:
                raise DseError(
                    f"{purpose}: {ref!r} is {with_article(variable.type)}, not a number one can score"
                )
            if variable not in outputs[variable.instance]:
                outputs[variable.instance].append(variable)
        return replace(self, outputs={name: tuple(vs) for name, vs in outputs.items()})


def lookup(
    variables: dict[str, dict[str, Variable]], models: dict[str, str], ref: str, purpose: str
) -> Variable:
    """Resolve ``instance.variable``; the error names it and suggests near names."""
    try:
        instance, name = split_ref(ref)
    except ValueError as e:
        raise DseError(f"{purpose}: {e}{_instance_hint(variables, ref)}") from None
    if instance not in variables:
        raise DseError(
            f"{purpose}: {ref!r} names instance {instance!r}, but the multi-model has "
            f"{', '.join(sorted(variables))}{did_you_mean(instance, variables)}"
        )
    variable = variables[instance].get(name)
    if variable is None:
        raise DseError(
            f"{purpose}: unknown variable {ref!r}: instance {instance!r} ({models[instance]}) "
            f"has no variable {name!r}{did_you_mean(name, variables[instance])}"
        )
    return variable


def _instance_hint(variables: dict[str, dict[str, Variable]], name: str) -> str:
    """For a variable named without its instance: the instances' variables it may mean."""
    refs = [f"{instance}.{v}" for instance, vs in variables.items() for v in vs]
    exact = [ref for ref in refs if ref.split(".", 1)[1] == name]
    if exact:
        return f" (did you mean {', '.join(exact[:3])}?)"
    close = [f"{instance}.{v}" for instance, vs in variables.items() for v in close_names(name, vs, 1)]
    return f" (did you mean {', '.join(close[:3])}?)" if close else ""


# ---- planning ------------------------------------------------------------------------------------


def _fmu_file(multimodel: MultiModel, name: str) -> Path:
    """The FMU an instance names, built if it is a source folder; an error names the instance."""
    try:
        return resolve_fmu(multimodel.fmu_path(name))
    except DseError as e:
        raise DseError(f"instance {name!r} of the multi-model names {multimodel.fmus[name]!r}: {e}") from None


def make_plan(multimodel: MultiModel, interface: str | None = None) -> Plan:
    """Build FMUs if needed and check every name the multi-model uses. ``interface`` ("cs" or "me")
    overrides every instance's."""
    fmu_paths = {name: _fmu_file(multimodel, name) for name in multimodel.fmus}
    descriptions = {name: fmus.describe(path) for name, path in fmu_paths.items()}
    interfaces = {
        name: fmus.choose_interface(fmu_paths[name], d, interface or multimodel.settings(name).interface)
        for name, d in descriptions.items()
    }
    variables = {
        name: {v.name: describe_variable(name, v) for v in d.modelVariables}
        for name, d in descriptions.items()
    }
    models = {name: d.modelName for name, d in descriptions.items()}
    outputs = {
        name: tuple(v for v in vs.values() if v.causality == "output" and v.numeric)
        for name, vs in variables.items()
    }
    texts = {
        name: tuple(v for v in vs.values() if v.causality == "output" and v.family == "string")
        for name, vs in variables.items()
    }
    links = _links(multimodel, variables, models)
    for ref in multimodel.scenario:
        check_settable(lookup(variables, models, ref, "scenario"))
    for ref, value in multimodel.parameters.items():
        check_value(lookup(variables, models, ref, "parameters"), value)
    defaults = _defaults(next(iter(descriptions.values())) if len(descriptions) == 1 else None)
    return Plan(multimodel, fmu_paths, interfaces, variables, models, outputs, texts, links, defaults)


def _links(multimodel: MultiModel, variables, models) -> tuple[Link, ...]:
    links, fed = [], {}
    for source_ref, target in multimodel.targets():
        source = lookup(variables, models, source_ref, "connection")
        if source.causality != "output":
            raise DseError(
                f"connection: {source_ref!r} must be an output (it is {with_article(source.causality)})"
            )
        sink = lookup(variables, models, target.input, "connection")
        if sink.causality != "input":
            raise DseError(
                f"connection {source_ref} -> {target.input}: the target must be an input "
                f"(it is {with_article(sink.causality)})"
            )
        if target.input in fed:
            raise DseError(
                f"connection: input {target.input!r} is fed by both {fed[target.input]} and {source_ref}"
            )
        fed[target.input] = source_ref
        links.append(Link(source, sink, conversion(source, sink, target.round, target.threshold)))
    return tuple(links)


def _defaults(description) -> tuple[float | None, float | None, float | None]:
    """A single FMU's default experiment: start, stop and step, where it gives them."""
    experiment = description.defaultExperiment if description is not None else None
    if experiment is None:
        return (None, None, None)

    def number(text) -> float | None:
        return float(text) if text not in (None, "") else None

    return number(experiment.startTime), number(experiment.stopTime), number(experiment.stepSize)
