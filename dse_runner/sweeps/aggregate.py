"""Reductions of a sweep's rows in Arrow's engine: what rank, sensitivity, the report and the dashboard ask of
a store of any size.

A sensitivity design or a cheap model gives sweeps of a million rows and more. Their readers need per-point
figures (each point's objectives reduced over its scenarios), per-scenario statistics and a few rows picked
out, never the rows themselves as Python objects. The store's scan (store.read_table) reads only the columns
and the model's rows asked for; the grouping here runs in pyarrow's hash aggregation (C++, every core), and
only the reduced tables, a row per point at most, become pandas frames. Why pyarrow and not DuckDB:
docs/dependencies.md.

Every function gives what the pandas group-bys it replaced gave: groups in sorted key order, a point's
scenarios reduced as ``ranking.over_scenarios`` says (tests/sweeps/test_aggregate.py checks them against
plain pandas on the same store).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

COUNT = "rows"  # the column of per_point's tables that counts each group's rows

Rows = pa.Table | pd.DataFrame


def arrow(rows: Rows) -> pa.Table:
    """``rows`` as an Arrow table (a DataFrame is converted without its index; an Arrow-backed column is
    not copied)."""
    return rows if isinstance(rows, pa.Table) else pa.Table.from_pandas(rows, preserve_index=False)


def ok_rows(rows: Rows) -> pa.Table:
    """The rows whose task succeeded."""
    rows = arrow(rows)
    ok = pc.equal(rows["status"], "ok")
    every = ok.null_count == 0 and pc.all(ok).as_py()
    return rows if every else rows.filter(ok)  # all ok, the usual case: no copy


def scored_rows(rows: Rows) -> pa.Table:
    """The rows with objectives: those whose task succeeded, and those whose FMU asked to stop early
    (status ``stopped``, objectives over a shorter span: rank.py ranks their points after the others)."""
    rows = arrow(rows)
    scored = pc.is_in(rows["status"], pa.array(["ok", "stopped"]))
    every = scored.null_count == 0 and pc.all(scored).as_py()
    return rows if every else rows.filter(scored)


def distinct(rows: Rows, column: str) -> int:
    """How many distinct values ``column`` holds."""
    rows = arrow(rows)
    return int(pc.count_distinct(rows[column]).as_py()) if rows.num_rows else 0


def per_point(rows: Rows, keys: Sequence[str], objectives: Sequence[str], over: str) -> pd.DataFrame:
    """One row per distinct ``keys`` (a point, or a point and a group): each objective reduced over the
    group's rows by ``over`` (sum, mean, max or min) and the number of rows (column COUNT), sorted by the
    keys as pandas' groupby sorts them."""
    rows = arrow(rows)
    keys, objectives = list(keys), list(objectives)
    if rows.num_rows == 0:
        return pd.DataFrame({name: pd.Series(dtype=float) for name in [*keys, *objectives, COUNT]})
    grouped = rows.group_by(keys).aggregate([*((name, over) for name in objectives), ([], "count_all")])
    named = {f"{name}_{over}": name for name in objectives} | {"count_all": COUNT}
    grouped = grouped.rename_columns([named.get(c, c) for c in grouped.column_names])
    order = pc.sort_indices(grouped, sort_keys=[(key, "ascending") for key in keys])
    return grouped.take(order).select([*keys, *objectives, COUNT]).to_pandas()


def of_points(rows: Rows, points: pd.DataFrame, keys: Sequence[str]) -> pa.Table:
    """The rows that belong to one of ``points`` (a frame with the ``keys`` columns), in their order."""
    rows = arrow(rows)
    chosen = pa.Table.from_pandas(points[list(keys)].drop_duplicates(), preserve_index=False)
    numbered = rows.append_column("__row", pa.array(np.arange(rows.num_rows)))
    kept = numbered.join(chosen, keys=list(keys), join_type="left semi")
    return rows.take(np.sort(kept["__row"].to_numpy()))


def at_point(rows: Rows, point: dict) -> pa.Table:
    """The rows of one point."""
    rows = arrow(rows)
    mask = None
    for name, value in point.items():
        equal = pc.equal(rows[name], pa.scalar(value, rows.schema.field(name).type))
        mask = equal if mask is None else pc.and_(mask, equal)
    return rows if mask is None else rows.filter(mask)


def statistics(rows: Rows, keys: Sequence[str], column: str, reductions: Sequence[str]) -> pd.DataFrame:
    """``column``'s ``reductions`` (min, max, mean, count_distinct, ...) per distinct ``keys``, sorted by the
    keys; columns named for the reductions."""
    rows = arrow(rows)
    keys = list(keys)
    grouped = rows.group_by(keys).aggregate([(column, how) for how in reductions])
    grouped = grouped.rename_columns(
        [c.removeprefix(f"{column}_") if c not in keys else c for c in grouped.column_names]
    )
    order = pc.sort_indices(grouped, sort_keys=[(key, "ascending") for key in keys])
    return grouped.take(order).select([*keys, *reductions]).to_pandas()


def aligned(
    points: pd.DataFrame, values: pd.DataFrame, keys: Sequence[str], columns: Sequence[str]
) -> pd.DataFrame:
    """``values``' ``columns`` for each row of ``points`` (matched on ``keys``; NaN where a point has
    none), in the order of ``points``: a design's rows looked up in per-point results, as a hash join."""
    keys = list(keys)
    right = pa.Table.from_pandas(values[[*keys, *columns]], preserve_index=False)
    kinds = pa.schema([right.schema.field(key) for key in keys])  # a design's 1 is a stored 1.0
    left = pa.Table.from_pandas(points[keys], preserve_index=False).cast(kinds)
    left = left.append_column("__row", pa.array(np.arange(len(points))))
    joined = left.join(right, keys=keys, join_type="left outer")
    joined = joined.take(pc.sort_indices(joined["__row"]))
    return pd.DataFrame({name: joined[name].to_numpy(zero_copy_only=False).astype(float) for name in columns})
