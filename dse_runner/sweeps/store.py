"""Results in a store: a Parquet dataset partitioned by sweep and scenario.

    <store>/results/sweep=<name>/scenario=<scenario>/part-<chunk>.parquet
    <store>/trajectories/sweep=<name>/scenario=<scenario>/rank-<k>.parquet
    <store>/<name>.sweep.json, <name>.model      (written by rank.save_sweep_spec)
    <store>/<name>.sample.csv                    (with uncertain parameters: each draw's values)

A store is a local folder or any fsspec URL the workers can reach
(``s3://bucket/prefix``, ``gs://…``, ``abfs://…``; credentials come the way
that file system's library takes them, e.g. AWS_* variables for S3). Workers
write their chunks' files themselves, so the client never holds a sweep's rows.

One row per task: ``task_id``, ``model`` (the hash of the model that produced
it: a changed FMU gives new rows beside the old, and rankings use the current
model's), the parameter values (one column each, named
``instance.variable``), ``group``, every objective, ``status`` (ok, failed, or stopped: an FMU asked
to stop early), ``span_end`` (the time the objectives are computed up to: the experiment's stop time, or
where a stopped run ended; empty for a failed row), ``error`` (a failure's message, or which FMU asked to
stop and when), ``wall_time``, ``worker`` and ``lifecycle`` (``reset``: the worker's instances were
reused; ``process``: a fresh process ran it, lifecycle.py); ``sweep`` and ``scenario`` come from
the folder names. A chunk's file appears whole or not at all (a local file is
written under a temporary name and renamed; an object store's PUT is atomic),
and its name is the chunk's id, so a chunk run twice replaces its own file and
readers drop any repeated ``task_id``: a result is never counted twice.
"""

from __future__ import annotations

import hashlib
import os
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import fsspec
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pa_csv
import pyarrow.dataset as ds
import pyarrow.parquet as pq
from fsspec.implementations.local import LocalFileSystem

from ..errors import DseError
from ..simulation.objectives import ObjectiveSpec, is_vector

RESULTS = "results"
TRAJECTORIES = "trajectories"
PARTITIONING = ds.partitioning(pa.schema([("sweep", pa.string()), ("scenario", pa.string())]), flavor="hive")

Root = str | Path  # a local folder or an fsspec URL


def is_url(text: str) -> bool:
    """``s3://bucket/x`` is a URL; ``/data/out`` and ``C:/out`` are not."""
    protocol, sep, _ = text.partition("://")
    return bool(sep) and len(protocol) > 1


def _fs(root: Root) -> tuple[fsspec.AbstractFileSystem, str]:
    """The file system of ``root`` and its path within it."""
    if not is_url(str(root)):
        return LocalFileSystem(), str(Path(root).resolve())
    try:
        fs, path = fsspec.core.url_to_fs(str(root))
    except (ImportError, ValueError) as e:
        raise DseError(f"store {root}: {e}") from None
    return fs, path.rstrip("/")


def _arrow_fs(fs: fsspec.AbstractFileSystem) -> Any:
    """None (pyarrow's own, faster local file system) for local folders, else the fsspec one."""
    return None if isinstance(fs, LocalFileSystem) else fs


def _join(*parts: str) -> str:
    return "/".join(p.strip("/") if i else p.rstrip("/") for i, p in enumerate(parts))


def _where(fs: fsspec.AbstractFileSystem, path: str) -> str:
    """A path to show users: local as is, remote as a full URL."""
    return path if isinstance(fs, LocalFileSystem) else fs.unstrip_protocol(path)


def _partition(kind: str, sweep: str, scenario: str) -> str:
    return f"{kind}/sweep={sweep}/scenario={scenario}"


def check_reachable(root: Root) -> None:
    """Fail early, naming the store, if it cannot be created or written."""
    fs, path = _fs(root)
    try:
        fs.makedirs(path, exist_ok=True)
        probe = _join(path, f".probe-{uuid.uuid4().hex}")
        fs.pipe_file(probe, b"")
        fs.rm_file(probe)
    except Exception as e:  # noqa: BLE001  (each file system raises its own errors)
        raise DseError(f"cannot write to the store {root}: {type(e).__name__}: {e}") from None


def _write_whole(
    root: Root, name: str, local: Callable[[Path], object], remote: Callable[[Any, str], object]
) -> str:
    """Write ``name`` under ``root`` so that readers see all of it or the old one; returns where it went.
    On a local disk ``local(partial)`` writes a file beside the target, renamed into place; on an object
    store, which replaces an object whole, ``remote(fs, target)`` writes it there."""
    fs, path = _fs(root)
    target = _join(path, name)
    if isinstance(fs, LocalFileSystem):
        _replace_whole(target, local)
    else:
        remote(fs, target)
    return _where(fs, target)


def _into_folder(fs: Any, target: str) -> str:
    """``target``, its folder made on a remote store (s3fs asks whether the bucket exists: a request, so not
    for every results file)."""
    fs.makedirs(target.rsplit("/", 1)[0], exist_ok=True)
    return target


def _replace_whole(target: str, write: Callable[[Path], object]) -> None:
    """Write a local file beside ``target`` and rename it into place: readers never see half of it, and
    a write cut short (a full disk, or Ctrl-C, which raises wherever the client is) leaves nothing behind."""
    Path(target).parent.mkdir(parents=True, exist_ok=True)
    partial = Path(target).with_name(f".{Path(target).name}.{uuid.uuid4().hex}.partial")
    try:
        write(partial)
        os.replace(partial, target)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise


def write_text(root: Root, name: str, text: str) -> str:
    """Write a small file (``name`` may hold folders) whole (a dashboard reads status and history files
    while a sweep rewrites them); returns where it went."""
    data = text.encode()
    return _write_whole(
        root,
        name,
        lambda partial: partial.write_bytes(data),
        lambda fs, to: fs.pipe_file(_into_folder(fs, to), data),
    )


def read_text(root: Root, name: str) -> str | None:
    """The file's text, or None if it does not exist."""
    fs, path = _fs(root)
    try:
        return fs.cat_file(_join(path, name)).decode()
    except FileNotFoundError:
        return None


def write_csv(frame: pd.DataFrame, root: Root, name: str) -> str:
    """``frame`` as CSV (no index), written whole like write_text. Arrow's writer: a million-row ranking in a
    second, where pandas' takes ten. On a local disk it streams to the file, not held: a million rows are
    70 MB of text."""
    table = pa.Table.from_pandas(frame, preserve_index=False)

    def remote(fs: Any, target: str) -> None:
        with fs.open(_into_folder(fs, target), "wb") as sink:
            pa_csv.write_csv(table, sink)

    return _write_whole(root, name, lambda partial: pa_csv.write_csv(table, str(partial)), remote)


def write_table(table: pa.Table, root: Root, relative: str) -> str:
    """Write ``table`` so that readers see all of it or nothing."""
    return _write_whole(
        root,
        relative,
        lambda partial: pq.write_table(table, partial),
        lambda fs, target: pq.write_table(table, target, filesystem=fs),
    )


def results_schema(parameters: dict[str, list[Any]], objectives: dict[str, ObjectiveSpec]) -> pa.Schema:
    """Column types fixed up front, so every file of a sweep has the same schema
    (a chunk whose tasks all failed has no objective values to infer types from)."""

    def kind(values: list[Any]) -> pa.DataType:
        types = set(map(type, values))  # at C speed: a grid may hold 100,000s of values
        if all(issubclass(t, bool) for t in types):
            return pa.bool_()
        if all(issubclass(t, (int, float)) and not issubclass(t, bool) for t in types):
            return pa.float64()
        return pa.string()

    return pa.schema(
        [("task_id", pa.string()), ("model", pa.string()), ("group", pa.string())]
        + [(name, kind(values)) for name, values in parameters.items()]
        + [
            (name, pa.list_(pa.float64()) if is_vector(spec) else pa.float64())
            for name, spec in objectives.items()
        ]
        + [
            ("status", pa.string()),
            ("span_end", pa.float64()),
            ("error", pa.string()),
            ("wall_time", pa.float64()),
            ("worker", pa.string()),
            ("lifecycle", pa.string()),
        ]
    )


def write_rows(
    root: Root, sweep: str, chunk: str, rows: list[dict[str, Any]], schema: pa.Schema
) -> list[str]:
    """Write one chunk's rows given as dicts (each with its "scenario"), one file per scenario partition."""
    return write_results(
        root, sweep, chunk, pa.Table.from_pylist(rows, schema=schema), [r["scenario"] for r in rows]
    )


def write_results(root: Root, sweep: str, chunk: str, table: pa.Table, scenarios: list[str]) -> list[str]:
    """Write one chunk's rows, ``scenarios`` naming each row's, one file per scenario partition ("scenario"
    is the partition, not a column)."""
    names = list(dict.fromkeys(scenarios))
    if len(names) == 1:
        parts = {names[0]: table}
    else:
        each = np.array(scenarios)
        parts = {name: table.filter(pa.array(each == name)) for name in names}
    return [
        write_table(part, root, f"{_partition(RESULTS, sweep, name)}/part-{chunk}.parquet")
        for name, part in parts.items()
    ]


def remove_chunk(root: Root, sweep: str, chunk: str) -> int:
    """Delete the rows one chunk wrote (every scenario partition); how many files went. For a chunk Dask gave
    up on after it had written them on a worker that died before its result was fetched: it is run again
    in halves, whose rows would otherwise stand beside these."""
    fs, path = _fs(root)
    files = fs.glob(_join(path, f"{RESULTS}/sweep={sweep}/scenario=*/part-{chunk}.parquet"))
    for file in files:
        fs.rm(file)
    return len(files)


def _files(fs: fsspec.AbstractFileSystem, path: str, kind: str, sweep: str | None = None) -> list[str]:
    """The finished files of one sweep (sweeps of one store may have different columns), or of all."""
    folder = _join(path, kind)
    where = _join(folder, f"sweep={sweep}") if sweep is not None else folder
    if isinstance(
        fs, LocalFileSystem
    ):  # fsspec's find stats every file, and an optimiser lists the store each round
        found = [os.path.join(parent, name) for parent, _, names in os.walk(where) for name in names]
    else:
        found = fs.find(where)
    return sorted(f for f in found if f.endswith(".parquet") and not os.path.basename(f).startswith("."))


def version(root: Root, sweep: str) -> str:
    """A fingerprint of the sweep's result files (names, sizes, modification times): equal while no chunk
    has written, so that readers compute an aggregate once per version of the store, not once per look."""
    fs, path = _fs(root)
    where = _join(path, RESULTS, f"sweep={sweep}")
    if isinstance(fs, LocalFileSystem):
        listing = [
            (name, stat.st_size, stat.st_mtime_ns)
            for name, stat in ((name, os.stat(name)) for name in _files(fs, path, RESULTS, sweep))
        ]
    else:
        found = fs.find(where, detail=True) if fs.exists(where) else {}
        listing = [
            (name, info.get("size"), str(info.get("mtime", info.get("LastModified", ""))))
            for name, info in found.items()
            if name.endswith(".parquet")
        ]
    return hashlib.sha256(repr(sorted(listing)).encode()).hexdigest()[:24]


def _dataset(
    root: Root, kind: str, sweep: str | None = None, files: list[str] | None = None
) -> ds.Dataset | None:
    """A dataset of ``files`` (default: every file of the sweep, or of all sweeps)."""
    fs, path = _fs(root)
    files = _files(fs, path, kind, sweep) if files is None else files
    if not files:
        return None
    return ds.dataset(
        files,
        format="parquet",
        partitioning=PARTITIONING,
        partition_base_dir=_join(path, kind),
        filesystem=_arrow_fs(fs),
    )


def _id_bytes(column: pa.ChunkedArray | pa.Array) -> np.ndarray:
    """Task ids as fixed-width bytes: about 24 bytes an id, where a Python string costs 70 and more."""
    return np.array(column.to_pylist(), dtype="S")


class _TaskIdCache:
    """Task ids per local file, keyed by (size, mtime): a chunk's file does not change once written
    (a chunk run again replaces it whole, with a new modification time). Bounded, so a process
    that scans a huge sweep re-reads it rather than holding every id."""

    limit = 2_000_000  # ids, ~50 MB

    def __init__(self) -> None:
        self.files: dict[str, tuple[tuple[int, int], np.ndarray]] = {}
        self.count = 0

    def ids(self, name: str) -> np.ndarray:
        stat = os.stat(name)
        version = (stat.st_size, stat.st_mtime_ns)
        cached = self.files.get(name)
        if cached is not None and cached[0] == version:
            return cached[1]
        # ParquetFile: a third of read_table's cost per small file (no dataset machinery)
        with pq.ParquetFile(name) as file:
            ids = _id_bytes(file.read(columns=["task_id"]).column("task_id"))
        if cached is not None:
            self.count -= len(self.files.pop(name)[1])
        if self.count + len(ids) > self.limit:
            self.files.clear()
            self.count = 0
        self.files[name] = (version, ids)
        self.count += len(ids)
        return ids


_IDS = _TaskIdCache()


def _task_ids_by_file(fs: fsspec.AbstractFileSystem, files: list[str]) -> dict[str, np.ndarray] | None:
    """The task ids in each of ``files`` (fixed-width bytes), or None for a remote store.

    An optimiser reads the store after every one of its many small rounds (fit.py); with the
    ids of each local file remembered, a round opens only the files written since the last."""
    if not isinstance(fs, LocalFileSystem):
        return None
    return {name: _IDS.ids(name) for name in files}


def vector_columns(root: Root, sweep: str) -> set[str] | None:
    """The sweep's result columns that hold a list per row (vector objectives), from its files' schemas; None
    before any file. What readers (rank, report, the dashboard) need to know of an objective without
    importing a user's function again: it ran on the workers, and its values are stored."""
    fs, path = _fs(root)
    files = _files(fs, path, RESULTS, sweep)
    if not files:
        return None
    schema = pq.read_schema(files[-1], filesystem=_arrow_fs(fs))  # one schema per sweep (store.schema)
    return {f.name for f in schema if pa.types.is_list(f.type)}


def _with_every_column(dataset: ds.Dataset, root: Root, kind: str) -> ds.Dataset:
    """The dataset with the union of its files' columns: a sweep re-run with more objectives has files
    of both shapes, and the dataset otherwise takes its columns from whichever file comes first."""
    fs, path = _fs(root)
    schemas = [pq.read_schema(f, filesystem=_arrow_fs(fs)) for f in dataset.files]
    schema = pa.unify_schemas(schemas + [PARTITIONING.schema])
    return ds.dataset(
        dataset.files,
        schema=schema,
        format="parquet",
        partitioning=PARTITIONING,
        partition_base_dir=_join(path, kind),
        filesystem=_arrow_fs(fs),
    )


def read_table(
    root: Root,
    sweep: str | None = None,
    columns: list[str] | None = None,
    task_ids: list[str] | None = None,
    model: str | None = None,
) -> pa.Table:
    """Rows of finished tasks as an Arrow table, each task once: only ``columns`` (plus the keys) are read,
    and only the rows of ``model`` (a filter the scan applies file by file, so rows of other models are
    never held) and of ``task_ids`` if given (what an optimiser reads back after each round, from only the
    files that hold them); no trajectories. What the readers of a large sweep aggregate (aggregate.py)."""
    files = None
    if task_ids is not None:
        fs, path = _fs(root)
        files = _files(fs, path, RESULTS, sweep)
        by_file = _task_ids_by_file(fs, files)
        if by_file is not None:
            wanted_ids = TaskIds.of(task_ids)
            files = [f for f in files if wanted_ids.among(by_file[f]).any()]
    keys = ["task_id", "sweep", "scenario"]
    dataset = _dataset(root, RESULTS, sweep, files)
    if dataset is None:
        return pa.table(
            {name: pa.array([], pa.string()) for name in dict.fromkeys([*keys, *(columns or [])])}
        )
    wanted = None
    if columns is not None:
        wanted = list(dict.fromkeys([*keys, *columns]))
        if any(c not in dataset.schema.names for c in wanted):
            dataset = _with_every_column(dataset, root, RESULTS)
        missing = [c for c in wanted if c not in dataset.schema.names]
        if missing:
            raise DseError(
                f"{root}: the results have no column {', '.join(missing)} "
                f"(columns: {', '.join(dataset.schema.names)})"
            )
    where = (ds.field("sweep") == sweep) if sweep is not None else None
    for chosen in ([ds.field("task_id").isin(task_ids)] if task_ids is not None else []) + (
        [ds.field("model") == model] if model is not None else []
    ):
        where = chosen if where is None else where & chosen
    return each_task_once(dataset.to_table(columns=wanted, filter=where))


def each_task_once(table: pa.Table) -> pa.Table:
    """``table`` with only the first row of each ``task_id``: the same task in two files (a chunk that ran
    twice in different company) counts once. Checked in one pass; rows are dropped only if there are any."""
    if table.num_rows == 0 or pc.count_distinct(table["task_id"]).as_py() == table.num_rows:
        return table
    numbered = table.append_column("__row", pa.array(np.arange(table.num_rows)))
    first = numbered.group_by("task_id", use_threads=False).aggregate([("__row", "min")])["__row_min"]
    return table.take(np.sort(first.to_numpy()))


def read_results(
    root: Root,
    sweep: str | None = None,
    columns: list[str] | None = None,
    task_ids: list[str] | None = None,
    model: str | None = None,
) -> pd.DataFrame:
    """read_table's rows as a DataFrame, indexed 0..n-1."""
    return read_table(root, sweep, columns, task_ids, model).to_pandas()


class TaskIds:
    """Ids of the tasks with a row: one sorted array of fixed-width bytes, about 24 bytes a task where a
    set of strings costs 200, so that resuming a sweep of millions holds tens of megabytes. Asked a
    batch at a time (``among``), as expand.py walks the space."""

    def __init__(self, ids: np.ndarray | None = None):
        self.ids = np.unique(ids) if ids is not None and len(ids) else np.array([], dtype="S24")

    @classmethod
    def of(cls, ids: list[str] | set[str]) -> TaskIds:
        return cls(np.array([i.encode() for i in ids], dtype="S"))

    def __len__(self) -> int:
        return len(self.ids)

    def __iter__(self):
        return (i.decode() for i in self.ids.tolist())

    def __contains__(self, task_id: str) -> bool:
        return bool(self.among(np.array([task_id.encode()]))[0])

    def among(self, ids: np.ndarray) -> np.ndarray:
        """Which of ``ids`` (fixed-width bytes) have a row."""
        if not len(self.ids):
            return np.zeros(len(ids), dtype=bool)
        at = np.minimum(np.searchsorted(self.ids, ids), len(self.ids) - 1)
        return self.ids[at] == ids


def finished_task_ids(root: Root, sweep: str) -> TaskIds:
    """Ids of every task with a row, ok or failed: what a re-run skips. A local file's ids are remembered
    (_TaskIdCache), a remote store's read a column at a time."""
    fs, path = _fs(root)
    by_file = _task_ids_by_file(fs, _files(fs, path, RESULTS, sweep))
    if by_file is not None:
        parts = list(by_file.values())
    else:
        dataset = _dataset(root, RESULTS, sweep)
        batches = dataset.to_batches(columns=["task_id"]) if dataset is not None else []
        parts = [_id_bytes(batch.column(0)) for batch in batches if batch.num_rows]
    return TaskIds(np.concatenate(parts) if parts else None)


def sweeps(root: Root) -> list[str]:
    fs, path = _fs(root)
    folder = _join(path, RESULTS)
    if not fs.isdir(folder):
        return []
    return sorted(Path(p).name.removeprefix("sweep=") for p in fs.glob(_join(folder, "sweep=*")))


def _trajectory_file(sweep: str, scenario: str, rank: int) -> str:
    return f"{_partition(TRAJECTORIES, sweep, scenario)}/rank-{rank}.parquet"


def write_trajectory(root: Root, sweep: str, scenario: str, rank: int, frame: pd.DataFrame) -> str:
    return write_table(
        pa.Table.from_pandas(frame, preserve_index=False), root, _trajectory_file(sweep, scenario, rank)
    )


def has_trajectory(root: Root, sweep: str, scenario: str, rank: int) -> bool:
    fs, path = _fs(root)
    return fs.isfile(_join(path, _trajectory_file(sweep, scenario, rank)))


def read_trajectory(root: Root, sweep: str, scenario: str, rank: int = 1) -> pd.DataFrame:
    fs, path = _fs(root)
    return pd.read_parquet(_join(path, _trajectory_file(sweep, scenario, rank)), filesystem=_arrow_fs(fs))
