"""Uncertainty propagation: parameters known only as distributions (the spec's ``uncertain:`` block).

A seeded sample of the uncertain parameters is drawn once (scipy.stats' distributions at
quasi-random or random unit points), and every scenario runs once per draw, as scenario
``<name>~u<k>`` with the draw's values among its parameters: the way scenario variants
multiply tasks, so task ids, chunks, the store and resuming need nothing new. Every design
point sees the same draws (common random numbers): two points' difference is not blurred by
different luck.

The reducer (rank.py) reduces each draw over the scenarios as the ranking says, then gives each
objective's mean, standard deviation and quantiles over the draws; a robust ranking ranks by
mean + k std or a quantile instead of the mean.
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, Discriminator, Field, PositiveFloat, PositiveInt, Tag, model_validator

from ..errors import DseError
from ..schema import Strict
from ..simulation.scenario import Scenario

if TYPE_CHECKING:
    import pandas as pd


SEPARATOR = "~u"  # <scenario>~u<k>: the k-th draw of the scenario
Z95 = 1.959963984540054  # a ~95 % interval is mean +/- this many std (the diagnosis's intervals)


# ---- the spec's blocks: uncertain (the distributions) and ranking.robust --------------------------------


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
    """A value whose natural logarithm is normal: ``median`` (the value's) and ``std_log`` (the logarithm's
    std); for a positive quantity known to a few percent, std_log is about its relative spread."""

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
            raise ValueError(
                f"needs low <= mode <= high and low < high (got {self.low:g}, {self.mode:g}, {self.high:g})"
            )
        return self


class FromDiagnosis(BaseModel):
    """A diagnosis's fitted value and ~95 % interval (``dse-runner diagnose --json``'s file), read as a
    normal whose mean is the fitted value and whose 1.96 sigma is the interval's half-width. ``effect``:
    the id of one of its ``effects`` (default: its ``fitted`` calibration, by the parameter's own name);
    ``parameter``: the name within that effect, when it has several."""

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


# One of the distributions, by its ``distribution`` key, or {from_diagnosis: ...}:
# a wrong one gives one message.
UncertainValue = Annotated[
    Annotated[Uniform, Tag("uniform")]
    | Annotated[Normal, Tag("normal")]
    | Annotated[LogNormal, Tag("lognormal")]
    | Annotated[Triangular, Tag("triangular")]
    | Annotated[FromDiagnosis, Tag("diagnosis")],
    Discriminator(
        _distribution_kind,
        custom_error_type="distribution",
        custom_error_message="expected {distribution: uniform | normal | lognormal | triangular, ...} "
        "or {from_diagnosis: FILE, effect: ...}",
    ),
]


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


# ---- drawing, running and summarising the draws ---------------------------------------------------------


def sample_name(scenario: str, k: int) -> str:
    return f"{scenario}{SEPARATOR}{k}"


def split_name(name: str) -> tuple[str, int | None]:
    """(the scenario, the draw) of a sampled scenario's name; (name, None) for any other."""
    base, sep, k = name.rpartition(SEPARATOR)
    return (base, int(k)) if sep and k.isdigit() else (name, None)


def frozen(spec: Any) -> Any:
    """The scipy.stats distribution a spec entry names (from_diagnosis entries resolved first)."""
    from scipy import stats  # on first use: scipy.stats costs every command about a second to import

    kind = spec.distribution
    if kind == "uniform":
        return stats.uniform(loc=spec.low, scale=spec.high - spec.low)
    if kind == "normal":
        return stats.norm(loc=spec.mean, scale=spec.std)
    if kind == "lognormal":
        return stats.lognorm(s=spec.std_log, scale=spec.median)
    return stats.triang(
        c=(spec.mode - spec.low) / (spec.high - spec.low), loc=spec.low, scale=spec.high - spec.low
    )


def from_diagnosis(entry: FromDiagnosis, name: str, base: Path, source: str) -> Normal:
    """A diagnosis's fitted value and interval as a normal: mean the value, std the half-width over 1.96."""
    where = f"{source}: uncertain.parameters.{name}"
    path = Path(entry.from_diagnosis)
    path = path if path.is_absolute() else base / path
    try:
        found = json.loads(path.read_text())
    except FileNotFoundError:
        raise DseError(f"{where}: from_diagnosis {entry.from_diagnosis!r}: no such file ({path})") from None
    except (OSError, ValueError) as e:
        raise DseError(f"{where}: from_diagnosis {path}: not a diagnosis's JSON ({e})") from None
    holder, label = _holder(found, entry, where, path)
    values, intervals = (
        holder.get("parameters") or {},
        holder.get("interval") or holder.get("intervals") or {},
    )
    key = entry.parameter or (next(iter(values)) if entry.effect is not None and len(values) == 1 else name)
    if key not in values or key not in intervals:
        short = name.rsplit(".", 1)[-1]
        key = short if entry.parameter is None and short in values and short in intervals else key
    if key not in values or key not in intervals:
        raise DseError(
            f"{where}: {label} in {path} has no fitted {key!r} with an interval (it has "
            f"{', '.join(values) or 'none'}); name one with 'parameter'"
        )
    value, (low, high) = float(values[key]), map(float, intervals[key])
    if not (math.isfinite(low) and math.isfinite(high) and high > low):
        raise DseError(
            f"{where}: {label} in {path}: {key}'s interval [{low}, {high}] is not a finite interval"
        )
    return Normal(distribution="normal", mean=value, std=(high - low) / 2 / Z95)


def _holder(found: Any, entry: FromDiagnosis, where: str, path: Path) -> tuple[dict, str]:
    """The part of a diagnosis's JSON holding the values: one of its effects, or its fitted calibration."""
    if not isinstance(found, dict):
        raise DseError(f"{where}: {path} is not a diagnosis's JSON (no object at its top)")
    if entry.effect is None:
        fitted = found.get("fitted")
        if not isinstance(fitted, dict):
            raise DseError(
                f"{where}: {path} has no 'fitted' calibration; name one of its effects with 'effect'"
            )
        return fitted, "its fitted calibration"
    effects = [e for e in found.get("effects", []) if isinstance(e, dict)]
    for effect in effects:
        if effect.get("id") == entry.effect:
            return effect, f"effect {entry.effect!r}"
    raise DseError(
        f"{where}: {path} has no effect {entry.effect!r} (it has "
        f"{', '.join(str(e.get('id')) for e in effects) or 'none'})"
    )


def resolved(uncertain: Uncertain, base: Path, source: str) -> dict[str, Any]:
    """Each uncertain parameter's distribution spec, a diagnosis's read as its normal."""
    return {
        name: from_diagnosis(d, name, base, source) if isinstance(d, FromDiagnosis) else d
        for name, d in uncertain.parameters.items()
    }


def unit_sample(n: int, d: int, sampling: str, seed: int) -> np.ndarray:
    """``n`` points in the unit cube of ``d`` dimensions, seeded. A scrambled Sobol' sequence's first points
    do not depend on ``n`` (more samples keep the earlier ones); a Latin hypercube's all do."""
    if sampling == "random":
        return np.random.default_rng(seed).random((n, d))
    from scipy.stats import qmc  # on first use, as in frozen()

    engine = (
        qmc.Sobol(d, scramble=True, seed=seed) if sampling == "sobol" else qmc.LatinHypercube(d, seed=seed)
    )
    with warnings.catch_warnings():
        warnings.simplefilter(
            "ignore", UserWarning
        )  # Sobol' at n not a power of 2: balanced less well, still fine
        return engine.random(n)


def draw(uncertain: Uncertain, distributions: dict[str, Any]) -> pd.DataFrame:
    """The sample: one row per draw, one column per uncertain parameter, plain floats."""
    import pandas as pd  # here, not at the top: a bad spec is named without it

    names = list(distributions)
    units = unit_sample(uncertain.samples, len(names), uncertain.sampling, uncertain.seed)
    table = pd.DataFrame({name: frozen(distributions[name]).ppf(units[:, i]) for i, name in enumerate(names)})
    bad = [name for name in names if not np.isfinite(table[name]).all()]
    if bad:  # a unit point at exactly 0 or 1 of an unbounded distribution
        raise DseError(f"uncertain: {', '.join(bad)}: a draw is infinite; change uncertain.seed")
    return table


def sampled(scenarios: list[Scenario], table: pd.DataFrame) -> list[Scenario]:
    """Every scenario once per draw, the draw's values on top of its own parameters, in its own group."""
    draws = table.to_dict("records")
    return [
        replace(
            s,
            name=sample_name(s.name, k),
            parameters={**s.parameters, **{p: float(v) for p, v in row.items()}},
        )
        for s in scenarios
        for k, row in enumerate(draws)
    ]


def identity(uncertain: Uncertain, distributions: dict[str, Any]) -> dict[str, Any]:
    """What determines each draw's values besides its index: part of the model's hash, so that rows of another
    seed or distribution, whose scenarios bear the same names, are never ranked with these."""
    found = {
        "sampling": uncertain.sampling,
        "seed": uncertain.seed,
        "parameters": {n: d.model_dump(mode="json") for n, d in distributions.items()},
    }
    if uncertain.sampling == "latin_hypercube":
        found["samples"] = uncertain.samples
    return found


# --- statistics over the draws (the reducer's) --------------------------------------------------------------


def label(q: float) -> str:
    """A quantile's column suffix: 0.05 -> q5, 0.5 -> q50, 0.975 -> q97.5."""
    return f"q{100 * q:g}"


def with_draws(rows: pd.DataFrame, samples: int) -> pd.DataFrame:
    """``rows`` with columns ``base`` (the scenario) and ``sample`` (the draw), only those of draws below
    ``samples`` (a sweep run earlier with more keeps its rows, which this one does not rank)."""
    parts = [split_name(name) for name in rows["scenario"].astype(str)]
    rows = rows.assign(base=[b for b, _ in parts], sample=[-1 if k is None else k for _, k in parts])
    return rows[(rows["sample"] >= 0) & (rows["sample"] < samples)]


def per_draw(
    ok: pd.DataFrame, parameters: list[str], objectives: list[str], over: str, scenarios: int
) -> pd.DataFrame:
    """Each (point, draw)'s objectives reduced over the scenarios as the ranking says; only draws with an ok
    row on all ``scenarios``."""
    grouped = ok.groupby([*parameters, "sample"], dropna=False)
    reduced = grouped[objectives].agg(over)
    return reduced[grouped.size() == scenarios].reset_index()


def summarise(
    draws: pd.DataFrame, parameters: list[str], objectives: list[str], quantiles: list[float], samples: int
) -> pd.DataFrame:
    """Per point with all ``samples`` draws: each objective's mean (the objective's own column), std (sample,
    ddof 1) and quantiles over the draws, and ``draws``."""
    grouped = draws.groupby(parameters, dropna=False)
    table = grouped[objectives].mean()
    for name in objectives:
        table[f"{name}_std"] = grouped[name].std(ddof=1)
        for q in quantiles:
            table[f"{name}_{label(q)}"] = grouped[name].quantile(q)
    table["draws"] = grouped.size()
    return table[table["draws"] == samples].reset_index()


def robust_column(objective: str) -> str:
    return f"{objective}_robust"


def robust_values(
    draws: pd.DataFrame, parameters: list[str], objective: str, robust: Robust, goal: str
) -> pd.Series:
    """The robust figure of ``objective`` per point: mean +/- k std towards the worse side, or a quantile."""
    grouped = draws.groupby(parameters, dropna=False)[objective]
    if robust.quantile is not None:
        return grouped.quantile(robust.quantile)
    sign = 1.0 if goal == "min" else -1.0
    return grouped.mean() + sign * robust.sigmas * grouped.std(ddof=1)


def robust_of(values: np.ndarray, robust: Robust | None, goal: str) -> float:
    """One point's figure from its per-draw values: the robust one, or the mean (a search's told value)."""
    values = np.asarray(values, dtype=float)
    if robust is None:
        return float(np.mean(values))
    if robust.quantile is not None:
        return float(np.quantile(values, robust.quantile))
    spread = float(np.std(values, ddof=1)) if len(values) > 1 else 0.0
    return float(np.mean(values)) + (1.0 if goal == "min" else -1.0) * robust.sigmas * spread


def collapse(ok: pd.DataFrame, parameters: list[str], objectives: list[str]) -> pd.DataFrame:
    """Rows of sampled scenarios as one row per point and scenario, each objective its mean over the draws:
    what Table 1, the group rankings and the per-scenario charts show."""
    if ok.empty:
        return ok
    keys = [*parameters, "base", "group"]
    merged = ok.groupby(keys, dropna=False)[objectives].mean().reset_index()
    return merged.rename(columns={"base": "scenario"})
