"""One simulation of a model on a scenario, scored: the unit of work a sweep repeats.

``simulate(model)`` takes an ``.fmu`` file, a multi-model file or object, or a
checked :class:`~dse_runner.simulation.plan.Plan`. Values come in layers, later ones
winning: the multi-model's parameters, the scenario's bound fields
(multi-model ``scenario:``), the scenario's parameters and constant inputs,
then ``values`` (a sweep's parameter point). Times follow experiment.py.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import DseError, did_you_mean
from . import derivative_terms, signal_effects, state_limits
from . import objectives as objs
from .build import is_source_dir
from .cosim import Runner, prepare
from .experiment import Experiment, Times, resolve_times
from .fmu import describe
from .lifecycle import Verdict, needs_process, plan_verdicts
from .multimodel import MultiModel, load_multimodel, single_fmu
from .plan import Plan, make_plan
from .scenario import Scenario, kind, load_scenario, nominal
from .trajectory import Series, Trajectory
from .variables import Value, split_ref


@dataclass(frozen=True)
class SimulationResult:
    scenario: Scenario
    values: dict[str, Value]
    times: Times
    trajectory: Trajectory
    objectives: dict[str, float | list[float]]
    lifecycle: dict[str, Verdict] = field(default_factory=dict)  # how each instance was run (lifecycle.py)
    notes: tuple[str, ...] = ()  # what of the scenario's recording was left uncompared (recording_notes)

    @property
    def fresh_process(self) -> bool:
        """Whether the run had a process of its own (an FMU could not be trusted with reuse)."""
        return needs_process(self.lifecycle)

    @property
    def step(self) -> float:
        return self.times.step

    @property
    def time(self) -> np.ndarray:
        return self.trajectory.time

    @property
    def outputs(self) -> dict[str, np.ndarray]:
        return self.trajectory.outputs


def load_model(path: str | Path) -> MultiModel:
    """The model a path names: an ``.fmu`` file or an FMU source folder (one instance, named after the file:
    the same name in every command and space), or a multi-model file."""
    return single_fmu(path) if _is_one_fmu(Path(path)) else load_multimodel(path)


def as_plan(model: Plan | MultiModel | str | Path, interface: str | None = None) -> Plan:
    """A checked plan from an ``.fmu`` file, an FMU source folder (built on first use), a multi-model
    file or object, or a plan."""
    if isinstance(model, Plan):
        return model
    if not isinstance(model, MultiModel):
        model = load_model(model)
    return make_plan(model, interface)


def _is_one_fmu(path: Path) -> bool:
    """An ``.fmu`` file or an FMU's C sources; a missing ``.fmu`` is an error that says how one is made."""
    if path.suffix.lower() == ".fmu":
        if not path.exists():
            raise DseError(
                f"FMU not found: {path} (`dse-runner build-fmus SOURCES --out DIR` makes .fmu files "
                "from FMU source folders, and a source folder can be given instead of an .fmu)"
            )
        return True
    return path.is_dir() and is_source_dir(path)


def qualify(plan: Plan, ref: str) -> str:
    """``mass`` -> ``model.mass`` when the plan has one instance and ``ref`` names none of its; ``Model.mass``
    stays as it is, for the lookup to say that the instance is ``model`` (a variable's name may hold dots)."""
    if len(plan.variables) == 1:
        instance, variables = next(iter(plan.variables.items()))
        try:
            named = split_ref(ref)[0]
        except ValueError:
            named = None
        misspelt = named is not None and named.casefold() == instance.casefold() and ref not in variables
        if named != instance and not misspelt:
            return f"{instance}.{ref}"
    return ref


Correction = (
    derivative_terms.DerivativeTerm | state_limits.StateLimit
)  # what the master changes in ME equations


def checked_term(plan: Plan, term: Correction) -> Correction:
    """``term`` (a derivative term or a state limit) with its instance (the plan's only one when the name
    leaves it out), checked: a model-exchange instance with those states and the variables the term reads."""
    instance = term.instance
    if instance is None:
        if len(plan.variables) != 1:
            named = replace(term, instance=next(iter(plan.variables)))
            raise DseError(f"{term.name}: name the instance, e.g. {named.name}")
        instance = next(iter(plan.variables))
    if instance not in plan.variables:
        raise DseError(
            f"{term.name}: the multi-model has no instance {instance!r} "
            f"(it has {', '.join(sorted(plan.variables))})"
        )
    term = replace(term, instance=instance)
    description = describe(plan.fmu_paths[instance])
    if isinstance(term, state_limits.StateLimit):
        state_limits.check(term, instance, plan.interfaces[instance], derivative_terms.states_of(description))
    else:
        derivative_terms.check(term, instance, plan.interfaces[instance], description)
    return term


def by_instance(terms: Mapping[Correction, float]) -> dict[str, dict]:
    """Derivative terms and state limits grouped by the instance they correct."""
    grouped: dict[str, dict] = {}
    for term, value in terms.items():
        grouped.setdefault(term.instance, {})[term] = value
    return grouped


def as_scenario(scenario: Scenario | str | Path | None) -> Scenario:
    if scenario is None:
        return nominal()
    return scenario if isinstance(scenario, Scenario) else load_scenario(scenario)


def default_objectives(scenario: Scenario, plan: Plan | None = None) -> dict[str, objs.ObjectiveSpec]:
    """What a scenario's kind scores when nothing is asked (field data: the GPS objectives); a kind that
    scores nothing of its own, with a recording, compares every recorded column that names an output of
    ``plan`` (``tanks.y``, or ``y`` when exactly one instance outputs a ``y``): ``<column>_rmse``. So a
    model simulated on a new record says at once how well it predicts it. A recording none of whose
    columns names an output is an error saying what it has and what was looked for: a run that compares
    nothing must not pass for one that compared (issue 63)."""
    found = objs.normalise(list(kind(scenario.kind).default_objectives))
    if found or scenario.recorded is None or plan is None:
        return found
    matched, _ = recorded_outputs(scenario, plan)
    if not matched:
        raise DseError(_compared_nothing(scenario, plan))
    return {
        f"{column}_rmse": objs.Fit(signal=ref, recorded=column, metric="rmse")
        for column, ref in matched.items()
    }


def recorded_outputs(scenario: Scenario, plan: Plan) -> tuple[dict[str, str], dict[str, list[str]]]:
    """The recorded columns that name one output of ``plan`` (``instance.variable``, or the variable alone
    when one instance outputs it), each with that output; and those whose bare name several instances
    output, with theirs."""
    matched: dict[str, str] = {}
    several: dict[str, list[str]] = {}
    if scenario.recorded is None:
        return matched, several
    for column in scenario.recorded.columns:
        named = [ref for ref in plan.recorded if ref == column or ref.split(".", 1)[1] == column]
        if len(named) == 1:
            matched[column] = named[0]
        elif named:
            several[column] = named
    return matched, several


def output_names(plan: Plan) -> list[str]:
    """The outputs as a recorded column may name them: one FMU's by the variable alone."""
    bare = len(plan.variables) == 1
    return [ref.split(".", 1)[1] if bare else ref for ref in plan.recorded]


MAX_LISTED = 12  # outputs listed in a message; describe lists them all


def _listed(names: list[str]) -> str:
    shown = ", ".join(names[:MAX_LISTED]) or "none"
    return shown + (
        f", ... ({len(names)} in all: dse-runner describe lists them)" if len(names) > MAX_LISTED else ""
    )


def _columns_said(scenario: Scenario, plan: Plan, columns: list[str]) -> str:
    """Columns, each with the outputs it may have meant, or the instances' outputs it cannot choose from."""
    _, several = recorded_outputs(scenario, plan)
    options = output_names(plan) if len(plan.variables) == 1 else [*plan.recorded, *output_names(plan)]
    said = []
    for column in columns:
        if column in several:
            said.append(f"{column} (output by {' and '.join(several[column])}: name which)")
        else:
            said.append(column + did_you_mean(column, options))
    return ", ".join(said)


def _compared_nothing(scenario: Scenario, plan: Plan) -> str:
    """Why a recording compares with no output, and how to make it compare."""
    recording = scenario.recorded
    columns = list(recording.columns)
    example = f"{{signal: {plan.recorded[0]}, recorded: {columns[0]}, metric: rmse}}" if plan.recorded else ""
    how = (
        f"; rename a column as the output it records, or name the comparison: --objective '{example}' "
        "(objectives= in Python)"
        if example
        else "; the model has no numeric output to compare"
    )
    return (
        f"scenario {scenario.name}: no column of its recording {recording.path.name} names an output of the "
        f"model, so nothing would be compared: it has {_columns_said(scenario, plan, columns)}; the outputs "
        f"looked for are {_listed(output_names(plan))}{how}"
    )


def recording_notes(
    scenario: Scenario, specs: Mapping[str, objs.ObjectiveSpec], plan: Plan, asked: bool
) -> tuple[str, ...]:
    """What of a scenario's recording the run leaves uncompared, said as warnings: with the default
    comparison, the columns that name no output (the others were compared); with objectives ``asked`` for
    (or a space's), a recording none of them reads. A kind that scores its own recording (field data), and
    an objective that is a function or a script, which may read the recording itself, leave nothing to say."""
    recording = scenario.recorded
    if recording is None or kind(scenario.kind).default_objectives:
        return ()
    outputs = _listed(output_names(plan))
    if not asked:
        matched, _ = recorded_outputs(scenario, plan)
        unread = [column for column in recording.columns if column not in matched]
        if not unread:
            return ()
        said = (
            f"scenario {scenario.name}: recorded {_columns_said(scenario, plan, unread)} named no output of "
            f"the model, so {'it was' if len(unread) == 1 else 'they were'} not compared (the outputs are "
            f"{outputs})"
        )
        return (said,)
    if not all(isinstance(spec, objs.Reduce) for spec in specs.values()):
        return ()
    said = (
        f"scenario {scenario.name}: its recording {recording.path.name} is compared by no objective (those "
        f"that ran, {', '.join(specs) or 'none'}, read no recorded column); it has "
        f"{_columns_said(scenario, plan, list(recording.columns))}, the outputs are {outputs}"
    )
    return (said,)


def bound_fields(multimodel: MultiModel, scenario: Scenario) -> dict[str, Value]:
    """The values the multi-model's ``scenario:`` section takes from this scenario; a field the
    scenario lacks is an error naming the binding."""
    bound = {}
    for ref, name in multimodel.scenario.items():
        try:
            bound[ref] = scenario.value_of(name)
        except DseError as e:
            raise DseError(f"the multi-model binds {ref} to {name!r}: {e}") from None
    return bound


def scenario_values(plan: Plan, scenario: Scenario) -> dict[str, Value]:
    """The values a scenario gives: bound fields, its parameters and its constant inputs."""
    constants = {ref: v for ref, v in scenario.inputs.items() if not isinstance(v, Series)}
    return {**bound_fields(plan.multimodel, scenario), **scenario.parameters, **constants}


def simulate(
    model: Plan | MultiModel | str | Path,
    scenario: Scenario | str | Path | None = None,
    values: Mapping[str, Value] | None = None,
    start_time: float | None = None,
    stop_time: float | None = None,
    step: float | None = None,
    objectives: Mapping[str, objs.ObjectiveSpec] | list[str] | None = None,
    timeout: float | None = None,
    experiment: Experiment | None = None,
    interface: str | None = None,
    loop: str | None = None,
    fresh_process: bool = False,
) -> SimulationResult:
    """Co-simulate ``model`` on ``scenario`` (none: the nominal one) with ``values`` and score it.

    ``objectives`` default to those of the scenario's kind (none for a plain scenario); ``loop``
    chooses the master's step loop (cosim.run: native C, or the Python reference); ``fresh_process``
    runs it in a process of its own whatever lifecycle.py says of its FMUs, so that an FMU that crashes
    takes only that process down (a sweep's task that workers died under runs so). Called again with
    the same plan, scenario, objectives and experiment (a sweep), it reuses what it worked out from
    them: plans and scenarios are immutable; objectives and the experiment are compared by value."""
    recipe = _recipe(model, scenario, objectives, experiment, (start_time, stop_time, step), interface)
    given, terms = derivative_terms.split(values or {})
    given, limits = state_limits.split(given)
    terms = {**terms, **limits}
    given, effects = signal_effects.split(given)
    values = recipe.layered(given)
    runner = recipe.runner
    if terms:
        terms = {recipe.qualified_term(term): value for term, value in terms.items()}
        runner = runner.with_terms(by_instance(terms))
    if effects:
        effects = recipe.qualified_effects(effects)
        runner = runner.with_inputs(signal_effects.on_inputs(recipe.signals, runner.times, effects))
    verdicts = recipe.lifecycle(runner, values)
    if fresh_process:
        verdicts = dict.fromkeys(verdicts, Verdict("process", "asked for a process of its own"))
    trajectory = runner.run(values, timeout, loop, fresh_process=needs_process(verdicts))
    if effects:
        trajectory = trajectory.with_columns(
            signal_effects.on_outputs(trajectory.time, trajectory.column, effects)
        )
    return SimulationResult(
        recipe.scenario,
        {**values, **{e.name: v for e, v in effects.items()}, **{t.name: v for t, v in terms.items()}},
        recipe.times,
        trajectory,
        objs.evaluate(recipe.specs, trajectory, recipe.scenario),
        verdicts,
        recipe.notes,
    )


@dataclass
class _Recipe:
    """What simulate() works out from everything but the values: the same for every run of a sweep."""

    given: tuple  # the arguments it was made from (kept, so that their ids stay theirs)
    objectives: object  # copies of the objectives and experiment given, to notice one changed in place
    experiment: Experiment | None
    scenario: Scenario
    specs: dict[str, objs.ObjectiveSpec]
    base: dict[str, Value]  # the multi-model's parameters and the scenario's values
    times: Times
    runner: Runner
    names: dict[str, str] = field(default_factory=dict)  # a value's name as given -> as the plan has it
    checked: dict = field(default_factory=dict)  # a derivative term as given -> checked, its instance named
    verdicts: dict[str, Verdict] | None = None  # how each instance lives across runs, found at the first
    notes: tuple[str, ...] = ()  # what of the recording the objectives leave uncompared (recording_notes)

    def lifecycle(self, runner: Runner, values: Mapping[str, Value]) -> dict[str, Verdict]:
        """How each instance lives across the runs of this process (lifecycle.py): reset between runs, or
        a fresh process; decided at the first run, by its runner and values (an FMU that cannot run alone is
        measured with them), and kept for the recipe's every run: its FMUs stay the same whatever terms or
        input effects a run adds."""
        if self.verdicts is None:
            runner.check(values)  # a bad value is an error before any FMU is measured
            self.verdicts = plan_verdicts(runner, values)
        return self.verdicts

    @property
    def signals(self) -> dict[str, Series]:
        """The scenario's input signals, by the names the runner feeds them under."""
        return {ref: s for ref, s in self.scenario.inputs.items() if isinstance(s, Series)}

    def qualified_effects(
        self, effects: Mapping[signal_effects.Effect, float]
    ) -> dict[signal_effects.Effect, float]:
        """Effects with their targets as the plan and the scenario name them
        (one FMU's may be written bare)."""
        plan = self.runner.plan
        fed = {qualify(plan, ref): ref for ref in self.signals}
        out = {}
        for effect, value in effects.items():
            target = qualify(plan, effect.target)
            out[replace(effect, target=fed.get(target, target))] = value
        return out

    def qualified_term(self, term: Correction) -> Correction:
        """A derivative term with its instance named (one FMU's may be left out), checked against it (once: a
        sweep runs the same terms at many values)."""
        found = self.checked.get(term)
        if found is None:
            found = self.checked[term] = checked_term(self.runner.plan, term)
        return found

    def layered(self, values: Mapping[str, Value]) -> dict[str, Value]:
        """The run's values: ``base``, then ``values`` (module docstring)."""
        names, plan = self.names, self.runner.plan
        layered = dict(self.base)
        for ref, value in values.items():
            name = names.get(ref)
            if name is None:
                name = names[ref] = qualify(plan, ref)
            layered[name] = value
        return layered


_RECIPES: dict[tuple, _Recipe] = {}
KEEP_RECIPES = 16


def _recipe(model, scenario, objectives, experiment: Experiment | None, times: tuple, interface) -> _Recipe:
    """The recipe of these arguments: made anew unless the model is a plan and the scenario one too
    (files may have changed since)."""
    given = (model, scenario, objectives, experiment, interface)
    key = (*map(id, given), times)
    reusable = isinstance(model, Plan) and (scenario is None or isinstance(scenario, Scenario))
    kept = _RECIPES.get(key) if reusable else None
    if kept is not None and kept.objectives == objectives and kept.experiment == experiment:
        return kept
    plan = as_plan(model, interface)
    scenario = as_scenario(scenario)
    specs = objs.normalise(objectives) if objectives is not None else default_objectives(scenario, plan)
    specs = {name: _qualified(plan, spec) for name, spec in specs.items()}
    for spec in specs.values():
        if isinstance(spec, str):
            objs.checked(spec)  # a function that cannot take (trajectory, scenario) fails here, once
    notes = recording_notes(scenario, specs, plan, asked=objectives is not None)
    plan = _recording(plan, specs)
    base = {**plan.multimodel.parameters, **scenario_values(plan, scenario)}
    resolved = resolve_times(plan, scenario, experiment, *times)
    inputs = {ref: s for ref, s in scenario.inputs.items() if isinstance(s, Series)}
    runner = prepare(plan, resolved.start, resolved.stop, resolved.step, inputs)
    recipe = _Recipe(
        given,
        copy.deepcopy(objectives),
        copy.deepcopy(experiment),
        scenario,
        specs,
        base,
        resolved,
        runner,
        notes=notes,
    )
    if reusable:
        while len(_RECIPES) >= KEEP_RECIPES:
            _RECIPES.pop(next(iter(_RECIPES)))
        _RECIPES[key] = recipe
    return recipe


def _qualified(plan: Plan, spec: objs.ObjectiveSpec) -> objs.ObjectiveSpec:
    """A declared objective's signal as the trajectory names it (one FMU's may be written bare)."""
    if isinstance(spec, (objs.Reduce, objs.Fit)):
        return spec.model_copy(update={"signal": qualify(plan, spec.signal)})
    return spec


def _recording(plan: Plan, specs: Mapping[str, objs.ObjectiveSpec]) -> Plan:
    """The plan, also recording whatever signal an objective reads that is not an output."""
    wanted = [ref for spec in specs.values() for ref in objs.signals(spec)]
    missing = [ref for ref in wanted if ref not in plan.recorded]
    return plan.recording(missing) if missing else plan


def write_csv(result: SimulationResult, path: Path, bare: bool = False) -> Path:
    """Every recorded signal: ``time``, then a column per output, ``instance.variable`` (or, for a
    single FMU, its variable's own name)."""
    trajectory = result.trajectory.renamed(lambda n: n.partition(".")[2]) if bare else result.trajectory
    trajectory.to_csv(Path(path))
    return Path(path).resolve()


def summary(result: SimulationResult, bare: bool = False) -> dict:
    """What ``simulate --json`` prints: the run's settings, objectives, every output's final value, and
    the warnings the text prints on stderr (what of the recording was left uncompared)."""
    final = result.trajectory.final()
    stop = result.trajectory.stopped  # an FMU asked to end the run early: which, when, the message
    stopped = stop and {"instance": stop.instance, "time": stop.time, "message": stop.message}
    if bare:
        final = {name.partition(".")[2]: value for name, value in final.items()}
    return {
        "scenario": result.scenario.name,
        "start_time": result.times.start,
        "stop_time": result.times.stop,
        "step": result.times.step,
        "end_time": result.trajectory.end,  # what objectives and final values cover: stop_time, or the stop
        "stopped": stopped,
        "values": result.values,
        "objectives": result.objectives,
        "final": final,
        "dropouts": result.scenario.dropouts,
        "lifecycle": {name: {"mode": v.mode, "reason": v.reason} for name, v in result.lifecycle.items()},
        "warnings": list(result.notes),
    }
