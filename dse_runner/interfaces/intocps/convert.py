"""An INTO-CPS DSE (dse.json + mm.json + coe.json) made one of our space specs.

What maps to what (docs/intocps.md has the table and the differences):

* ``parameters`` ``{fmu}.instance.variable: [values]`` -> ``instance.variable: [values]``;
* ``parameterConstraints`` (Python expressions) -> our constraint language, ids
  made ``instance.variable``; an expression outside it is an error naming it;
* ``internalFunctions`` max/min/mean -> ``{signal, reduce: max|min|sample_mean}``
  (INTO-CPS's mean is that of the samples);
* ``externalScripts`` -> script objectives (simulation/scripts.py), same
  calling convention, ``userMetricScripts/`` of the project;
* ``objectiveConstraints`` -> ``ranking.constraints``; ``ranking.pareto`` ->
  ``ranking.pareto`` (``-`` min, ``+`` max);
* ``scenarios`` -> one scenario each, with ``userMetricScripts/<name>/`` as
  its data folder (the scripts' third argument);
* ``algorithm`` exhaustive -> the grid; genetic -> ``genetic`` (one objective)
  or ``nsga2`` (a Pareto ranking of two or more);
* the coe.json's start, end and step -> ``experiment``;
* the mm.json -> the multi-model, inline.

Paths in the spec are written relative to ``base``, the folder the spec will
be read from, so a converted space.yaml runs where it is written.
"""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path
from typing import Any

from ...errors import DseError
from ...simulation.multimodel import from_into_cps, into_cps_instances, split_into_cps_id
from ...sweeps.constraints import compile_constraint
from ...sweeps.spec import SpaceSpec
from .formats import CoeConfig, DseConfig, FixedStep, IntoCpsWarning, VariableStep, read, read_json
from .project import Located

# an id as INTO-CPS writes it in an expression: {fmu}.instance.variable (variables may hold dots)
ID = re.compile(r"\{[^{}\s]+\}\.[A-Za-z_]\w*\.[A-Za-z_][\w.]*")
MM_KEYS = {"fmus", "connections", "parameters"}  # what the application writes; the COE takes more
INTERNAL = {"max": "max", "min": "min", "mean": "sample_mean"}
ALGORITHMS = ("exhaustive", "genetic")
GENERATIONS = 10  # a genetic search's default budget, in populations, when the DSE sets none


def _relative(path: Path, base: Path) -> str:
    return os.path.relpath(path.resolve(), base.resolve())


def _ours(ref: str, where: str) -> str:
    try:
        return ".".join(split_into_cps_id(ref)[1:])
    except DseError as e:
        raise DseError(f"{where}: {e}") from None


def translate_expression(text: str, names: set[str], what: str, where: str) -> str:
    """A Python expression of INTO-CPS made one of our constraint language, or an error naming it."""
    ours = ID.sub(lambda m: _ours(m.group(0), where), text)
    try:
        compile_constraint(ours, names, what)
    except DseError as e:
        raise DseError(
            f"{where}: cannot translate {text!r} into dse-runner's constraint language: "
            f"{str(e).removeprefix(f'constraint {ours!r}: ')}"
        ) from None
    return ours


def experiment(coe: CoeConfig, path: Path) -> dict[str, float]:
    """The coe.json's times and fixed step; a variable step becomes its initial size, with a warning."""
    step = coe.algorithm.size if isinstance(coe.algorithm, FixedStep) else _fixed(coe.algorithm, path)
    return {"start_time": coe.startTime, "stop_time": coe.endTime, "step": step}


def _fixed(algorithm: VariableStep, path: Path) -> float:
    low, high = algorithm.size
    step = min(max(algorithm.initsize, low), high)
    dropped = f" and its constraints ({', '.join(algorithm.constraints)})" if algorithm.constraints else ""
    warnings.warn(
        f"{path}: the variable-step algorithm becomes a fixed step of {step:g} s (its initsize); "
        f"its size range [{low:g}, {high:g}]{dropped} are not applied",
        IntoCpsWarning,
        stacklevel=2,
    )
    return step


def multimodel(path: Path, base: Path) -> tuple[dict[str, Any], dict[str, str]]:
    """Our multi-model, inline, with FMU paths relative to ``base``; and instance -> FMU key."""
    data = read_json(path)
    if not isinstance(data, dict) or "fmus" not in data:
        raise DseError(f"{path}: not an INTO-CPS multi-model (no 'fmus')")
    unknown = sorted(set(data) - MM_KEYS)
    if unknown:
        warnings.warn(
            f"{path}: {', '.join(unknown)} ignored (co-simulation engine settings)",
            IntoCpsWarning,
            stacklevel=2,
        )
    try:
        ours = from_into_cps({k: data[k] for k in MM_KEYS if k in data}, path.parent)
    except DseError as e:
        raise DseError(f"{path}: {str(e).removeprefix('mm.json: ')}") from None
    for instance, fmu in ours["fmus"].items():
        found = Path(fmu) if Path(fmu).is_absolute() else path.parent / fmu
        if not found.exists():
            raise DseError(
                f"{path}: FMU of {instance} not found: {fmu} (INTO-CPS looks in the project's FMUs folder)"
            )
        ours["fmus"][instance] = _relative(found, base)
    return ours, into_cps_instances(data)


def objectives(dse: DseConfig, located: Located, base: Path, logged: list[str]) -> dict[str, dict[str, Any]]:
    """Internal functions and external scripts, in the DSE's order; ``logged``: the ids INTO-CPS's
    results.csv has besides those the scripts are given (the connected outputs)."""
    where = f"{located.dse}: objectiveDefinitions"
    found: dict[str, dict[str, Any]] = {}
    for name, function in dse.objectiveDefinitions.internalFunctions.items():
        if not function.columnID.startswith("{"):
            raise DseError(
                f"{where}.internalFunctions.{name}: column {function.columnID!r} is not a model "
                "variable; dse-runner reduces {fmu}.instance.variable columns"
            )
        found[name] = {
            "signal": _ours(function.columnID, f"{where}.internalFunctions.{name}"),
            "reduce": INTERNAL[function.objectiveType],
        }
    for name, script in dse.objectiveDefinitions.externalScripts.items():
        path = located.scripts / script.scriptFile
        if not path.is_file():
            raise DseError(f"{where}.externalScripts.{name}: script not found: {path}")
        args = [script.scriptParameters[key] for key in sorted(script.scriptParameters)]  # INTO-CPS's order
        ids = dict.fromkeys([*logged, *(a for a in args if a.startswith("{"))])
        found[name] = {
            "script": _relative(path, base),
            "args": args,
            "columns": {i: _ours(i, f"{where}.externalScripts.{name}") for i in ids},
        }
    if not found:
        raise DseError(f"{where}: define at least one objective (internalFunctions or externalScripts)")
    return found


def ranking(dse: DseConfig, names: list[str], path: Path) -> dict[str, Any]:
    """INTO-CPS ranks by a Pareto front of at most two objectives, ``-`` minimised and ``+`` maximised."""
    unknown = sorted(set(dse.ranking) - {"pareto"})
    if unknown:
        raise DseError(
            f"{path}: ranking {unknown[0]!r} is not a ranking INTO-CPS or dse-runner knows (pareto)"
        )
    pareto = [
        {"objective": n, "goal": "min" if sign == "-" else "max"}
        for n, sign in dse.ranking.get("pareto", {}).items()
    ]
    for entry in pareto:
        if entry["objective"] not in names:
            raise DseError(
                f"{path}: ranking.pareto names {entry['objective']!r}, which objectiveDefinitions "
                f"does not define ({', '.join(names)})"
            )
    constraints = [
        translate_expression(text, set(names), "objective", f"{path}: objectiveConstraints.{i}")
        for i, text in enumerate(dse.objectiveConstraints)
    ]
    first = pareto[0] if pareto else {"objective": names[0], "goal": "min"}
    return {
        **first,
        **({"pareto": pareto} if len(pareto) > 1 else {}),
        **({"constraints": constraints} if constraints else {}),
    }


def scenarios(dse: DseConfig, located: Located, base: Path, scripted: bool) -> list[dict[str, Any]]:
    """One scenario per name; the scripts' data folder is ``userMetricScripts/<name>``. A scenario
    changes no simulation in INTO-CPS, only what the scripts read."""
    found = []
    for name in dse.scenarios or [""]:
        scenario: dict[str, Any] = {"name": re.sub(r"[^A-Za-z0-9_.-]", "_", name) or "nominal"}
        data = located.scripts / name
        if scripted and data.is_dir():
            scenario["data"] = _relative(data, base)
        elif scripted and name:
            warnings.warn(
                f"{located.dse}: scenario {name!r} has no data folder {data}; its scripts get an empty one",
                IntoCpsWarning,
                stacklevel=2,
            )
        found.append(scenario)
    return found


def search(dse: DseConfig, pareto: bool, path: Path, points: int) -> dict[str, Any]:
    """exhaustive: the grid; genetic: ``genetic``, or ``nsga2`` for a Pareto
    ranking, with INTO-CPS's options."""
    kind = dse.algorithm.type
    if kind not in ALGORITHMS:
        raise DseError(
            f"{path}: algorithm {kind!r} is not one INTO-CPS or dse-runner runs ({', '.join(ALGORITHMS)})"
        )
    if kind == "exhaustive":
        return {}
    options = {**dse.algorithm.options, **(dse.geneticArguments or {})}
    population = int(options.get("initialPopulation") or options.get("popSize") or 20)
    mutation = options.get("mutationChance")
    if mutation is None and options.get("mutationProbability"):
        mutation = float(options["mutationProbability"]) / 100  # the application's is a percentage
    generations = int(options.get("maxGenerations") or GENERATIONS)
    settings: dict[str, Any] = {"max_points": min(population * generations, points)}
    if pareto:
        settings.update(
            strategy="nsga2",
            population_size=population,
            **({"mutation_prob": mutation} if mutation is not None else {}),
        )
    else:
        settings.update(
            strategy="genetic",
            population=population,
            **({"mutation_probability": mutation} if mutation is not None else {}),
        )
        without = options.get("maxGenerationsWithoutImprovement")
        if without:
            settings["max_generations_without_improvement"] = int(without)
    used = {
        "initialPopulation",
        "popSize",
        "mutationChance",
        "mutationProbability",
        "maxGenerations",
        "maxGenerationsWithoutImprovement",
        "initialPopulationDistribution",
        "parentSelectionStrategy",
    }
    ignored = sorted(set(options) - used)
    if ignored:
        warnings.warn(
            f"{path}: genetic options {', '.join(ignored)} have no counterpart in {settings['strategy']}; "
            "ignored",
            IntoCpsWarning,
            stacklevel=2,
        )
    return settings


def _values(values: list[Any], dse: DseConfig) -> list[Any] | dict[str, float]:
    """A list of choices; in the Python 3 scripts' genetic format (``geneticArguments``), ``[min, max]``."""
    if (
        dse.geneticArguments is not None
        and len(values) == 2
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
    ):
        return {"low": min(values), "high": max(values)}
    return values


def _points(parameters: dict[str, Any]) -> int:
    """How many points the grid has (a search over an interval: no limit)."""
    count = 1
    for values in parameters.values():
        count *= len(values) if isinstance(values, list) else 10**9
    return count


def to_spec(located: Located, base: Path) -> SpaceSpec:
    """The space spec equivalent to the located DSE, paths relative to ``base``."""
    dse = read(located.dse, DseConfig)
    coe = read(located.coe, CoeConfig)
    model, fmu_keys = multimodel(located.multimodel, base)
    where = located.dse
    parameters = {
        _ours(ref, f"{where}: parameters"): _values(values, dse) for ref, values in dse.parameters.items()
    }
    constraints = [
        translate_expression(text, set(parameters), "parameter", f"{where}: parameterConstraints.{i}")
        for i, text in enumerate(dse.parameterConstraints)
    ]
    logged = [f"{fmu_keys[s.split('.')[0]]}.{s}" for s in model["connections"] if s.split(".")[0] in fmu_keys]
    scored = objectives(dse, located, base, logged)
    ranked = ranking(dse, list(scored), where)
    scripted = bool(dse.objectiveDefinitions.externalScripts)
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", located.dse.name.removesuffix(".json").removesuffix(".dse"))
    return SpaceSpec.model_validate(
        {
            "name": name,
            "multimodel": model,
            "experiment": experiment(coe, located.coe),
            "scenarios": scenarios(dse, located, base, scripted),
            "parameters": parameters,
            "constraints": constraints,
            "objectives": scored,
            "ranking": ranked,
            "search": search(dse, "pareto" in ranked, where, _points(parameters)),
            "origin": {"format": "intocps", "path": _relative(located.dse, base), "fmu_keys": fmu_keys},
        }
    )
