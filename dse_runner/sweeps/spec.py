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
import math
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    Tag,
    model_validator,
)

from .. import bundled
from ..errors import DseError
from ..simulation import objectives as objs
from ..simulation import derivative_terms, signal_effects, state_limits, user_modules
from ..simulation.cosim import Plan, make_plan
from ..simulation.experiment import Experiment
from ..simulation.multimodel import MultiModel, parse_multimodel
from ..simulation.run import bound_fields, checked_term, load_model, qualify
from ..simulation.scenario import Scenario, ScenarioSpec, Series, kind, load_scenario, nominal, parse_scenario
from ..simulation.variables import FiniteValue, check_value
from ..yamlfile import read_yaml, shape
from . import makers, uncertainty
from .constraints import compile_constraint
from .domain import Dimension, Point
from .search import Problem, Strategy, parse_options, strategy

if TYPE_CHECKING:  # pandas and the store's pyarrow wait for a spec that reads: a bad one is named sooner
    import pandas as pd

Strict = ConfigDict(extra="forbid", allow_inf_nan=False)  # unknown keys, NaN and infinity are errors


class Range(BaseModel):
    """``{start, stop, step}`` (stop included when the steps land on it) or ``{start, stop, num}``."""

    model_config = Strict
    start: float
    stop: float
    step: PositiveFloat | None = None
    num: PositiveInt | None = None
    log: bool = False

    @model_validator(mode="after")
    def _one_of_step_or_num(self) -> Range:
        if (self.step is None) == (self.num is None):
            raise ValueError("give exactly one of 'step' or 'num'")
        if self.log and (self.step is not None or self.start <= 0 or self.stop <= 0):
            raise ValueError("a log range needs 'num' and positive 'start' and 'stop'")
        if self.stop < self.start:
            raise ValueError("'stop' must not be below 'start'")
        return self

    def values(self) -> list[float]:
        if self.log:
            return [float(v) for v in np.geomspace(self.start, self.stop, self.num)]
        if self.num is not None:
            return [float(v) for v in np.linspace(self.start, self.stop, self.num)]
        count = math.floor((self.stop - self.start) / self.step + 1e-9) + 1
        # round() keeps 0.1-steps free of 0.30000000000000004 in tables and ids
        return [round(self.start + i * self.step, 12) for i in range(count)]


class Interval(BaseModel):
    """``{low, high}``: every value between, for search strategies; ``log: true`` samples the
    logarithm uniformly, ``integer: true`` takes whole numbers only."""

    model_config = Strict
    low: float
    high: float
    log: bool = False
    integer: bool = False

    @model_validator(mode="after")
    def _ordered(self) -> Interval:
        if not self.high > self.low:
            raise ValueError("'high' must be above 'low'")
        if self.log and self.low <= 0:
            raise ValueError("a log interval needs a positive 'low'")
        if self.integer and not (self.low.is_integer() and self.high.is_integer()):
            raise ValueError("an integer interval needs whole-number 'low' and 'high'")
        return self


def _parameter_kind(value: Any) -> str | None:
    if isinstance(value, Interval) or (isinstance(value, dict) and ("low" in value or "high" in value)):
        return "interval"
    return "range" if isinstance(value, (dict, Range)) else "values" if isinstance(value, list) else None


# A list of values, a grid or an interval; the discriminator makes a wrong one give one message, not one per kind.
ParameterValues = Annotated[
    Annotated[Annotated[list[FiniteValue], Field(min_length=1)], Tag("values")] | Annotated[Range, Tag("range")]
    | Annotated[Interval, Tag("interval")],
    Discriminator(_parameter_kind, custom_error_type="parameter_values",
                  custom_error_message="expected a list of values, a grid {start, stop, step or num} "
                                       "or an interval {low, high}")]


class Variant(BaseModel):
    """One variant of every scenario of a source: ``{name: heavy, parameters: {vehicle.mass: 2000}}``."""

    model_config = Strict
    name: str = Field(pattern=r"^[A-Za-z0-9_.]+$")
    parameters: dict[str, FiniteValue] = Field(min_length=1)


class ScenarioSource(BaseModel):
    """Scenario folders: ``{path: runs/*, group: .., kind: .., variants: [..]}`` plus the kind's own options."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)  # the rest goes to the kind
    path: str  # a folder or a glob of folders, relative to the spec
    group: str | None = None  # overrides the scenario's own group
    kind: str | None = None  # default: the first installed kind that recognises the folder
    # Each folder runs once per variant, as scenario <name>-<variant> with the variant's parameters on top of
    # its own: a design evaluated over several plants (a robust objective: ranking.over_scenarios max or mean).
    # A string is a YAML file holding the list, relative to the spec.
    variants: Annotated[
        Annotated[list[Variant], Tag("list")] | Annotated[str, Tag("scalar")],
        Discriminator(shape, custom_error_type="variants",
                      custom_error_message="expected a list of {name, parameters} or a YAML file holding one")] = []


def read_variants(path: Path) -> list[Variant]:
    """A variants file: a YAML list of ``{name, parameters}``; errors name the file."""
    return read_yaml(path, list[Variant], "variants file")


def varied(scenario: Scenario, variant: Variant) -> Scenario:
    """``scenario`` with ``variant``'s parameters, named for both."""
    return replace(scenario, name=f"{scenario.name}-{variant.name}",
                   parameters={**scenario.parameters, **variant.parameters})


def _source_or_inline(value: Any) -> str | None:
    if isinstance(value, str):
        return "folder"
    if isinstance(value, ScenarioSource) or (isinstance(value, Mapping) and "path" in value):
        return "source"
    return "inline" if shape(value) == "mapping" else None


# A folder (or glob), {path: ...} with options, or a scenario written inline ({name: ..., inputs: ...}).
ScenarioEntry = Annotated[
    Annotated[str, Tag("folder")] | Annotated[ScenarioSource, Tag("source")] | Annotated[ScenarioSpec, Tag("inline")],
    Discriminator(_source_or_inline, custom_error_type="scenario_entry",
                  custom_error_message="expected a folder or glob, {path: ...}, or an inline scenario {name: ...}")]


class Uniform(BaseModel):
    """Every value between ``low`` and ``high`` equally likely."""

    model_config = Strict
    distribution: Literal["uniform"]
    low: float
    high: float

    @model_validator(mode="after")
    def _ordered(self) -> Uniform:
        if not self.high > self.low:
            raise ValueError(f"'high' ({self.high:g}) must be above 'low' ({self.low:g})")
        return self


class Normal(BaseModel):
    """Gaussian with ``mean`` and standard deviation ``std``."""

    model_config = Strict
    distribution: Literal["normal"]
    mean: float
    std: PositiveFloat


class LogNormal(BaseModel):
    """A value whose natural logarithm is normal: ``median`` (the value's) and ``std_log`` (the logarithm's std);
    for a positive quantity known to a few percent, std_log is about its relative spread."""

    model_config = Strict
    distribution: Literal["lognormal"]
    median: PositiveFloat
    std_log: PositiveFloat


class Triangular(BaseModel):
    """Between ``low`` and ``high``, most likely at ``mode``."""

    model_config = Strict
    distribution: Literal["triangular"]
    low: float
    mode: float
    high: float

    @model_validator(mode="after")
    def _ordered(self) -> Triangular:
        if not (self.low <= self.mode <= self.high and self.high > self.low):
            raise ValueError(f"needs low <= mode <= high and low < high (got {self.low:g}, {self.mode:g}, "
                             f"{self.high:g})")
        return self


class FromDiagnosis(BaseModel):
    """A diagnosis's fitted value and ~95 % interval (``dse-runner diagnose --json``'s file), read as a normal
    whose mean is the fitted value and whose 1.96 sigma is the interval's half-width. ``effect``: the id of one
    of its ``effects`` (default: its ``fitted`` calibration, by the parameter's own name); ``parameter``: the
    name within that effect, when it has several."""

    model_config = Strict
    from_diagnosis: str  # relative to the spec
    effect: str | None = None
    parameter: str | None = None


DISTRIBUTIONS = {"uniform": Uniform, "normal": Normal, "lognormal": LogNormal, "triangular": Triangular}


def _distribution_kind(value: Any) -> str | None:
    if isinstance(value, FromDiagnosis) or (isinstance(value, dict) and "from_diagnosis" in value):
        return "diagnosis"
    kind = value.get("distribution") if isinstance(value, dict) else getattr(value, "distribution", None)
    return kind if kind in DISTRIBUTIONS else None


# One of the distributions, by its ``distribution`` key, or {from_diagnosis: ...}: a wrong one gives one message.
UncertainValue = Annotated[
    Annotated[Uniform, Tag("uniform")] | Annotated[Normal, Tag("normal")] | Annotated[LogNormal, Tag("lognormal")]
    | Annotated[Triangular, Tag("triangular")] | Annotated[FromDiagnosis, Tag("diagnosis")],
    Discriminator(_distribution_kind, custom_error_type="distribution",
                  custom_error_message="expected {distribution: uniform | normal | lognormal | triangular, ...} "
                                       "or {from_diagnosis: FILE, effect: ...}")]


class Uncertain(BaseModel):
    """Parameters known only as distributions: every design point runs on ``samples`` draws of them, each draw
    a copy of every scenario (sweeps/uncertainty.py); objectives get their mean, std and quantiles."""

    model_config = Strict
    parameters: dict[str, UncertainValue] = Field(min_length=1)  # instance.variable -> distribution
    samples: PositiveInt = 64
    seed: int = 0
    # sobol: scrambled Sobol' points (quasi-random, best at powers of 2; more samples keep the first ones);
    # latin_hypercube: one draw per stratum of each parameter; random: plain pseudo-random draws
    sampling: Literal["sobol", "latin_hypercube", "random"] = "sobol"
    quantiles: list[Annotated[float, Field(gt=0, lt=1)]] = [0.05, 0.5, 0.95]


class Robust(BaseModel):
    """Rank by a pessimistic figure of the ranking objective's distribution over the uncertain samples:
    ``sigmas: k``, the mean k standard deviations towards the worse side (mean + k std when minimising,
    mean - k std when maximising); or ``quantile: q``, its q-quantile as written (0.9 when minimising,
    0.1 when maximising is the worse tenth)."""

    model_config = Strict
    sigmas: Annotated[float, Field(ge=0)] | None = None
    quantile: Annotated[float, Field(gt=0, lt=1)] | None = None

    @model_validator(mode="after")
    def _one(self) -> Robust:
        if (self.sigmas is None) == (self.quantile is None):
            raise ValueError("give exactly one of 'sigmas' (mean + k std) or 'quantile' (e.g. 0.9)")
        return self

    def label(self, goal: str) -> str:
        """How the ranked figure is named in tables and reports."""
        if self.quantile is not None:
            return f"q{100 * self.quantile:g}"
        return f"mean{'+' if goal == 'min' else '-'}{self.sigmas:g}sd"


class Direction(BaseModel):
    model_config = Strict
    objective: str
    goal: Literal["min", "max"] = "min"


class Ranking(BaseModel):
    model_config = Strict
    objective: str | None = None  # reduced over scenarios (by default summed: the paper's Equation 2); default: the first
    goal: Literal["min", "max"] = "min"
    over_scenarios: Literal["sum", "mean", "max", "min"] = "sum"  # max: the worst case of a minimised objective
    pareto: list[Annotated[  # objectives of the Pareto front, each "name" or {objective, goal}
        Annotated[Direction, Tag("mapping")] | Annotated[str, Tag("scalar")],
        Discriminator(shape, custom_error_type="pareto", custom_error_message="expected a name or {objective, goal}")
    ]] = []
    weights: dict[str, float] = {}  # weighted sum of per-point totals
    constraints: list[str] = []  # on objective totals, e.g. "level_max < 2.4": points breaking one are not ranked
    robust: Robust | None = None  # with an uncertain block: rank by mean + k std or a quantile, not the mean

    def pareto_goals(self) -> list[tuple[str, str]]:
        """(objective, "min" | "max") for each Pareto objective."""
        return [(d, "min") if isinstance(d, str) else (d.objective, d.goal) for d in self.pareto]

    def objectives_used(self) -> list[str]:
        return [self.objective, *(name for name, _ in self.pareto_goals()), *self.weights]


BATCH = 4  # a reproducible search's points asked ahead: fixed, so that the points do not depend on the cluster


class Search(BaseModel):
    """How points are chosen (search.py). Keys besides these are the strategy's own options."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)
    strategy: str = "exhaustive"  # built-in or a plug-in's (see search.py)
    max_points: PositiveInt = 100  # a search stops after this many simulated points (not for exhaustive)
    max_seconds: PositiveFloat | None = None  # ... or when this submission has run this long
    seed: int = 0  # with order: reproducible, the same seed and spec give the same points
    # reproducible: each result is told once every point asked before it has been told, and a point is
    # asked only while fewer than ``batch`` points wait for theirs: the points depend on no worker's timing.
    # asynchronous: each result is told as it comes (closed_loop.py).
    order: Literal["reproducible", "asynchronous"] = "reproducible"
    batch: PositiveInt | None = None  # points asked ahead of their results; default BATCH, or threads + 1 if asynchronous

    @property
    def options(self) -> dict[str, Any]:
        return dict(self.model_extra or {})


class Tls(BaseModel):
    """Certificates for a TLS scheduler (distributed's Security); paths relative to the spec."""

    model_config = Strict
    ca_file: str  # the authority that signed the scheduler's and workers' certificates
    cert: str  # this client's certificate
    key: str  # its private key


class Cluster(BaseModel):
    """Where tasks run: ``address`` of an existing scheduler, or a cluster of ``kind`` started for the sweep.
    Keys besides these are cluster kinds' own blocks, each named by its kind (``htcondor: {cores: 4}``)
    and validated by that kind's maker (makers.py)."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)
    kind: str = "local"  # local, slurm, htcondor, kubernetes, or a plug-in's (see makers.py)
    address: str | None = None  # tcp://host:8786 or tls://host:8786: use this scheduler, start nothing
    n_workers: PositiveInt | None = None  # workers to start; local default: the number of cores
    min_workers: NonNegativeInt | None = None  # with max_workers: Dask's adaptive scaling between the two,
    max_workers: PositiveInt | None = None  # workers (jobs) started as tasks wait and given back when idle
    threads_per_worker: PositiveInt = 1
    tls: Tls | None = None
    dashboard_address: str = "127.0.0.1:0"  # of a scheduler we start; loopback unless asked otherwise
    connect_timeout: PositiveFloat = 30.0  # seconds to reach a scheduler, or get it back after a restart; a
    # sweep whose local or addressed cluster has had no worker for twice this stops (cluster.worker_grace)

    @model_validator(mode="after")
    def _address_or_kind(self) -> Cluster:
        if self.address is not None and self.kind != "local":
            raise ValueError(f"give either 'address' (an existing scheduler) or 'kind: {self.kind}', not both")
        if self.address is not None and not self.address.startswith(("tcp://", "tls://", "ucx://", "inproc://")):
            raise ValueError(f"address {self.address!r} needs a protocol: tcp://host:port or tls://host:port")
        return self

    @model_validator(mode="after")
    def _fixed_or_adaptive(self) -> Cluster:
        """A fixed ``n_workers``, or ``min_workers`` to ``max_workers`` for Dask's adapt: not both."""
        if self.min_workers is not None and self.max_workers is None:
            raise ValueError("min_workers needs max_workers (adaptive scaling between the two)")
        if self.max_workers is None:
            return self
        if self.n_workers is not None:
            raise ValueError("give either n_workers (a fixed count) or min_workers/max_workers (adaptive), not both")
        if self.address is not None:
            raise ValueError("min_workers/max_workers scale a cluster dse-runner starts, not one at 'address'")
        if (self.min_workers or 0) > self.max_workers:
            raise ValueError(f"min_workers ({self.min_workers}) is more than max_workers ({self.max_workers})")
        return self

    @model_validator(mode="after")
    def _kind_blocks(self) -> Cluster:
        """Every block, and the chosen kind's even when absent (its required options), if installed here."""
        blocks = dict(self.model_extra or {})
        if self.address is None:
            blocks.setdefault(self.kind, None)
        for key, block in blocks.items():
            try:
                makers.check_block(key, block, self.kind)
            except DseError as e:
                raise ValueError(str(e)) from None
        return self

    def block(self, kind: str) -> Any:
        """The block ``cluster.<kind>`` as written; None if the spec has none (the maker's defaults)."""
        return (self.model_extra or {}).get(kind)


# A list of names or a mapping name -> objective (simulation/objectives.py's forms); an entry with options in a
# list is the likely slip, so its message says where options go.
ObjectiveName = Annotated[Annotated[str, Tag("scalar")], Discriminator(
    shape, custom_error_type="objective_name",
    custom_error_message="a list holds names only (an objective with options goes in a mapping, "
                         "objectives: {name: {signal: ..., reduce: ...}})")]
Objectives = Annotated[
    Annotated[list[ObjectiveName], Tag("list")] | Annotated[dict[str, objs.ObjectiveSpec], Tag("mapping")],
    Discriminator(shape, custom_error_type="objectives",
                  custom_error_message="expected a list of names or a mapping name: objective")]


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
    ranking: Ranking = Ranking()
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
            raise ValueError("ranking.robust ranks over uncertain samples: add an 'uncertain' block "
                             "(docs/space.md#uncertain-parameters)")
        if self.ranking.robust is not None and self.ranking.robust.sigmas is not None and self.uncertain.samples < 2:
            raise ValueError("ranking.robust.sigmas needs a standard deviation: give uncertain.samples 2 or more")
        return self


def _normal(value: Any) -> Any:
    """Numbers as floats, so 1000 and 1000.0 are one point (and one task id)."""
    return float(value) if isinstance(value, int) and not isinstance(value, bool) else value


def dimension(name: str, values: list[Any] | Range | Interval) -> Dimension:
    """How a search strategy sees one parameter (domain.py)."""
    if isinstance(values, Interval):
        return Dimension(name, values.low, values.high, log=values.log, integer=values.integer)
    if isinstance(values, Range) and values.step is not None and not values.log:
        return Dimension(name, values.start, values.values()[-1], step=values.step)
    listed = values.values() if isinstance(values, Range) else values
    return Dimension(name, choices=tuple(dict.fromkeys(_normal(v) for v in listed)))


class Space:
    """A loaded, checked spec with everything resolved: the unit the rest of the tool works on."""

    def __init__(self, spec: SpaceSpec, path: Path, plan: Plan, scenarios: list[Scenario],
                 distributions: dict[str, Any] | None = None, draws: pd.DataFrame | None = None):
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

    def with_overrides(self, output: str | Path | None = None, address: str | None = None,
                       n_workers: int | None = None, kind: str | None = None, max_points: int | None = None,
                       max_seconds: float | None = None) -> Space:
        """The same space with the CLI's --out, --scheduler, --cluster, --workers, --max-points or
        --max-seconds applied."""
        update: dict[str, Any] = {}
        budget = {k: v for k, v in (("max_points", max_points), ("max_seconds", max_seconds)) if v is not None}
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
            cluster.update(n_workers=n_workers, min_workers=None, max_workers=None)  # --workers: a fixed count
        if cluster:
            update["cluster"] = Cluster.model_validate({**self.spec.cluster.model_dump(), **cluster})
        return Space(self.spec.model_copy(update=update), self.path, self.plan, self.scenarios, self.distributions,
                     self.draws)

    def admits(self, point: Point) -> bool:
        for check in self.constraints:  # a loop, not all(...): a large grid asks this of every point
            if not check(point):
                return False
        return True

    def problem(self, threads: int = 1) -> Problem:
        """What the search strategy is told (search.py); ``threads``: the cluster's, for the default batch."""
        search, ranking = self.spec.search, self.spec.ranking
        return Problem(label=self.name, dimensions=tuple(self.dimensions),
                       objective=(ranking.objective, ranking.goal), pareto=tuple(ranking.pareto_goals()),
                       scenarios=tuple(s.name for s in self.scenarios),
                       vectors=tuple(n for n, o in self.objectives.items() if objs.is_vector(o)),
                       max_points=search.max_points, seed=search.seed, batch=batch_of(search, threads),
                       options=search.options, admits=self.admits, constrained=bool(self.constraints))

    def strategy(self, threads: int = 1) -> Strategy:
        return strategy(self.spec.search.strategy)(self.problem(threads))


def batch_of(search: Search, threads: int) -> int:
    """Points asked ahead of their results: a reproducible search's may not depend on the cluster (it would
    change the points); an asynchronous one keeps every worker thread busy and one point waiting."""
    if search.batch is not None:
        return search.batch
    return threads + 1 if search.order == "asynchronous" else BATCH


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
    """The spec with its default objectives and ranking objective filled in."""
    objectives = spec.objectives
    if objectives is None:
        defaults = {name: None for s in scenarios for name in kind(s.kind).default_objectives}
        if not defaults:
            raise DseError(f"{source}: objectives: name at least one, e.g. "
                           "{level_max: {signal: tank.level, reduce: max}}")
        objectives = list(defaults)
    scalar = [name for name, o in objs.normalise(objectives).items() if not objs.is_vector(o)]
    ranking = spec.ranking
    if ranking.objective is None:
        if not scalar:
            raise DseError(f"{source}: ranking needs an objective with one number per task")
        ranking = ranking.model_copy(update={"objective": scalar[0]})
    return spec.model_copy(update={"objectives": objectives, "ranking": ranking})


def _check_names(space: Space, source: str) -> None:
    """Every name the spec uses must exist: FMU variables, objectives, the strategy."""
    for ref, values in space.parameters.items():
        effect = signal_effects.parse(ref)
        if effect is not None:
            _check_effect(space, effect, values, source)
            continue
        term = _parsed_term(ref, source)
        if term is not None:
            _check_term(space, term, values, source)
            continue
        variable = space.plan.variable(ref, f"{source}: parameters")
        for value in values:
            try:
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
                check_value(variable, value)
            except DseError as e:
                raise DseError(f"{where}.{ref}: {e}") from None
    for name, objective in space.objectives.items():
        _check_objective(space, name, objective, source)
    _check_search(space, source)
    for name in space.spec.ranking.objectives_used():
        if name not in space.objectives:
            raise DseError(f"{source}: ranking uses objective {name!r}, which 'objectives' does not list "
                           f"({', '.join(space.objectives)})")
        if objs.is_vector(space.objectives[name]):
            raise DseError(f"{source}: ranking uses {name!r}, a vector objective; rankings need one number per task")
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
                raise DseError(f"{where}: scenario {scenario.name} does not drive {effect.target} with a signal "
                               f"(it drives {', '.join(sorted(driven)) or 'none'}); an input effect acts on a "
                               "scenario's input signal")


def _parsed_term(ref: str, source: str) -> derivative_terms.DerivativeTerm | state_limits.StateLimit | None:
    """A derivative term or a state limit: what the master changes in a model-exchange instance's equations."""
    try:
        return derivative_terms.parse(ref) or state_limits.parse(ref)
    except DseError as e:
        raise DseError(f"{source}: parameters.{e}") from None


def _check_term(space: Space, term: derivative_terms.DerivativeTerm | state_limits.StateLimit, values: list[Any],
                source: str) -> None:
    """A derivative term's values are coefficients, a state limit's bounds or fractions, on a model-exchange
    instance that has the states and the variables the term reads (derivative_terms.check, state_limits.check)."""
    split = state_limits.split if isinstance(term, state_limits.StateLimit) else derivative_terms.split
    try:
        for value in values:
            split({term.name: value})
        checked_term(space.plan, term)
    except DseError as e:
        raise DseError(f"{source}: parameters.{e}") from None


def _check_search(space: Space, source: str) -> None:
    """The strategy exists, takes its options and suits the parameters and the ranking."""
    search = space.spec.search
    try:
        kind = strategy(search.strategy)
        parse_options(kind, search.options)
        if kind.multi_objective and len(space.spec.ranking.pareto) < 2:
            raise DseError(f"search: {search.strategy} optimises several objectives: list two or more "
                           "under ranking.pareto")
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
        objs.function(objective)
        return
    for signal in objs.signals(objective):
        variable = space.plan.variable(qualify(space.plan, signal), where)
        if not variable.numeric:
            raise DseError(f"{where}: {variable.ref!r} is a {variable.type}, not a number one can score")
    if isinstance(objective, objs.Fit):
        for scenario in space.scenarios:
            if scenario.recorded is None:
                raise DseError(f"{where}: compares with recorded {objective.recorded!r}, but scenario "
                               f"{scenario.name} has no recording")
            if objective.recorded not in scenario.recorded.columns:
                raise DseError(f"{where}: scenario {scenario.name}'s recording {scenario.recorded.path} has no "
                               f"column {objective.recorded!r} (it has {', '.join(scenario.recorded.columns)})")


def derived_space(space: Space, **update: Any) -> Space:
    """``space`` with its spec changed by ``update`` (another sweep's name, parameters, objectives), resolved
    and checked again, keeping its scenarios as they are: a diagnosis's views of its runs (a record's
    validation blocks) exist only there."""
    resolved = resolve_space(space.spec.model_copy(update=update), space.path)
    return Space(resolved.spec, resolved.path, resolved.plan, space.scenarios, resolved.distributions, resolved.draws)


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


def _check_uncertain(spec: SpaceSpec, plan: Plan, scenarios: list[Scenario], draws: pd.DataFrame,
                     source: str) -> None:
    """Uncertain parameters are FMU parameters that nothing else sets, and every drawn value suits them."""
    swept = {qualify(plan, ref): ref for ref in spec.parameters if signal_effects.parse(ref) is None
             and _parsed_term(ref, source) is None}
    taken = {"sample", *(spec.objectives or ())}  # columns of the draws' table (rank.with_drawn_values)
    for ref in draws.columns:
        where = f"{source}: uncertain.parameters.{ref}"
        if ref in taken:
            raise DseError(f"{where}: the name is a column of the ranking's draws already (the draw's number, or "
                           "an objective); write the parameter as instance.variable")
        if signal_effects.parse(ref) is not None or _parsed_term(ref, source) is not None:
            raise DseError(f"{where}: uncertain parameters are FMU variables; a signal effect or derivative "
                           "term can be swept, not sampled")
        name = qualify(plan, ref)
        variable = plan.variable(name, f"{source}: uncertain.parameters")
        if name in swept:
            raise DseError(f"{where}: {swept[name]!r} is also under 'parameters'; a parameter is either swept "
                           "(a design choice) or uncertain (a distribution), not both")
        for scenario in scenarios:
            if name in {qualify(plan, r) for r in scenario.parameters}:
                raise DseError(f"{where}: scenario {scenario.name} sets it too; an uncertain parameter takes "
                               "its value from the draws only")
        for k, value in enumerate(draws[ref].tolist()):
            try:
                check_value(variable, value)
            except DseError as e:
                raise DseError(f"{where}: draw {k} ({value:.6g}): {e}; narrow its distribution, or give a bounded "
                               "one (uniform, triangular)") from None
    for scenario in scenarios:
        if uncertainty.SEPARATOR in scenario.name:
            raise DseError(f"{source}: scenario {scenario.name!r}: with an uncertain block scenario names may not "
                           f"hold {uncertainty.SEPARATOR!r}, which names each draw")
