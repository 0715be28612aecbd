"""The design-space spec (``space.yaml``): what to simulate, how to score and rank, where.

Loading checks everything that can be checked before a single task runs: the
file's shape (pydantic; errors give file, key path and reason), the scenario
globs and files, the constraint expressions, the objectives, and every FMU
variable the spec names against the FMUs' model descriptions.

A spec without ``scenarios`` runs its experiment once per point, as the one
scenario ``nominal``. Objectives a spec leaves out are its scenarios' kind's
(field data: the GPS objectives); the ranking objective it leaves out is the
first objective. The loaded :class:`Space` carries the spec with both filled
in, which is what a sweep saves beside its results.
"""

from __future__ import annotations

import functools
import glob
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import (
    BaseModel,
    Discriminator,
    Field,
    PositiveFloat,
    Tag,
    model_validator,
)

from .. import bundled
from ..errors import DseError, close_names
from ..schema import Extensible, Strict
from ..simulation import derivative_terms, signal_effects, state_limits, user_modules
from ..simulation import objectives as objs
from ..simulation.experiment import Experiment
from ..simulation.multimodel import MultiModel, parse_multimodel
from ..simulation.plan import Plan, make_plan
from ..simulation.run import bound_fields, checked_term, load_model, qualify
from ..simulation.scenario import Scenario, ScenarioSpec, kind, load_scenario, nominal, parse_scenario
from ..simulation.trajectory import Series
from ..simulation.variables import FiniteValue, check_value
from ..yamlfile import read_yaml, shape
from . import uncertainty
from .constraints import compile_constraint
from .domain import ParameterValues, Point, dimension
from .makers import Cluster
from .search import Problem, Search, Strategy, batch_of, parse_options, strategy
from .uncertainty import Robust, Uncertain

if TYPE_CHECKING:  # pandas and the store's pyarrow wait for a spec that reads: a bad one is named sooner
    import pandas as pd


class Variant(BaseModel):
    """One variant of every scenario of a source: ``{name: heavy, parameters: {vehicle.mass: 2000}}``."""

    model_config = Strict
    name: str = Field(pattern=r"^[A-Za-z0-9_.]+$")
    parameters: dict[str, FiniteValue] = Field(min_length=1)


class ScenarioSource(BaseModel):
    """Scenario folders: ``{path: runs/*, group: .., kind: .., variants:
    [..]}`` plus the kind's own options."""

    model_config = Extensible  # the rest goes to the kind
    path: str  # a folder or a glob of folders, relative to the spec
    group: str | None = None  # overrides the scenario's own group
    kind: str | None = None  # default: the first installed kind that recognises the folder
    # Each folder runs once per variant, as scenario <name>-<variant> with the variant's parameters on top of
    # its own: a design evaluated over several plants (a robust objective: ranking.over_scenarios max or
    # mean). A string is a YAML file holding the list, relative to the spec.
    variants: Annotated[
        Annotated[list[Variant], Tag("list")] | Annotated[str, Tag("scalar")],
        Discriminator(
            shape,
            custom_error_type="variants",
            custom_error_message="expected a list of {name, parameters} or a YAML file holding one",
        ),
    ] = []


def read_variants(path: Path) -> list[Variant]:
    """A variants file: a YAML list of ``{name, parameters}``; errors name the file."""
    return read_yaml(path, list[Variant], "variants file")


def varied(scenario: Scenario, variant: Variant) -> Scenario:
    """``scenario`` with ``variant``'s parameters, named for both."""
    return replace(
        scenario,
        name=f"{scenario.name}-{variant.name}",
        parameters={**scenario.parameters, **variant.parameters},
    )


def _source_or_inline(value: Any) -> str | None:
    if isinstance(value, str):
        return "folder"
    if isinstance(value, ScenarioSource) or (isinstance(value, Mapping) and "path" in value):
        return "source"
    return "inline" if shape(value) == "mapping" else None


# A folder (or glob), {path: ...} with options, or a scenario written inline ({name: ..., inputs: ...}).
ScenarioEntry = Annotated[
    Annotated[str, Tag("folder")]
    | Annotated[ScenarioSource, Tag("source")]
    | Annotated[ScenarioSpec, Tag("inline")],
    Discriminator(
        _source_or_inline,
        custom_error_type="scenario_entry",
        custom_error_message="expected a folder or glob, {path: ...}, or an inline scenario {name: ...}",
    ),
]


class Direction(BaseModel):
    model_config = Strict
    objective: str
    goal: Literal["min", "max"] = "min"


class RankingSpec(BaseModel):
    model_config = Strict
    objective: str | None = (
        None  # reduced over scenarios (by default summed: the paper's Equation 2); default: the first
    )
    goal: Literal["min", "max"] = "min"
    over_scenarios: Literal["sum", "mean", "max", "min"] = (
        "sum"  # max: the worst case of a minimised objective
    )
    pareto: list[
        Annotated[  # objectives of the Pareto front, each "name" or {objective, goal}
            Annotated[Direction, Tag("mapping")] | Annotated[str, Tag("scalar")],
            Discriminator(
                shape, custom_error_type="pareto", custom_error_message="expected a name or {objective, goal}"
            ),
        ]
    ] = []
    weights: dict[str, float] = {}  # weighted sum of per-point totals
    constraints: list[
        str
    ] = []  # on objective totals, e.g. "level_max < 2.4": points breaking one are not ranked
    robust: Robust | None = None  # with an uncertain block: rank by mean + k std or a quantile, not the mean

    def pareto_goals(self) -> list[tuple[str, str]]:
        """(objective, "min" | "max") for each Pareto objective."""
        return [(d, "min") if isinstance(d, str) else (d.objective, d.goal) for d in self.pareto]

    def objectives_used(self) -> list[str]:
        return [self.objective, *(name for name, _ in self.pareto_goals()), *self.weights]


# A list of names or a mapping name -> objective (simulation/objectives.py's forms); an entry with options in
# a list is the likely slip, so its message says where options go.
ObjectiveName = Annotated[
    Annotated[str, Tag("scalar")],
    Discriminator(
        shape,
        custom_error_type="objective_name",
        custom_error_message="a list holds names only (an objective with options goes in a mapping, "
        "objectives: {name: {signal: ..., reduce: ...}})",
    ),
]
Objectives = Annotated[
    Annotated[list[ObjectiveName], Tag("list")] | Annotated[dict[str, objs.ObjectiveSpec], Tag("mapping")],
    Discriminator(
        shape,
        custom_error_type="objectives",
        custom_error_message="expected a list of names or a mapping name: objective",
    ),
]


class Origin(BaseModel):
    """What a space was converted from, so that reports also write that tool's result files."""

    model_config = Strict
    format: Literal["intocps"]
    path: str  # the file converted: an INTO-CPS DSE config
    fmu_keys: dict[str, str] = {}  # instance -> the FMU key its tool names it under ({tank})


class SpaceSpec(BaseModel):
    model_config = Strict
    name: str = Field(pattern=r"^[A-Za-z0-9_.-]+$")
    multimodel: str | dict[str, Any]  # a path relative to the spec or bundled:..., or the multi-model inline
    experiment: Experiment = Experiment()
    scenarios: list[ScenarioEntry] = []  # none: the experiment alone, as scenario "nominal"
    parameters: dict[str, ParameterValues] = Field(min_length=1)
    constraints: list[str] = []
    objectives: Objectives | None = None  # default: the scenarios' kind's
    ranking: RankingSpec = RankingSpec()
    search: Search = Search()
    output: str = "out"  # results store: a folder relative to the spec, or an fsspec URL (s3://bucket/prefix)
    cluster: Cluster = Cluster()
    keep_trajectories: int = Field(default=3, ge=0)  # best points whose tracks are kept
    timeout: PositiveFloat = 600.0  # seconds one simulation may take
    chunk_seconds: PositiveFloat = 2.0  # target wall time of one chunk of tasks
    origin: Origin | None = None  # set when converted from another tool's files (interfaces/intocps)
    uncertain: Uncertain | None = None  # parameters as distributions, each point run over a sample of them

    @model_validator(mode="after")
    def _robust_needs_uncertain(self) -> SpaceSpec:
        if self.ranking.robust is not None and self.uncertain is None:
            raise ValueError(
                "ranking.robust ranks over uncertain samples: add an 'uncertain' block "
                "(docs/space.md#uncertain-parameters)"
            )
        if (
            self.ranking.robust is not None
            and self.ranking.robust.sigmas is not None
            and self.uncertain.samples < 2
        ):
            raise ValueError(
                "ranking.robust.sigmas needs a standard deviation: give uncertain.samples 2 or more"
            )
        return self


class Space:
    """A loaded, checked spec with everything resolved: the unit the rest of the tool works on."""

    def __init__(
        self,
        spec: SpaceSpec,
        path: Path,
        plan: Plan,
        scenarios: list[Scenario],
        distributions: dict[str, Any] | None = None,
        draws: pd.DataFrame | None = None,
    ):
        self.spec = spec
        self.path = path
        self.plan = plan  # the multi-model with every name checked against its FMUs
        self.scenarios = scenarios  # with an uncertain block, each once per draw (uncertainty.sampled)
        self.distributions = distributions  # uncertain parameter -> its distribution (a diagnosis's read)
        self.draws = draws  # the uncertain sample: a row per draw, a column per uncertain parameter
        self.dimensions = [dimension(name, v) for name, v in spec.parameters.items()]
        # name -> declared objective, in the spec's order; scripts read, to travel to the workers
        self.objectives = objs.load_scripts(objs.normalise(spec.objectives or []), path.parent, str(path))
        # every value of a grid or list; an interval's two ends (what the type and bound checks need)
        self.parameters = {d.name: d.extremes() for d in self.dimensions}
        self.constraints = []
        for index, text in enumerate(spec.constraints):
            try:
                self.constraints.append(compile_constraint(text, set(self.parameters)))
            except DseError as e:
                raise DseError(f"{path}: constraints.{index}: {e}") from None

    @property
    def name(self) -> str:
        return self.spec.name

    @functools.cached_property
    def modules(self) -> dict[str, bytes]:
        """The sources of the objective modules beside the spec (imported by resolve_space), read once: they
        travel to the workers and are part of the model's hash."""
        return user_modules.beside(self.objectives.values(), self.path.parent)

    @property
    def multimodel(self) -> MultiModel:
        return self.plan.multimodel

    @property
    def experiment(self) -> Experiment:
        return self.spec.experiment

    @property
    def model_key(self) -> str:
        """The hash of what determines results besides the point and scenario (expand.model_hash)."""
        from .expand import model_hash

        extra = None if self.draws is None else uncertainty.identity(self.spec.uncertain, self.distributions)
        return model_hash(self.plan, self.objectives, self.experiment, extra, self.modules)

    @property
    def output(self) -> Path | str:
        """The results store: a local folder (relative to the spec) or an fsspec URL."""
        from .store import is_url

        if is_url(self.spec.output):
            return self.spec.output
        out = Path(self.spec.output)
        return out if out.is_absolute() else (self.path.parent / out).resolve()

    def with_scenarios(self, scenarios: list[Scenario]) -> Space:
        """The same space run on ``scenarios`` instead of its own (a diagnosis' held-out views, or only
        its recorded runs)."""
        return Space(self.spec, self.path, self.plan, scenarios, self.distributions, self.draws)

    def with_overrides(
        self,
        output: str | Path | None = None,
        address: str | None = None,
        n_workers: int | None = None,
        kind: str | None = None,
        max_points: int | None = None,
        max_seconds: float | None = None,
    ) -> Space:
        """The same space with the CLI's --out, --scheduler, --cluster, --workers, --max-points or
        --max-seconds applied."""
        update: dict[str, Any] = {}
        budget = {
            k: v for k, v in (("max_points", max_points), ("max_seconds", max_seconds)) if v is not None
        }
        if budget:
            update["search"] = Search.model_validate({**self.spec.search.model_dump(), **budget})
        if output is not None:
            from .store import is_url

            update["output"] = output if is_url(str(output)) else str(Path(output).resolve())
        cluster: dict[str, Any] = {}
        if address is not None:
            cluster.update(address=address, kind="local")
        if kind is not None:
            cluster.update(kind=kind, address=None)
        if n_workers is not None:
            cluster.update(
                n_workers=n_workers, min_workers=None, max_workers=None
            )  # --workers: a fixed count
        if cluster:
            update["cluster"] = Cluster.model_validate({**self.spec.cluster.model_dump(), **cluster})
        return Space(
            self.spec.model_copy(update=update),
            self.path,
            self.plan,
            self.scenarios,
            self.distributions,
            self.draws,
        )

    def admits(self, point: Point) -> bool:
        for check in self.constraints:  # a loop, not all(...): a large grid asks this of every point
            if not check(point):
                return False
        return True

    def problem(self, threads: int = 1) -> Problem:
        """What the search strategy is told (search.py); ``threads``: the cluster's, for the default batch."""
        search, ranking = self.spec.search, self.spec.ranking
        return Problem(
            label=self.name,
            dimensions=tuple(self.dimensions),
            objective=(ranking.objective, ranking.goal),
            pareto=tuple(ranking.pareto_goals()),
            scenarios=tuple(s.name for s in self.scenarios),
            vectors=tuple(n for n, o in self.objectives.items() if objs.is_vector(o)),
            max_points=search.max_points,
            seed=search.seed,
            batch=batch_of(search, threads),
            options=search.options,
            admits=self.admits,
            constrained=bool(self.constraints),
        )

    def strategy(self, threads: int = 1) -> Strategy:
        return strategy(self.spec.search.strategy)(self.problem(threads))


def _scenarios(spec: SpaceSpec, base: Path, source: str) -> list[Scenario]:
    """Every scenario the spec names, read and checked; the nominal one when it names none."""
    if not spec.scenarios:
        return [nominal()]
    found: dict[str, Scenario] = {}
    for index, entry in enumerate(spec.scenarios):
        for scenario in _entry(entry, index, base, source):
            if scenario.name in found and found[scenario.name].sources != scenario.sources:
                raise DseError(f"{source}: two scenarios are named {scenario.name!r}")
            found[scenario.name] = scenario
    return list(found.values())


def _entry(entry: ScenarioSpec | ScenarioSource | str, index: int, base: Path, source: str) -> list[Scenario]:
    if isinstance(entry, ScenarioSpec):
        return [parse_scenario(entry.model_dump(), f"{source}: scenarios.{index}", base)]
    entry = ScenarioSource(path=entry) if isinstance(entry, str) else entry
    pattern = entry.path if Path(entry.path).is_absolute() else str(base / entry.path)
    folders = sorted(p for p in glob.glob(pattern) if Path(p).is_dir())
    if not folders:
        raise DseError(f"{source}: scenarios.{index}.path: {entry.path!r} matches no folder")
    scenarios = [load_scenario(folder, entry.kind, entry.model_extra) for folder in folders]
    scenarios = [s.with_group(entry.group) if entry.group is not None else s for s in scenarios]
    variants = read_variants(base / entry.variants) if isinstance(entry.variants, str) else entry.variants
    return [varied(s, v) for s in scenarios for v in variants] if variants else scenarios


def _resolved(spec: SpaceSpec, scenarios: list[Scenario], source: str) -> SpaceSpec:
    """The spec with its default objectives and ranking objective filled in: the first scalar objective, or
    for a space whose objectives are all vectors, the sum of squares of its residuals, added."""
    objectives = spec.objectives
    if objectives is None:
        defaults = {name: None for s in scenarios for name in kind(s.kind).default_objectives}
        if not defaults:
            raise DseError(f"{source}: objectives: name at least one, e.g. {EXAMPLE_OBJECTIVE}")
        objectives = list(defaults)
    if not objectives:
        raise DseError(f"{source}: objectives is empty: name at least one, e.g. {EXAMPLE_OBJECTIVE}")
    named = objs.normalise(objectives)
    scalar = [name for name, o in named.items() if not objs.is_vector(o)]
    ranking = spec.ranking
    if ranking.objective is None:
        if not scalar:
            added, fit = _sum_of_squares(named, source)
            objectives, scalar = {**named, added: fit}, [added]
        ranking = ranking.model_copy(update={"objective": scalar[0]})
    return spec.model_copy(update={"objectives": objectives, "ranking": ranking})


EXAMPLE_OBJECTIVE = "{level_max: {signal: tank.level, reduce: max}}"


def _sum_of_squares(vectors: dict[str, objs.ObjectiveSpec], source: str) -> tuple[str, objs.Fit]:
    """What a space whose every objective is a vector ranks by: the sum of squares of its first residuals
    fit (``<name>_sum_squares``), which is what least squares minimises, summed over the scenarios. Vectors
    of functions have no such counterpart: the message names what to add."""
    for name, spec in vectors.items():
        if isinstance(spec, objs.Fit):
            return f"{name}_sum_squares", spec.model_copy(update={"metric": "sum_squares"})
    names = ", ".join(vectors)
    raise DseError(
        f"{source}: ranking needs an objective with one number per task, and {names} "
        f"{'is a vector' if len(vectors) == 1 else 'are vectors'} (a number per sample): add a scalar "
        "objective beside it, e.g. {fit: {signal: inst.var, recorded: column, metric: rmse}}, which the "
        "ranking then uses (or name it in ranking.objective)"
    )


def _check_names(space: Space, source: str) -> None:
    """Every name the spec uses must exist: FMU variables (one FMU's also by the bare name, as ``simulate
    --set`` takes them), objectives, the strategy."""
    named: dict[str, str] = {}
    for ref, values in space.parameters.items():
        effect = signal_effects.parse(ref)
        if effect is not None:
            _check_effect(space, effect, values, source)
            continue
        term = _parsed_term(ref, source)
        if term is not None:
            _check_term(space, term, values, source)
            continue
        variable = space.plan.variable(qualify(space.plan, ref), f"{source}: parameters")
        if variable.ref in named:
            raise DseError(
                f"{source}: parameters: {named[variable.ref]!r} and {ref!r} name the same variable, "
                f"{variable.ref}; list it once"
            )
        named[variable.ref] = ref
        try:
            space.plan.check_not_fed(variable)  # once per variable, not per value: a grid may hold thousands
            for value in values:
                check_value(variable, value)
        except DseError as e:
            raise DseError(f"{source}: parameters.{ref}: {e}") from None
    for scenario in space.scenarios:
        try:
            bound_fields(space.multimodel, scenario)
        except DseError as e:
            raise DseError(f"{source}: {e}") from None
        where = f"{source}: scenario {scenario.name}: parameters"
        for ref, value in scenario.parameters.items():
            variable = space.plan.variable(qualify(space.plan, ref), where)
            try:
                space.plan.check_not_fed(variable)
                check_value(variable, value)
            except DseError as e:
                raise DseError(f"{where}.{ref}: {e}") from None
        for ref in scenario.inputs:  # an input signal there would be overwritten as a value would
            variable = space.plan.variable(qualify(space.plan, ref), f"{source}: scenario {scenario.name}")
            try:
                space.plan.check_not_fed(variable)
            except DseError as e:
                raise DseError(f"{source}: scenario {scenario.name}: inputs.{ref}: {e}") from None
    for name, objective in space.objectives.items():
        _check_objective(space, name, objective, source)
    _check_search(space, source)
    for name in space.spec.ranking.objectives_used():
        if name not in space.objectives:
            raise DseError(
                f"{source}: ranking uses objective {name!r}, which 'objectives' does not list "
                f"({', '.join(space.objectives)}{_meant(name, space.objectives)})"
            )
        if objs.is_vector(space.objectives[name]):
            raise DseError(f"{source}: ranking uses {name!r}, {_vector_hint(name, space.objectives[name])}")
    for index, text in enumerate(space.spec.ranking.constraints):
        try:
            compile_constraint(text, set(space.objectives), "objective")
        except DseError as e:
            raise DseError(f"{source}: ranking.constraints.{index}: {e}") from None


def _check_effect(space: Space, effect: signal_effects.Effect, values: list[Any], source: str) -> None:
    """A signal effect's values are numbers it takes, on a signal it can act on: an input every scenario
    drives, or a variable the model has (an output effect acts on what the run records)."""
    where = f"{source}: parameters.{effect.name}"
    for value in values:
        try:
            signal_effects.split({effect.name: value})
        except DseError as e:
            raise DseError(f"{source}: parameters.{e}") from None
    target = qualify(space.plan, effect.target)
    space.plan.variable(target, where)
    if effect.side == "input":
        for scenario in space.scenarios:
            driven = {qualify(space.plan, ref) for ref, v in scenario.inputs.items() if isinstance(v, Series)}
            if target not in driven:
                raise DseError(
                    f"{where}: scenario {scenario.name} does not drive {effect.target} with a signal "
                    f"(it drives {', '.join(sorted(driven)) or 'none'}); an input effect acts on a "
                    "scenario's input signal"
                )


Correction = derivative_terms.DerivativeTerm | derivative_terms.DerivativeWidth | state_limits.StateLimit


def _parsed_term(ref: str, source: str) -> Correction | None:
    """A derivative term, its companion width or a state limit: what the master changes in a
    model-exchange instance's equations."""
    try:
        return derivative_terms.parse(ref) or derivative_terms.parse_width(ref) or state_limits.parse(ref)
    except DseError as e:
        raise DseError(f"{source}: parameters.{e}") from None


def _check_term(space: Space, term: Correction, values: list[Any], source: str) -> None:
    """A derivative term's values are coefficients, a state limit's bounds or fractions, on a
    model-exchange instance that has the states and the variables the term reads
    (derivative_terms.check, state_limits.check)."""
    if isinstance(term, derivative_terms.DerivativeWidth):
        _check_width(space, term, values, source)
        return
    split = state_limits.split if isinstance(term, state_limits.StateLimit) else derivative_terms.split
    try:
        for value in values:
            split({term.name: value})
        checked_term(space.plan, term)
    except DseError as e:
        raise DseError(f"{source}: parameters.{e}") from None


def _check_width(
    space: Space, width: derivative_terms.DerivativeWidth, values: list[Any], source: str
) -> None:
    """A derivative term's companion width: its values are widths (finite, > 0), and its term is a parameter
    of the space as well (derivative_terms.split asks the same of every run's values), checked."""
    try:
        for value in values:
            derivative_terms.split({width.term.name: 1.0, width.name: value})
        if not any(derivative_terms.parse(ref) == width.term for ref in space.parameters):
            raise DseError(
                f"{width.name}: the parameters have no {width.term.name}, whose width it fits; "
                "sweep or fit the coefficient too"
            )
        checked_term(space.plan, width.term)
    except DseError as e:
        raise DseError(f"{source}: parameters.{e}") from None


def _check_search(space: Space, source: str) -> None:
    """The strategy exists, takes its options and suits the parameters and the ranking."""
    search = space.spec.search
    try:
        kind = strategy(search.strategy)
        parse_options(kind, search.options)
        if kind.multi_objective and len(space.spec.ranking.pareto) < 2:
            raise DseError(
                f"search: {search.strategy} optimises several objectives: list two or more "
                "under ranking.pareto"
            )
        # Built once here, so what only its constructor checks fails now, not after the cluster starts:
        # a grid needs every parameter on a grid, Optuna's samplers take only their own keyword
        # arguments, least squares needs a vector objective.
        kind(space.problem())
    except DseError as e:
        raise DseError(f"{source}: {e}") from None


def _check_objective(space: Space, name: str, objective: objs.ObjectiveSpec, source: str) -> None:
    """A declared objective's signals must exist and its recorded column be in every scenario."""
    where = f"{source}: objectives.{name}"
    if isinstance(objective, str):
        try:
            objs.checked(objective)
        except DseError as e:
            raise DseError(f"{where}: {e}") from None
        return
    for signal in objs.signals(objective):
        variable = space.plan.variable(qualify(space.plan, signal), where)
        if not variable.numeric:
            raise DseError(f"{where}: {variable.ref!r} is a {variable.type}, not a number one can score")
    if isinstance(objective, objs.Fit):
        for scenario in space.scenarios:
            if scenario.recorded is None:
                raise DseError(
                    f"{where}: compares with recorded {objective.recorded!r}, but scenario "
                    f"{scenario.name} has no recording"
                )
            if objective.recorded not in scenario.recorded.columns:
                raise DseError(
                    f"{where}: scenario {scenario.name}'s recording {scenario.recorded.path} has no "
                    f"column {objective.recorded!r} (it has {', '.join(scenario.recorded.columns)}"
                    f"{_meant(objective.recorded, scenario.recorded.columns)})"
                )


def _vector_hint(name: str, spec: objs.ObjectiveSpec) -> str:
    """Why a vector cannot rank, and what would."""
    said = "a vector objective (a number per sample); rankings need one number per task"
    if isinstance(spec, objs.Fit):
        return (
            f"{said}: rank by its sum of squares, {{{name}_sum_squares: {{signal: {spec.signal}, recorded: "
            f"{spec.recorded}, metric: sum_squares}}}}, or leave ranking.objective out, which adds that one"
        )
    return f"{said}: add a scalar objective, e.g. {{signal: inst.var, recorded: column, metric: rmse}}"


def _meant(name: str, options) -> str:
    """``; did you mean a?`` inside a parenthesis that lists the options, or nothing."""
    close = close_names(name, options)
    return f"; did you mean {', '.join(close)}?" if close else ""


def unread_recordings(space: Space) -> str | None:
    """A warning for a space whose scenarios have recordings that none of its objectives reads (only
    reductions): a comparison its author likely meant, which would otherwise be dropped without a word. A
    kind that scores its own recording (field data) is left out, and so is a space with a function or a
    script objective, which may read the recording itself."""
    recorded = [s for s in space.scenarios if s.recorded is not None and not kind(s.kind).default_objectives]
    if not recorded or not all(isinstance(o, objs.Reduce) for o in space.objectives.values()):
        return None
    names = ", ".join(s.name for s in recorded[:5]) + (f" and {len(recorded) - 5} more" * (len(recorded) > 5))
    column = next(iter(recorded[0].recorded.columns))
    return (
        f"{space.path}: the recordings of scenario {names} are compared by no objective (the objectives, "
        f"{', '.join(space.objectives)}, only reduce signals); compare a column with "
        f"{{signal: inst.var, recorded: {column}, metric: rmse}}"
    )


def derived_space(space: Space, **update: Any) -> Space:
    """``space`` with its spec changed by ``update`` (another sweep's name, parameters, objectives), resolved
    and checked again, keeping its scenarios as they are: a diagnosis's views of its runs (a record's
    validation blocks) exist only there."""
    resolved = resolve_space(space.spec.model_copy(update=update), space.path)
    return Space(
        resolved.spec, resolved.path, resolved.plan, space.scenarios, resolved.distributions, resolved.draws
    )


def load_space(path: str | Path) -> Space:
    """Read, validate and resolve a space.yaml; every error names the file."""
    path = Path(path).resolve()
    return resolve_space(read_spec(path), path)


def read_spec(path: Path) -> SpaceSpec:
    """Read and validate a space.yaml without resolving anything it names."""
    return read_yaml(path, SpaceSpec, "space.yaml", empty={})


def resolve_space(spec: SpaceSpec, path: Path) -> Space:
    """A validated spec made a Space: its multi-model, FMUs and scenarios found and every name
    checked. ``path`` is where relative paths start from (the spec file's folder)."""
    source = str(path)
    if isinstance(spec.multimodel, str):
        multimodel = load_model(bundled.resolve(spec.multimodel, path.parent))  # or one .fmu, or its sources
    else:
        multimodel = parse_multimodel(spec.multimodel, f"{source}: multimodel", path.parent)
    scenarios = _scenarios(spec, path.parent, source)
    plan = make_plan(multimodel)
    distributions = draws = None
    if spec.uncertain is not None:
        distributions = uncertainty.resolved(spec.uncertain, path.parent, source)
        try:
            draws = uncertainty.draw(spec.uncertain, distributions)
        except DseError as e:
            raise DseError(f"{source}: {e}") from None
        _check_uncertain(spec, plan, scenarios, draws, source)
        scenarios = uncertainty.sampled(scenarios, draws)
    # a module:function beside the spec, imported before anything asks its function (is_vector, the checks)
    user_modules.import_beside(objs.normalise(spec.objectives or []).values(), path.parent)
    space = Space(_resolved(spec, scenarios, source), path, plan, scenarios, distributions, draws)
    _check_names(space, source)
    return space


def _check_uncertain(
    spec: SpaceSpec, plan: Plan, scenarios: list[Scenario], draws: pd.DataFrame, source: str
) -> None:
    """Uncertain parameters are FMU parameters that nothing else sets, and every drawn value suits them."""
    swept = {
        qualify(plan, ref): ref
        for ref in spec.parameters
        if signal_effects.parse(ref) is None and _parsed_term(ref, source) is None
    }
    taken = {"sample", *(spec.objectives or ())}  # columns of the draws' table (rank.with_drawn_values)
    for ref in draws.columns:
        where = f"{source}: uncertain.parameters.{ref}"
        if ref in taken:
            raise DseError(
                f"{where}: the name is a column of the ranking's draws already (the draw's number, or "
                "an objective); write the parameter as instance.variable"
            )
        if signal_effects.parse(ref) is not None or _parsed_term(ref, source) is not None:
            raise DseError(
                f"{where}: uncertain parameters are FMU variables; a signal effect or derivative "
                "term can be swept, not sampled"
            )
        name = qualify(plan, ref)
        variable = plan.variable(name, f"{source}: uncertain.parameters")
        try:
            plan.check_not_fed(variable)
        except DseError as e:
            raise DseError(f"{where}: {e}") from None
        if name in swept:
            raise DseError(
                f"{where}: {swept[name]!r} is also under 'parameters'; a parameter is either swept "
                "(a design choice) or uncertain (a distribution), not both"
            )
        for scenario in scenarios:
            if name in {qualify(plan, r) for r in scenario.parameters}:
                raise DseError(
                    f"{where}: scenario {scenario.name} sets it too; an uncertain parameter takes "
                    "its value from the draws only"
                )
        for k, value in enumerate(draws[ref].tolist()):
            try:
                check_value(variable, value)
            except DseError as e:
                raise DseError(
                    f"{where}: draw {k} ({value:.6g}): {e}; narrow its distribution, or give a bounded "
                    "one (uniform, triangular)"
                ) from None
    for scenario in scenarios:
        if uncertainty.SEPARATOR in scenario.name:
            raise DseError(
                f"{source}: scenario {scenario.name!r}: with an uncertain block scenario names may not "
                f"hold {uncertainty.SEPARATOR!r}, which names each draw"
            )
