"""The reducer: from result rows to rankings.

* totals: each objective summed over a point's scenarios (the paper's
  Equation 2 / Algorithm 2), or their mean, worst or best as
  ``ranking.over_scenarios`` says; the best point minimises (or maximises) the
  ranking objective's total. Only points with an ok row for every scenario
  are ranked; the others are counted as incomplete.
* runs an FMU ended early (status ``stopped``, objectives over the span the
  run reached, ``span_end``): a point with one is ranked, after every point
  whose runs all reached the stop time (its ``stopped`` column counts them), so
  the best point is a complete one whenever there is one; the Pareto front and
  the best per group are over complete points only. With uncertain draws, a
  stopped draw leaves its point incomplete.
* Table 1 (the paper's): per scenario, min, max and average over the ranked
  points, and the value at the best point with its difference from the average.
* the Pareto front over any number of objectives, each minimised or maximised;
* the best point within each scenario group;
* weighted sums of the objectives' totals.

Only the columns needed are read from Parquet; trajectories are never loaded.
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from .. import strict_json
from ..errors import DseError, did_you_mean
from ..simulation.objectives import Fit, normalise
from . import aggregate, store, uncertainty
from .constraints import compile_constraint
from .domain import Point
from .spec import RankingSpec, SpaceSpec

SWEEP_FILE = "sweep.json"  # the spec a sweep ran with, saved beside its results
MODEL_FILE = "model"  # the hash of the model it last ran
SAMPLE_FILE = "sample.csv"  # with uncertain parameters: a row per draw, the values it ran with


REDUCED = {"sum": "total", "mean": "mean", "max": "largest", "min": "smallest"}  # ranking.over_scenarios


@dataclass
class Ranking:
    sweep: str
    parameters: list[str]
    objective: str
    goal: str
    best: dict[str, Any]
    best_total: float
    totals: pd.DataFrame  # one row per complete point, best first
    table1: pd.DataFrame
    pareto: pd.DataFrame
    groups: pd.DataFrame
    weighted: pd.DataFrame
    incomplete_points: int
    failed_rows: int
    excluded_points: int = 0  # complete points that break one of the ranking's constraints
    stopped_points: int = 0  # ranked points with a run an FMU ended early: ranked after the others
    over_scenarios: str = "sum"  # how each objective was reduced over the scenarios
    constraints: tuple[str, ...] = ()  # the ranking's constraints on objectives, as written
    ranked_by: str = ""  # the totals' column the points are ranked by: the objective, or its robust figure
    uncertainty: dict[str, Any] | None = (
        None  # with an uncertain block: samples, quantiles, robust, distributions
    )
    draws: pd.DataFrame | None = (
        None  # per ranked point and draw: the drawn values, the objectives over scenarios
    )

    @property
    def reduced(self) -> str:
        """How the ranked figures came from the scenarios, for labels: 'total',
        'mean', 'largest', 'smallest'."""
        return REDUCED[self.over_scenarios]

    @property
    def ranked_label(self) -> str:
        """What ``best_total`` is, in words: ``total y``, or ``mean+1sd of total y over 64 draws``."""
        if self.uncertainty is None:
            return figure_label(self.objective, self.reduced, None)
        return (
            f"{figure_label(self.objective, self.reduced, self.uncertainty['ranked_by'])} "
            f"over {self.uncertainty['samples']} draws"
        )

    def to_json(self) -> dict[str, Any]:
        def records(frame: pd.DataFrame, limit: int | None = None) -> list[dict[str, Any]]:
            return (
                json.loads(frame.head(limit).to_json(orient="records"))
                if limit
                else json.loads(frame.to_json(orient="records"))
            )

        return {
            "sweep": self.sweep,
            "objective": self.objective,
            "goal": self.goal,
            "best": self.best,
            "best_total": self.best_total,
            "points": len(self.totals),
            "incomplete_points": self.incomplete_points,
            "excluded_points": self.excluded_points,
            "failed_rows": self.failed_rows,
            "stopped_points": self.stopped_points,
            "table1": records(self.table1),
            "pareto": records(self.pareto),
            "groups": records(self.groups),
            "weighted": records(self.weighted, 10),
            "top": records(self.totals, 10),
            **({"ranked_by": self.ranked_by, "uncertainty": self.uncertainty} if self.uncertainty else {}),
        }


def save_sweep_spec(
    output: store.Root, spec: SpaceSpec, model: str, sample: pd.DataFrame | None = None
) -> None:
    """The spec a sweep runs with, the hash of its model, whose rows rankings use, and with uncertain
    parameters its sample: the rows name a draw only by its number (``<scenario>~u<k>``), and the spec
    alone may not remake the values (a diagnosis's file it read can be gone)."""
    store.write_text(output, f"{spec.name}.{SWEEP_FILE}", spec.model_dump_json(indent=2))
    store.write_text(output, f"{spec.name}.{MODEL_FILE}", model + "\n")
    if sample is not None:
        store.write_text(
            output,
            f"{spec.name}.{SAMPLE_FILE}",
            sample.rename_axis("sample").reset_index().to_csv(index=False),
        )


def with_drawn_values(draws: pd.DataFrame, output: store.Root, sweep: str) -> pd.DataFrame:
    """``draws`` (a row per point and draw) with the values each draw's uncertain parameters ran with, after
    ``sample``; as it is for a store saved without them."""
    text = store.read_text(output, f"{sweep}.{SAMPLE_FILE}")
    if text is None:
        return draws
    sample = pd.read_csv(io.StringIO(text))
    drawn = [c for c in sample.columns if c != "sample" and c not in draws.columns]
    at = list(draws.columns).index("sample") + 1
    order = [*draws.columns[:at], *drawn, *draws.columns[at:]]
    return draws.merge(sample[["sample", *drawn]], on="sample", how="left")[order]


def current_model(output: store.Root, sweep: str) -> str | None:
    text = store.read_text(output, f"{sweep}.{MODEL_FILE}")
    return text.strip() if text is not None else None


def load_sweep_spec(output: store.Root, sweep: str) -> SpaceSpec:
    text = store.read_text(output, f"{sweep}.{SWEEP_FILE}")
    if text is None:
        held = store.sweeps(output)
        if held and sweep not in held:  # a misspelt --sweep
            raise DseError(
                f"{output}: no sweep {sweep!r}{did_you_mean(sweep, held)}; it holds {', '.join(held)}"
            )
        raise DseError(
            f"{output}: no {sweep}.{SWEEP_FILE}; is this the output folder of a dse-runner submit?"
        )
    return SpaceSpec.model_validate_json(text)


def _sign(goal: str) -> float:
    return 1.0 if goal == "min" else -1.0


def pareto_mask(values: np.ndarray, goals: list[str]) -> np.ndarray:
    """Rows not dominated by any other row; ``values`` is points x objectives. pymoo's
    non-dominated sort (first front only): 100,000 points in about a second
    (benchmarks/pareto.py). Equal rows share their fate."""
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

    costs = np.asarray(values, dtype=float) * np.array([_sign(g) for g in goals])  # everything minimised
    mask = np.zeros(len(costs), dtype=bool)
    if len(costs):
        mask[NonDominatedSorting().do(costs, only_non_dominated_front=True)] = True
    return mask


def _best_first(frame: pd.DataFrame, column: str, goal: str) -> pd.DataFrame:
    return frame.sort_values(column, ascending=(goal == "min"), kind="stable").reset_index(drop=True)


def current_table(output: store.Root, sweep: str, columns: list[str]) -> pa.Table:
    """The sweep's rows of its current model, ``columns`` of them: rows of an earlier version of the model (a
    changed FMU or objective list) are neither ranked nor shown, nor read. The last table read is kept while
    the store is unchanged: the report ranks and then draws the same rows."""
    model = current_model(output, sweep)
    key = (str(output), sweep, model, store.version(output, sweep))
    kept = _LAST_READ.get(key)
    if kept is not None and set(columns) <= set(kept.column_names):
        return kept.select(list(dict.fromkeys(["task_id", "sweep", "scenario", *columns])))
    table = store.read_table(output, sweep, columns=columns, model=model)
    _LAST_READ.clear()
    _LAST_READ[key] = table
    return table


_LAST_READ: dict[tuple, pa.Table] = {}  # current_table's last table, by store, sweep, model and store version


def current_rows(output: store.Root, sweep: str, columns: list[str]) -> pd.DataFrame:
    """current_table's rows as a DataFrame."""
    return current_table(output, sweep, columns).to_pandas()


def pick_sweep(output: store.Root, sweep: str | None) -> str:
    """``sweep``, or the one sweep ``output`` holds results of."""
    if sweep is not None:
        return sweep
    names = store.sweeps(output)
    if not names:
        raise DseError(f"{output}: no results (expected {store.RESULTS}/sweep=NAME/...)")
    if len(names) > 1:
        raise DseError(f"{output} holds several sweeps ({', '.join(names)}): name one with --sweep")
    return names[0]


def rank(output: store.Root, sweep: str | None = None, settings: RankingSpec | None = None) -> Ranking:
    """Rank the results in ``output`` with the sweep's own ranking settings unless given others."""
    sweep = pick_sweep(output, sweep)
    spec = load_sweep_spec(output, sweep)
    settings = settings or spec.ranking
    parameters = list(spec.parameters)
    objectives = scalar_objectives(spec, output, sweep)
    pareto = settings.pareto_goals()
    for name in settings.objectives_used():
        if name not in objectives:
            raise DseError(
                f"ranking: objective {name!r} is not among the sweep's ({', '.join(objectives)})"
                f"{did_you_mean(name, objectives)}"
            )

    rows = current_table(output, sweep, ["group", "status", *parameters, *objectives])
    if rows.num_rows == 0:
        raise DseError(f"{output}: sweep {sweep!r} has no rows yet")
    draws, about = None, None
    ranked_by = settings.objective
    if spec.uncertain is not None:  # a row per draw: reduced in pandas, over the draws' names
        rows = uncertainty.with_draws(rows.to_pandas(), spec.uncertain.samples)
        failed = int((rows["status"] != "ok").sum())
        complete, draws, n_points = _over_draws(rows, parameters, objectives, settings, spec)
        ok = uncertainty.collapse(rows[rows["status"] == "ok"], parameters, objectives)
        rows = rows.assign(scenario=rows["base"])  # Table 1 and the groups are per scenario, over the draws
        about = _about(spec, settings)
        ranked_by = uncertainty.robust_column(settings.objective) if settings.robust else settings.objective
    else:
        ok = aggregate.scored_rows(rows)  # ok, and stopped early: ranked after the complete points
        failed = rows.num_rows - ok.num_rows
        n_scenarios = aggregate.distinct(rows, "scenario")
        points = aggregate.per_point(ok, parameters, objectives, settings.over_scenarios)
        n_points = len(points)
        complete = with_stopped(_complete(points, n_scenarios), ok, parameters)
        if complete.empty:
            raise DseError(
                f"sweep {sweep!r}: no parameter point has an ok result for all {n_scenarios} scenarios"
            )
    admitted = admits(complete, settings.constraints, objectives)
    excluded = int((~admitted).sum())
    complete = complete[admitted]
    if complete.empty:
        raise DseError(
            f"sweep {sweep!r}: every complete point breaks a ranking constraint "
            f"({'; '.join(settings.constraints)})"
        )
    complete = _stopped_last(_best_first(complete, ranked_by, settings.goal))
    whole = complete[complete[STOPPED] == 0] if STOPPED in complete else complete  # every run to the end
    best = {p: plain(complete.loc[0, p]) for p in parameters}
    if draws is not None:
        draws = with_drawn_values(
            draws[_of_points(draws, complete, parameters)].reset_index(drop=True), output, sweep
        )

    ranked_ok = ok if len(complete) == n_points else aggregate.of_points(ok, complete, parameters)
    table1 = _table1(ranked_ok, settings.objective, best)
    if pareto:
        cols = [n for n, _ in pareto]
        front = whole[pareto_mask(whole[cols].to_numpy(float), [g for _, g in pareto])]
        front = front.sort_values(cols[0], ascending=pareto[0][1] == "min").reset_index(drop=True)
    else:
        front = complete.iloc[0:0]
    full = ok if whole is complete else aggregate.ok_rows(ok)  # a group's best: of complete runs too
    groups = _groups(full, parameters, settings.objective, settings.goal, rows)
    weighted = complete.iloc[0:0].assign(weighted=pd.Series(dtype=float))
    if settings.weights:
        score = sum(weight * complete[name] for name, weight in settings.weights.items())
        weighted = _stopped_last(_best_first(complete.assign(weighted=score), "weighted", settings.goal))

    return Ranking(
        sweep,
        parameters,
        settings.objective,
        settings.goal,
        best,
        float(complete.loc[0, ranked_by]),
        complete,
        table1,
        front,
        groups,
        weighted,
        incomplete_points=n_points - len(complete) - excluded,
        failed_rows=failed,
        excluded_points=excluded,
        stopped_points=len(complete) - len(whole),
        over_scenarios=settings.over_scenarios,
        constraints=tuple(settings.constraints),
        ranked_by=ranked_by,
        uncertainty=about,
        draws=draws,
    )


def _over_draws(
    rows: pd.DataFrame, parameters: list[str], objectives: list[str], settings: RankingSpec, spec: SpaceSpec
) -> tuple[pd.DataFrame, pd.DataFrame, int]:
    """(complete points with each objective's mean, std and quantiles over the draws and, if asked, the robust
    figure; every draw of them; how many points have any ok row): ``rows`` of sampled scenarios."""
    uncertain = spec.uncertain
    ok = rows[rows["status"] == "ok"]
    n_scenarios = rows["base"].nunique()
    draws = uncertainty.per_draw(ok, parameters, objectives, settings.over_scenarios, n_scenarios)
    complete = uncertainty.summarise(draws, parameters, objectives, uncertain.quantiles, uncertain.samples)
    if complete.empty:
        raise DseError(
            f"sweep {spec.name!r}: no parameter point has an ok result for all {n_scenarios} scenarios "
            f"in each of its {uncertain.samples} uncertain draws"
        )
    complete = complete.drop(columns="draws")
    if settings.robust is not None:
        figure = uncertainty.robust_values(
            draws, parameters, settings.objective, settings.robust, settings.goal
        )
        keys = (
            pd.MultiIndex.from_frame(complete[parameters]) if len(parameters) > 1 else complete[parameters[0]]
        )
        complete[uncertainty.robust_column(settings.objective)] = figure.reindex(keys).to_numpy()
    return complete, draws, ok.groupby(parameters, dropna=False).ngroups


def _about(spec: SpaceSpec, settings: RankingSpec) -> dict[str, Any]:
    """The ranking JSON's ``uncertainty``: how the draws were made and how points are ranked over them."""
    uncertain = spec.uncertain
    robust = settings.robust
    return {
        "samples": uncertain.samples,
        "sampling": uncertain.sampling,
        "seed": uncertain.seed,
        "quantiles": list(uncertain.quantiles),
        "ranked_by": robust.label(settings.goal) if robust is not None else "mean",
        "robust": robust.model_dump(exclude_none=True) if robust is not None else None,
        "parameters": {
            n: d.model_dump(mode="json", exclude_none=True) for n, d in uncertain.parameters.items()
        },
        "columns": "each objective's column is its mean over the draws; <objective>_std the standard "
        "deviation (ddof 1), <objective>_q<percent> its quantiles, <objective>_robust the ranked figure",
    }


def scalar_objectives(spec: SpaceSpec, output: store.Root, sweep: str) -> list[str]:
    """The sweep's objectives that give one number per task: those a ranking reduces over scenarios (a
    vector objective, such as residuals, is not summed). Told by the stored columns' types, so that a
    user's ``module:function`` is not imported again to ask; before any row, by what the spec says."""
    vectors = store.vector_columns(output, sweep)
    declared = normalise(spec.objectives or [])
    if vectors is None:
        vectors = {name for name, o in declared.items() if isinstance(o, Fit) and o.metric == "residuals"}
    return [name for name in declared if name not in vectors]


def complete_totals(
    ok: aggregate.Rows, parameters: list[str], objectives: list[str], over: str, scenarios: int
) -> pd.DataFrame:
    """Each point with an ok row on all ``scenarios``: its ``objectives`` reduced over them
    (``over``: the ranking's ``over_scenarios``). Only these are ranked: a point's total over
    fewer scenarios is not its total."""
    return _complete(aggregate.per_point(ok, parameters, objectives, over), scenarios)


STOPPED = "stopped"  # the totals' column counting a point's runs an FMU ended early (only when there are any)


def with_stopped(complete: pd.DataFrame, scored: aggregate.Rows, parameters: list[str]) -> pd.DataFrame:
    """``complete`` with a STOPPED column (how many of each point's runs an FMU ended early), where any run
    did; else as it is, so that a sweep without early stops ranks and writes what it always did."""
    scored = aggregate.arrow(scored)
    stopped = pc.equal(scored["status"], "stopped")
    if not pc.any(stopped).as_py():
        return complete
    flags = scored.append_column(STOPPED, pc.cast(stopped, pa.int64()))
    counts = aggregate.per_point(flags, parameters, [STOPPED], "sum").drop(columns=aggregate.COUNT)
    return complete.merge(counts, on=parameters, how="left")


def _stopped_last(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` (best first) with the points that have a run an FMU ended early after the others, each
    part in its order: their objectives are over a shorter span, not comparable with a whole run's."""
    if STOPPED not in frame:
        return frame
    return frame.sort_values(STOPPED, key=lambda n: n > 0, kind="stable").reset_index(drop=True)


def _complete(points: pd.DataFrame, scenarios: int) -> pd.DataFrame:
    """per_point's points that have a row on all ``scenarios``, without the count."""
    return points[points[aggregate.COUNT] == scenarios].drop(columns=aggregate.COUNT).reset_index(drop=True)


def without_excluded(
    table: pd.DataFrame,
    ok: pd.DataFrame,
    parameters: list[str],
    objectives: list[str],
    settings: RankingSpec,
    scenarios: int,
    samples: int | None = None,
) -> pd.DataFrame:
    """A running sweep's standings (``table``: :func:`standings` or :func:`draw_standings`) without
    the points :func:`rank` leaves out for breaking a ranking constraint, so that the dashboard
    never names as best a point the rank command excludes. ``ok``: the ok rows with ``objectives``
    (with uncertain draws, ``with_draws``' rows and the ``samples`` drawn). A point is judged once
    it has finished every scenario (every draw on every scenario), as rank() judges it; until then
    it stays, ranked by what it has."""
    if not settings.constraints or table.empty:
        return table
    if samples is None:
        totals = complete_totals(ok, parameters, objectives, settings.over_scenarios, scenarios)
    else:
        draws = uncertainty.per_draw(ok, parameters, objectives, settings.over_scenarios, scenarios)
        totals = uncertainty.summarise(draws, parameters, objectives, [], samples)
    excluded = totals[~admits(totals, settings.constraints, objectives)]
    return table[~_of_points(table, excluded, parameters)].reset_index(drop=True)


def admits(totals: pd.DataFrame, constraints: list[str], objectives: list[str]) -> np.ndarray:
    """Which points' objective totals meet every ranking constraint."""
    if not constraints:
        return np.ones(len(totals), dtype=bool)
    checks = [compile_constraint(text, set(objectives), "objective") for text in constraints]
    records = totals[objectives].to_dict("records")
    return np.array([all(check(r) for check in checks) for r in records], dtype=bool)


def figure_label(objective: str, reduced: str, over_draws: str | None) -> str:
    """The ranked figure in words, one label for the rank command, the report and the dashboard: ``total y``,
    or with uncertain draws ``q90 of total y`` (``over_draws`` the figure over them: mean, q90, mean+1sd)."""
    return f"{reduced} {objective}" if over_draws is None else f"{over_draws} of {reduced} {objective}"


def ranked_figure_label(settings: RankingSpec, uncertain: bool) -> str:
    """What a sweep with these ranking settings ranks its points by, in words (see figure_label)."""
    robust = settings.robust if uncertain else None
    over_draws = robust.label(settings.goal) if robust is not None else "mean" if uncertain else None
    return figure_label(settings.objective, REDUCED[settings.over_scenarios], over_draws)


def standings(
    ok: aggregate.Rows, parameters: list[str], objective: str, goal: str, over: str = "sum"
) -> pd.DataFrame:
    """The best-so-far ranking of a running sweep: the points that have finished the most scenarios
    first (tasks run scenario by scenario, so these have finished the same ones and compare like with
    like), each group by ``objective`` reduced over its scenarios as the ranking's ``over_scenarios`` says
    (column ``ranked``; ``mean`` beside it). Once every point has finished every scenario the order is that
    of :func:`rank`."""
    if len(ok) == 0:
        return pd.DataFrame(columns=[*parameters, "scenarios", "mean", "ranked"])
    found = aggregate.statistics(ok, parameters, objective, list(dict.fromkeys([over, "mean", "count"])))
    table = found[parameters].assign(scenarios=found["count"], mean=found["mean"], ranked=found[over])
    return table.sort_values(
        ["scenarios", "ranked"], ascending=[False, goal == "min"], kind="stable"
    ).reset_index(drop=True)


def draw_standings(
    ok: pd.DataFrame, parameters: list[str], objective: str, settings: RankingSpec, scenarios: int
) -> pd.DataFrame:
    """The best-so-far ranking of a running sweep with uncertain draws (``ok`` with_draws' rows): per point
    the draws finished on all ``scenarios``, ``mean`` the mean over them of ``objective`` reduced over
    the scenarios, and ``ranked`` the figure rank() ranks by (the robust one if the ranking is robust,
    else that mean). Points with the most finished draws first, each group by ``ranked``; points with
    none yet last, ranked blank: a draw's figure needs every scenario, and ranking the mean alone would
    name another best than rank()."""
    if ok.empty:
        return pd.DataFrame(columns=[*parameters, "draws", "mean", "ranked"])
    draws = uncertainty.per_draw(ok, parameters, [objective], settings.over_scenarios, scenarios)
    started = ok.groupby(parameters, dropna=False).size().index
    grouped = draws.groupby(parameters, dropna=False)[objective]
    mean = grouped.mean()
    ranked = (
        mean
        if settings.robust is None
        else uncertainty.robust_values(draws, parameters, objective, settings.robust, settings.goal)
    )
    table = pd.DataFrame({"draws": grouped.size(), "mean": mean, "ranked": ranked}).reindex(started)
    table["draws"] = table["draws"].fillna(0).astype(int)
    return (
        table.reset_index()
        .sort_values(
            ["draws", "ranked"], ascending=[False, settings.goal == "min"], na_position="last", kind="stable"
        )
        .reset_index(drop=True)
    )


def plain(value: Any) -> Any:
    return value.item() if hasattr(value, "item") else value


def format_point(point: Point, digits: int = 6) -> str:
    """``vehicle.mass = 3000, vehicle.mu = 0.3``: a point as people read it, numbers to ``digits``
    significant digits."""
    return ", ".join(
        f"{k} = {v:.{digits}g}" if isinstance(v, float) else f"{k} = {v}"
        for k, v in ((k, plain(v)) for k, v in point.items())
    )


def _of_points(rows: pd.DataFrame, points: pd.DataFrame, parameters: list[str]) -> np.ndarray:
    """Which ``rows`` belong to one of ``points``: Table 1 is over the ranked points only, so that its
    min is never below the best point's value and its average is over the points it names."""
    return pd.MultiIndex.from_frame(rows[parameters]).isin(pd.MultiIndex.from_frame(points[parameters]))


TABLE1_HEADINGS = {
    "min_error": "min",
    "max_error": "max",
    "average_error": "average",
    "computed": "best",
    "difference": "difference",
}  # Table 1's columns as the CLI and the report head them


def table1_scope(ranking: Ranking) -> str:
    """Which points Table 1's min, max and average are over, in words: all of them (``125 points``), or
    the ranked ones and what left the others out (objective constraints, results missing on a scenario)."""
    ranked = len(ranking.totals)
    if not ranking.excluded_points and not ranking.incomplete_points:
        return f"{ranked} points"
    parts = []
    if ranking.excluded_points:
        constraints = " and ".join(ranking.constraints) or "the constraints"
        parts.append(f"{ranked} of {ranked + ranking.excluded_points} points meet {constraints}")
    if ranking.incomplete_points:
        parts.append(f"{ranking.incomplete_points} points without an ok result on every scenario left out")
    return "; ".join(parts) + f"; min/max/average over the {ranked}"


def _table1(ok: aggregate.Rows, objective: str, best: dict[str, Any]) -> pd.DataFrame:
    stats = aggregate.statistics(ok, ["scenario", "group"], objective, ["min", "max", "mean"])
    stats = stats.rename(columns={"min": "min_error", "max": "max_error", "mean": "average_error"})
    computed = aggregate.at_point(ok, best).select(["scenario", "group", objective]).to_pandas()
    table = stats.merge(
        computed.rename(columns={objective: "computed"}), on=["scenario", "group"], how="left"
    )
    table["difference"] = table["computed"] - table["average_error"]
    return table


def _groups(
    ok: aggregate.Rows, parameters: list[str], objective: str, goal: str, rows: aggregate.Rows
) -> pd.DataFrame:
    """The best point within each scenario group, by the group's total."""
    scenarios = aggregate.statistics(rows, ["group"], "scenario", ["count_distinct"])
    per_point = aggregate.per_point(ok, ["group", *parameters], [objective], "sum")
    result = []
    for group, n in zip(scenarios["group"], scenarios["count_distinct"]):
        members = per_point[(per_point["group"] == group) & (per_point[aggregate.COUNT] == n)]
        if members.empty:
            continue
        top = _best_first(members, objective, goal).iloc[0]
        result.append(
            {
                "group": group,
                "scenarios": int(n),
                **{p: plain(top[p]) for p in parameters},
                f"{objective}_total": float(top[objective]),
            }
        )
    return pd.DataFrame(result)


def write_ranking(ranking: Ranking, output: store.Root, sweep: str) -> dict[str, str]:
    """CSV files and one JSON file in ``<output>/ranking/<sweep>/``, for people and for scripts."""
    paths = {}
    tables = [
        "totals",
        "table1",
        "pareto",
        "groups",
        "weighted",
        *(["draws"] if ranking.draws is not None else []),
    ]
    for name in tables:
        paths[name] = store.write_csv(getattr(ranking, name), output, f"ranking/{sweep}/{name}.csv")
    paths["json"] = store.write_text(
        output, f"ranking/{sweep}/ranking.json", strict_json.dumps(ranking.to_json())
    )
    return paths
