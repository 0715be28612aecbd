"""Global sensitivity of a sweep's objectives to its parameters: Sobol' indices, Morris screening or eFAST.

A sweep sampled by a sensitivity design (sweeps/strategies/designs.py: ``sobol_indices``,
``morris``, ``fast``) is read back here. The design is drawn again from the spec the sweep saved (the same
seed, budget and constraints give the same rows), each row's objective is looked up in the
store by its point, reduced over the scenarios as the ranking reduces them (``over_scenarios``),
for all scenarios and for each scenario group, and SALib's estimators turn the rows into indices
with bootstrap confidence intervals. Blocks the estimator cannot use whole (a point failed, is
not simulated yet, or was refused by a constraint) are left out and counted.

Why SALib: its estimators are the reference ones (Saltelli 2010 for S1 and ST, Saltelli 2002 for
S2, Campolongo 2007 for mu*, Saltelli, Tarantola and Chan 1999 for eFAST), with bootstrap intervals
built in; docs/dependencies.md. eFAST reads each parameter's search curve alone: a curve with a point
missing leaves that parameter without indices, the others keep theirs.
"""

from __future__ import annotations

import hashlib
import math
import os
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
from pydantic import BaseModel, ValidationError

from ..errors import DseError, did_you_mean
from ..sweeps import aggregate, store
from ..sweeps.constraints import compile_constraint
from ..sweeps.domain import Dimension, dimension
from ..sweeps.rank import (
    REDUCED,
    SWEEP_FILE,
    complete_totals,
    current_model,
    current_table,
    load_sweep_spec,
    pick_sweep,
    scalar_objectives,
)
from ..sweeps.search import Problem, strategy
from ..sweeps.spec import SpaceSpec
from ..sweeps.strategies.designs import Design, SensitivityDesign, interval_values, salib_problem

CONFIDENCE = 0.95  # bootstrap interval level
RESAMPLES = 100  # bootstrap resamples (SALib's default)
WIDE = 0.1  # a Sobol' index known only to +/- this is too loose to tell parameters apart
NEGLIGIBLE = (
    0.01  # factor fixing (Saltelli et al. 2008): a total index surely below this may be fixed anywhere
)
# An objective whose std is below this fraction of its mean barely varies: its indices share out noise.
FLAT = 1e-6
FAST_INTERVALS = (
    "eFAST's intervals are SALib's bootstrap of each search curve, which SALib itself calls "
    "indicative only (SALib issue 649): judge the indices by their values, not by these intervals"
)
# From this many rows SALib's Sobol' bootstrap runs a process per parameter (its ``parallel``, the
# same numbers): 14 s alone at a million rows on 2 cores, 7 s in two; below, it takes under a
# second, less than starting them.
PARALLEL_ROWS = 100_000
MIN_TRAJECTORIES = 10  # Morris: fewer trajectories than this screen poorly (Campolongo et al. 2007 use 10-20)


@dataclass
class Scope:
    """One objective's indices over one set of scenarios: all of them, or one group's."""

    scenarios: int
    blocks: int  # blocks the estimator used
    left_out: int  # blocks with a point missing
    parameters: dict[str, dict[str, float | None]]  # parameter -> S1, S1_conf, ST, ST_conf | mu, mu_star, ...
    spread: dict[str, float | None]  # the objective over the sample: mean, std, cv (std / |mean|)
    second_order: dict[str, dict[str, float | None]] = field(default_factory=dict)  # "a x b" -> S2, S2_conf
    note: str | None = None  # why there are no indices, or why they are all zero

    def to_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {
            "scenarios": self.scenarios,
            "blocks": self.blocks,
            "left_out": self.left_out,
            "spread": self.spread,
            "parameters": self.parameters,
            "note": self.note,
        }
        if self.second_order:
            data["second_order"] = self.second_order
        return data


@dataclass
class ObjectiveIndices:
    """One objective's indices over every scenario, and within each scenario
    group (when there are several)."""

    overall: Scope | None
    groups: dict[str, Scope]


@dataclass
class Sensitivity:
    sweep: str
    method: str  # "sobol" | "morris" | "fast"
    parameters: list[str]
    reduced: str  # how scenarios were combined: total, mean, largest, smallest
    design: dict[str, Any]  # strategy, rows, blocks, block, seed
    confidence: float
    objectives: dict[str, ObjectiveIndices]
    warnings: list[str]

    @property
    def indices(self) -> bool:
        """Whether the method gives first-order and total indices (Sobol', eFAST)
        rather than Morris' mu*, sigma."""
        return self.method != "morris"

    def negligible(self, objective: str, group: str | None = None) -> list[str]:
        """Parameters that can be fixed anywhere in their range (factor fixing): the upper end of the total
        index's interval is below NEGLIGIBLE (Morris: of mu*'s, below NEGLIGIBLE of the largest mu*)."""
        found = self.objectives[objective]
        found = (found.overall if group is None else found.groups[group]).parameters
        key, conf = ("ST", "ST_conf") if self.indices else ("mu_star", "mu_star_conf")
        known = {name: v for name, v in found.items() if v.get(key) is not None}
        if not known:
            return []
        scale = 1.0 if self.indices else max(v[key] for v in known.values())
        return [name for name, v in known.items() if v[key] + (v.get(conf) or 0.0) < NEGLIGIBLE * scale]

    def least_responsive(self, objective: str) -> list[tuple[str, float]]:
        """Scenario groups by how little the objective varies over the sample (its coefficient of
        variation), least first: the indices say which parameter moves an objective, this says whether
        the objective moves at all."""
        groups = [
            (name, scope.spread["cv"])
            for name, scope in self.objectives[objective].groups.items()
            if scope.spread.get("cv") is not None
        ]
        return sorted(groups, key=lambda item: item[1])

    def to_json(self) -> dict[str, Any]:
        objectives = {}
        for name, found in self.objectives.items():
            objectives[name] = {
                **found.overall.to_json(),
                "negligible": self.negligible(name),
                "groups": {
                    g: {**s.to_json(), "negligible": self.negligible(name, g)}
                    for g, s in found.groups.items()
                },
                "least_responsive_groups": [g for g, _ in self.least_responsive(name)],
            }
        return {
            "sweep": self.sweep,
            "method": self.method,
            "parameters": self.parameters,
            "reduced": self.reduced,
            "design": self.design,
            "confidence": self.confidence,
            "objectives": objectives,
            "warnings": self.warnings,
        }


def stored_design(spec: SpaceSpec) -> tuple[Design, tuple[Dimension, ...]]:
    """The design a sweep ran, drawn again from its saved spec."""
    kind = strategy(spec.search.strategy)
    if not issubclass(kind, SensitivityDesign):
        raise DseError(
            f"sweep {spec.name!r} was sampled by {spec.search.strategy!r}; sensitivity reads a "
            "sweep sampled for it: search.strategy sobol_indices, morris or fast (docs/sensitivity.md)"
        )
    dimensions = tuple(dimension(name, values) for name, values in spec.parameters.items())
    checks = [compile_constraint(text, {d.name for d in dimensions}) for text in spec.constraints]
    problem = Problem(
        label=spec.name,
        dimensions=dimensions,
        objective=(spec.ranking.objective, spec.ranking.goal),
        pareto=(),
        scenarios=(),
        vectors=(),
        max_points=spec.search.max_points,
        seed=spec.search.seed,
        batch=1,
        options=spec.search.options,
        admits=lambda p: all(check(p) for check in checks),
        constrained=bool(checks),
    )
    return kind(problem).design, dimensions


CACHE_FILE = "sensitivity.json"  # <sweep>.sensitivity.json: the indices of one version of the store


class Cached(BaseModel):
    """The file format of the indices kept beside a sweep's results: what they were computed from (``key``:
    the store's version, the model, the spec, the options, SALib's version) and the indices."""

    key: str
    found: Sensitivity


def sensitivity(
    output: Any,
    sweep: str | None = None,
    objectives: list[str] | None = None,
    confidence: float = CONFIDENCE,
    resamples: int = RESAMPLES,
) -> Sensitivity:
    """Indices of every scalar objective (or those named) of ``sweep``, overall and per scenario group;
    computed once per version of the store and kept in it: the bootstrap of a million-row design takes
    its time, and the report, the dashboard and this command all show the same indices."""
    if not 0 < confidence < 1:
        raise DseError(f"--confidence {confidence}: give a level between 0 and 1, e.g. 0.95")
    if resamples < 2:
        raise DseError(f"--resamples {resamples}: bootstrap intervals need at least 2 resamples")
    sweep = pick_sweep(output, sweep)
    key = _cache_key(output, sweep, objectives, confidence, resamples)
    text = store.read_text(output, f"{sweep}.{CACHE_FILE}")
    if text is not None:
        try:
            cached = Cached.model_validate_json(text)
            if cached.key == key:
                return cached.found
        except ValidationError:  # another version's file: computed again below
            pass
    found = _computed(output, sweep, objectives, confidence, resamples)
    try:
        store.write_text(output, f"{sweep}.{CACHE_FILE}", Cached(key=key, found=found).model_dump_json())
    except OSError:  # a store this process may only read: the indices are still shown
        pass
    return found


def _cache_key(
    output: Any, sweep: str, objectives: list[str] | None, confidence: float, resamples: int
) -> str:
    """What the indices depend on: the rows (the store's version and the current model), the spec the sweep
    ran with (its design), the options and the estimator's version."""
    from importlib.metadata import version

    parts = [
        store.version(output, sweep),
        current_model(output, sweep),
        store.read_text(output, f"{sweep}.{SWEEP_FILE}"),
        objectives,
        confidence,
        resamples,
        version("SALib"),
    ]
    return hashlib.sha256(repr(parts).encode()).hexdigest()[:32]


def _computed(
    output: Any, sweep: str, objectives: list[str] | None, confidence: float, resamples: int
) -> Sensitivity:
    spec = load_sweep_spec(output, sweep)
    if spec.uncertain is not None:
        raise DseError(
            f"sweep {sweep!r} runs each point over uncertain draws; sensitivity reads a sweep without "
            "an uncertain block (its parameters' indices would mix in the draws' spread): sample the "
            "uncertain parameters as parameters of a sobol_indices sweep instead"
        )
    design, dimensions = stored_design(spec)
    parameters = [d.name for d in dimensions]
    scalar = scalar_objectives(spec, output, sweep)
    for name in objectives or []:
        if name not in scalar:
            raise DseError(
                f"objective {name!r} is not among sweep {sweep!r}'s ({', '.join(scalar)})"
                f"{did_you_mean(name, scalar)}"
            )
    chosen = list(objectives or scalar)
    rows = current_table(output, sweep, ["group", "status", *parameters, *chosen])
    if rows.num_rows == 0:
        raise DseError(f"{output}: sweep {sweep!r} has no rows yet")
    fast = interval_values(dimensions, design.units)  # a million rows without a dict each, where it applies
    points = pd.DataFrame(fast if fast is not None else design.points(dimensions), columns=parameters)
    over = spec.ranking.over_scenarios
    groups = aggregate.statistics(rows, ["group"], "scenario", ["count_distinct"])["group"].tolist()
    scopes = [
        (None, rows),
        *(((str(g), rows.filter(pc.equal(rows["group"], g))) for g in groups) if len(groups) > 1 else ()),
    ]
    found = {name: ObjectiveIndices(overall=None, groups={}) for name in chosen}
    notes: list[str] = []
    wide: dict[str, list[str]] = {
        name: [] for name in chosen
    }  # per objective, the groups whose intervals are wide
    for group, members in scopes:
        n_scenarios = aggregate.distinct(members, "scenario")
        values = aggregate.aligned(
            points, _reduced(members, parameters, chosen, over, n_scenarios), parameters, chosen
        )
        for name in chosen:
            scope = _scope(
                design,
                values[name].to_numpy(float),
                parameters,
                n_scenarios,
                confidence,
                resamples,
                spec.search.seed + 1,
            )
            if group is None:
                found[name].overall = scope
                notes.extend(_warnings(design, scope, f"{name} (all scenarios)"))
                continue
            found[name].groups[group] = scope
            if scope.left_out or scope.blocks < 2 or design.method != "sobol":
                notes.extend(_warnings(design, scope, f"{name} (group {group})"))
            elif _widest(scope) > WIDE:  # one line per objective for all its wide groups, below
                wide[name].append(f"{group} +/-{_widest(scope):.2f}")
    notes.extend(
        f"{name}: intervals wider than +/-{WIDE} in groups {', '.join(listed)}"
        for name, listed in wide.items()
        if listed
    )
    if design.method == "fast":
        notes.append(FAST_INTERVALS)
    return Sensitivity(
        sweep,
        design.method,
        parameters,
        REDUCED[over],
        {
            "strategy": spec.search.strategy,
            "rows": len(design.units),
            "blocks": design.blocks,
            "block": design.block,
            "seed": spec.search.seed,
            "second_order": design.second_order,
            "levels": design.levels or None,
            "harmonics": design.harmonics or None,
        },
        confidence,
        found,
        notes,
    )


def _reduced(
    rows: pa.Table, parameters: list[str], objectives: list[str], over: str, scenarios: int
) -> pd.DataFrame:
    """Each point's objectives reduced over the ``scenarios`` of ``rows``; only
    points ok on every one of them."""
    return complete_totals(aggregate.ok_rows(rows), parameters, objectives, over, scenarios)


def _scope(
    design: Design,
    y: np.ndarray,
    parameters: list[str],
    scenarios: int,
    confidence: float,
    resamples: int,
    seed: int,
) -> Scope:
    """Indices from the design's whole blocks: each block is one estimator term, so leaving one out
    leaves the estimate unbiased over the rest (though no longer quasi-random)."""
    whole = ~np.isnan(y.reshape(design.blocks, design.block)).any(axis=1)
    rows = np.repeat(whole, design.block)
    full = y  # eFAST reads curve i as rows i N .. (i + 1) N - 1: its incomplete curves stay in place, unread
    y, x = y[rows], design.units[rows]
    used, left_out = int(whole.sum()), int((~whole).sum())
    mean, std = (float(np.mean(y)), float(np.std(y))) if len(y) else (None, None)
    cv = std / abs(mean) if mean else None
    spread = {"mean": mean, "std": std, "cv": cv}
    empty = {name: dict.fromkeys(_keys(design.method)) for name in parameters}
    least = 1 if design.method == "fast" else 2  # an eFAST curve is one parameter's whole estimate
    if used < least:
        return Scope(
            scenarios, used, left_out, empty, spread, note=f"{used} whole block(s): too few to estimate"
        )
    if np.ptp(y) == 0.0:  # no variance to share out: no parameter has an effect
        zero = {name: dict.fromkeys(_keys(design.method), 0.0) for name in parameters}
        return Scope(
            scenarios, used, left_out, zero, spread, note="constant over the sample: no parameter moves it"
        )
    found = _estimate(
        design, full if design.method == "fast" else y, x, parameters, confidence, resamples, seed
    )
    indices = {
        name: {
            key: float(found[key][i]) if design.method != "fast" or whole[i] else None
            for key in _keys(design.method)
        }
        for i, name in enumerate(parameters)
    }
    pairs = {}
    if design.method == "sobol" and design.second_order:
        for i, a in enumerate(parameters):
            for j in range(i + 1, len(parameters)):
                pairs[f"{a} x {parameters[j]}"] = {
                    "S2": float(found["S2"][i, j]),
                    "S2_conf": float(found["S2_conf"][i, j]),
                }
    note = None
    if cv is not None and cv < FLAT:
        note = (
            f"varies by only {cv:.1g} of its mean over the sample: "
            "the indices share out what may be rounding noise"
        )
    return Scope(scenarios, used, left_out, indices, spread, pairs, note)


def _estimate(
    design: Design,
    y: np.ndarray,
    x: np.ndarray,
    parameters: list[str],
    confidence: float,
    resamples: int,
    seed: int,
) -> dict[str, Any]:
    """SALib's estimator of the design's method on its outputs ``y`` (Morris also reads the inputs ``x``)."""
    problem = salib_problem(tuple(Dimension(name) for name in parameters))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", (RuntimeWarning, UserWarning))
        if design.method == "sobol":
            from SALib.analyze import sobol

            processes = bootstrap_processes(len(y), len(parameters))
            return sobol.analyze(
                problem,
                y,
                calc_second_order=design.second_order,
                num_resamples=resamples,
                conf_level=confidence,
                seed=seed,
                parallel=processes > 1,
                n_processors=processes,
            )
        if design.method == "fast":
            from SALib.analyze import fast

            return fast.analyze(
                problem, y, M=design.harmonics, num_resamples=resamples, conf_level=confidence, seed=seed
            )
        from SALib.analyze import morris

        return morris.analyze(
            problem, x, y, num_resamples=resamples, conf_level=confidence, num_levels=design.levels, seed=seed
        )


def bootstrap_processes(rows: int, parameters: int) -> int:
    """How many processes SALib's Sobol' bootstrap gets: one per parameter up to the cores, from PARALLEL_ROWS
    rows; one below."""
    return 1 if rows < PARALLEL_ROWS else max(1, min(os.cpu_count() or 1, parameters))


def _keys(method: str) -> tuple[str, ...]:
    return (
        ("mu", "mu_star", "sigma", "mu_star_conf")
        if method == "morris"
        else ("S1", "S1_conf", "ST", "ST_conf")
    )


def _warnings(design: Design, scope: Scope, label: str) -> list[str]:
    """What makes these indices less than the user asked for: blocks lost, or a sample too small."""
    found = []
    if scope.left_out:
        found.append(
            f"{label}: {scope.left_out} of {scope.blocks + scope.left_out} blocks left out (a point failed, "
            "has no result yet, or a constraint refused it)"
        )
    if scope.note and scope.blocks < 2:
        found.append(f"{label}: {scope.note}")
        return found
    if (
        design.method == "fast"
    ):  # a curve's length is fixed by the design (> 4 M^2); its intervals are SALib's caveat
        return found
    if design.method == "morris":
        if scope.blocks < MIN_TRAJECTORIES:
            found.append(
                f"{label}: {scope.blocks} trajectories; screening wants at least {MIN_TRAJECTORIES} "
                f"(max_points >= {MIN_TRAJECTORIES * design.block})"
            )
        return found
    widest = _widest(scope)
    if widest > WIDE:
        needed = math.ceil(scope.blocks * (widest / WIDE) ** 2)  # intervals narrow as 1 / sqrt(blocks)
        found.append(
            f"{label}: intervals up to +/-{widest:.2f}, too wide to tell parameters apart (over {WIDE}); "
            f"about {needed} base rows would narrow them to {WIDE} (max_points >= {needed * design.block})"
        )
    return found


def _widest(scope: Scope) -> float:
    """The widest half-width among a scope's intervals."""
    return max(
        (v for p in scope.parameters.values() for k, v in p.items() if k.endswith("_conf") and v is not None),
        default=0.0,
    )
