"""Results on disk: a Parquet dataset partitioned by sweep and scenario.

    <output>/results/sweep=<name>/scenario=<scenario>/part-<chunk>.parquet
    <output>/trajectories/sweep=<name>/scenario=<scenario>/rank-<k>.parquet

One row per task: ``task_id``, ``model`` (the hash of the model that produced
it: a changed FMU gives new rows beside the old, and rankings use the current
model's), the parameter values (one column each, named
``instance.variable``), ``group``, every objective, ``status`` (ok/failed),
``error``, ``wall_time`` and ``worker``; ``sweep`` and ``scenario`` come from
the folder names. Each chunk's file is written under a temporary name and
renamed into place, so a crash never leaves half a file, and readers drop
any repeated ``task_id``, so a result is never counted twice.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.dataset as ds
import pyarrow.parquet as pq

from .errors import DseError
from .objectives import is_vector

RESULTS = "results"
TRAJECTORIES = "trajectories"
PARTITIONING = ds.partitioning(pa.schema([("sweep", pa.string()), ("scenario", pa.string())]), flavor="hive")


def partition_dir(root: Path, kind: str, sweep: str, scenario: str) -> Path:
    return Path(root) / kind / f"sweep={sweep}" / f"scenario={scenario}"


def write_atomically(table: pa.Table, path: Path) -> Path:
    """Write ``table`` to ``path`` so that readers see all of it or nothing."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.name}.{uuid.uuid4().hex}.partial")
    pq.write_table(table, partial)
    os.replace(partial, path)
    return path


def results_schema(parameters: dict[str, list[Any]], objectives: tuple[str, ...]) -> pa.Schema:
    """Column types fixed up front, so every file of a sweep has the same schema
    (a chunk whose tasks all failed has no objective values to infer types from)."""

    def kind(values: list[Any]) -> pa.DataType:
        if all(isinstance(v, bool) for v in values):
            return pa.bool_()
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            return pa.float64()
        return pa.string()

    return pa.schema(
        [("task_id", pa.string()), ("model", pa.string()), ("group", pa.string())]
        + [(name, kind(values)) for name, values in parameters.items()]
        + [(name, pa.list_(pa.float64()) if is_vector(name) else pa.float64()) for name in objectives]
        + [("status", pa.string()), ("error", pa.string()), ("wall_time", pa.float64()), ("worker", pa.string())]
    )


def write_rows(root: Path, sweep: str, chunk: str, rows: list[dict[str, Any]], schema: pa.Schema) -> list[Path]:
    """Write one chunk's rows, one file per scenario partition."""
    by_scenario: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        by_scenario.setdefault(row["scenario"], []).append({k: v for k, v in row.items() if k != "scenario"})
    return [write_atomically(pa.Table.from_pylist(group, schema=schema), partition_dir(root, RESULTS, sweep, scenario) /
                             f"part-{chunk}.parquet")
            for scenario, group in by_scenario.items()]


def _dataset(root: Path, kind: str, sweep: str | None = None) -> ds.Dataset | None:
    """The files of one sweep (sweeps of one store may have different columns), or of all."""
    folder = Path(root) / kind
    if not folder.is_dir():
        return None
    files = [str(p) for p in (folder / f"sweep={sweep}" if sweep is not None else folder).rglob("*.parquet")]
    if not files:
        return None
    return ds.dataset(files, format="parquet", partitioning=PARTITIONING, partition_base_dir=str(folder))


def _with_every_column(dataset: ds.Dataset) -> ds.Dataset:
    """The dataset with the union of its files' columns: a sweep re-run with more objectives has files
    of both shapes, and the dataset otherwise takes its columns from whichever file comes first."""
    schema = pa.unify_schemas([pq.read_schema(f) for f in dataset.files] + [PARTITIONING.schema])
    return ds.dataset(dataset.files, schema=schema, format="parquet", partitioning=PARTITIONING,
                      partition_base_dir=str(Path(dataset.files[0]).parents[2]))


def read_results(root: Path, sweep: str | None = None, columns: list[str] | None = None) -> pd.DataFrame:
    """Rows of finished tasks, reading only ``columns`` (plus the keys); no trajectories."""
    dataset = _dataset(root, RESULTS, sweep)
    if dataset is None:
        return pd.DataFrame(columns=["task_id", "sweep", "scenario", *(columns or [])])
    wanted = None
    if columns is not None:
        wanted = list(dict.fromkeys(["task_id", "sweep", "scenario", *columns]))
        if any(c not in dataset.schema.names for c in wanted):
            dataset = _with_every_column(dataset)
        missing = [c for c in wanted if c not in dataset.schema.names]
        if missing:
            raise DseError(f"{root}: the results have no column {', '.join(missing)} "
                           f"(columns: {', '.join(dataset.schema.names)})")
    where = (ds.field("sweep") == sweep) if sweep is not None else None
    frame = dataset.to_table(columns=wanted, filter=where).to_pandas()
    return frame.drop_duplicates("task_id", keep="first").reset_index(drop=True)


def read_tasks(root: Path, sweep: str, task_ids: list[str], columns: list[str]) -> pd.DataFrame:
    """The rows of just these tasks: what an optimiser reads back after each round."""
    dataset = _dataset(root, RESULTS, sweep)
    if dataset is None:
        return pd.DataFrame(columns=["task_id", "sweep", "scenario", *columns])
    where = (ds.field("sweep") == sweep) & ds.field("task_id").isin(task_ids)
    wanted = list(dict.fromkeys(["task_id", "sweep", "scenario", *columns]))
    frame = dataset.to_table(columns=wanted, filter=where).to_pandas()
    return frame.drop_duplicates("task_id", keep="first").reset_index(drop=True)


def finished_task_ids(root: Path, sweep: str) -> set[str]:
    """Ids of every task with a row, ok or failed: what a re-run skips."""
    return set(read_results(root, sweep, columns=[])["task_id"])


def sweeps(root: Path) -> list[str]:
    folder = Path(root) / RESULTS
    return sorted(p.name.removeprefix("sweep=") for p in folder.glob("sweep=*")) if folder.is_dir() else []


def write_trajectory(root: Path, sweep: str, scenario: str, rank: int, frame: pd.DataFrame) -> Path:
    path = partition_dir(root, TRAJECTORIES, sweep, scenario) / f"rank-{rank}.parquet"
    return write_atomically(pa.Table.from_pandas(frame, preserve_index=False), path)


def read_trajectory(root: Path, sweep: str, scenario: str, rank: int = 1) -> pd.DataFrame:
    return pd.read_parquet(partition_dir(root, TRAJECTORIES, sweep, scenario) / f"rank-{rank}.parquet")
