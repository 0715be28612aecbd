"""Scenarios: the named conditions a simulation runs under.

A scenario is, in general (docs/space.md):

* input signals: ``instance.variable`` fed from a CSV time series (held or
  linearly interpolated) or a constant;
* parameter overrides: ``instance.variable`` -> value;
* optionally a recording: CSV columns the objectives compare signals with;
* optionally its own start time, stop time and step;
* named fields a multi-model's ``scenario:`` section binds to FMU variables
  (how a recording's own format hands over, e.g., a file an FMU reads);
* optionally a data folder, whose files script objectives read (scripts.py).

It is written inline in space.yaml or as ``scenario.yaml`` in a folder
(kind ``signals``, this module). Other formats are *kinds*, plug-ins in the
entry-point group ``dse_runner.scenarios`` that turn a folder into the same
:class:`Scenario`; the field-data format (``dse_runner/cases/fielddata.py``) is one.
:class:`ScenarioKind` is their contract.

Recorded values are never silently wrong (docs/recordings.md): every value is
checked when the scenario loads, and errors name the file, line and column.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from importlib.metadata import EntryPoint
from itertools import pairwise
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, Protocol

import numpy as np
from pydantic import BaseModel, Discriminator, Field, PositiveFloat, Tag, ValidationError

from .. import plugins
from ..errors import DseError, did_you_mean, format_validation_error
from ..schema import Strict
from ..yamlfile import load_yaml, shape
from .trajectory import Series
from .variables import FiniteValue, Value, split_ref

if TYPE_CHECKING:
    from .trajectory import Trajectory

INFO_FILE = "scenario.yaml"
DEFAULT_GROUP = "all"
NOMINAL = "nominal"  # the one scenario of a space that names none


# ---- recorded tables ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Table:
    """Named columns read from a recording, and the lines skipped as dropouts."""

    columns: list[np.ndarray]
    dropped: list[int]
    lines: list[int] = field(default_factory=list)  # each kept row's line number, for later messages


def is_dropout_text(text: str) -> bool:
    """How a missing measurement is written: nothing, or NaN in any case and sign (printf writes -nan)."""
    return text == "" or text.lstrip("+-").lower() == "nan"


def read_header(path: Path) -> list[str]:
    """The column names of a headed CSV."""
    lines = _lines(path)
    return [h.strip() for h in lines[0].split(",")]


def _lines(path: Path) -> list[str]:
    try:
        lines = path.read_text().splitlines()
    except OSError as e:
        raise DseError(f"cannot read {path}: {e.strerror}") from None
    except UnicodeDecodeError:
        raise DseError(f"{path}: not a text file") from None
    if not lines:
        raise DseError(f"{path}: the file is empty")
    return lines


def read_table(
    path: Path,
    names: tuple[str, ...],
    may_drop: tuple[str, ...] = (),
    drop_rows: bool = True,
    ordered: bool = True,
) -> Table:
    """Named numeric columns of a headed CSV whose first named column is time (if ``ordered``).

    Every value must be a finite number; a ``may_drop`` value that is empty or NaN is a dropout:
    with ``drop_rows`` its whole row is skipped, otherwise the value stays NaN. Either way its line
    is counted. Times must increase, unless ``ordered`` is false (a table that is not a time
    series, such as a list of waypoints). Errors name the file, the line and the column."""
    lines = _lines(path)
    header = [h.strip() for h in lines[0].split(",")]
    missing = [n for n in names if n not in header]
    if missing:
        raise DseError(f"{path} line 1: no column {', '.join(missing)} (header: {lines[0]!r})")
    index = [header.index(n) for n in names]
    rows, times, dropped, kept = [], [], [], []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.split(",")
        if len(fields) != len(header):
            raise DseError(f"{path} line {number}: expected {len(header)} fields, got {line!r}")
        texts = {name: fields[i].strip() for name, i in zip(names, index)}
        gaps = {n for n in may_drop if is_dropout_text(texts[n])}
        values = [
            math.nan if name in gaps else _number(path, number, name, text) for name, text in texts.items()
        ]
        times.append((values[0], number))
        if gaps:
            dropped.append(number)
        if not (gaps and drop_rows):
            rows.append(values)
            kept.append(number)
    if ordered:
        _check_increasing(path, names[0], times)
    data = np.array(rows, dtype=float).reshape(-1, len(names))
    return Table([data[:, i].copy() for i in range(len(names))], dropped, kept)


def _number(path: Path, line: int, column: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is None or not np.isfinite(value):
        what = "is empty" if not text else f"{text!r} is not a finite number"
        raise DseError(f"{path} line {line}, column {column}: {what}")
    return value


def _check_increasing(path: Path, column: str, times: list[tuple[float, int]]) -> None:
    """Times (of every row, dropouts included) must increase: interpolation and the step loop rely on it."""
    for (previous, _), (time, line) in pairwise(times):
        if not time > previous:
            raise DseError(
                f"{path} line {line}, column {column}: {time:g} does not increase on the "
                f"previous row's {previous:g}"
            )


# ---- what a scenario holds ---------------------------------------------------------------------


@dataclass(frozen=True)
class Recording:
    """Recorded signals to compare simulated ones with: NaN where a sample is missing."""

    path: Path
    time: np.ndarray
    columns: dict[str, np.ndarray]
    missing: int = 0  # samples (field data: whole rows) skipped as dropouts

    def samples(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """The times and values of column ``name`` where it has a value."""
        if name not in self.columns:
            raise DseError(
                f"{self.path}: no recorded column {name!r}{did_you_mean(name, self.columns)}; it has "
                f"{', '.join(self.columns)}"
            )
        values = self.columns[name]
        present = np.isfinite(values)
        return self.time[present], values[present]


@dataclass(frozen=True)
class Scenario:
    """One scenario in the general form every kind produces; picklable, so it travels to workers."""

    name: str
    group: str = DEFAULT_GROUP
    kind: str = "signals"
    inputs: Mapping[str, Series | Value] = field(default_factory=dict)  # instance.variable -> signal
    parameters: Mapping[str, Value] = field(default_factory=dict)  # instance.variable -> value
    fields: Mapping[str, Value] = field(default_factory=dict)  # what a multi-model's `scenario:` binds
    files: Mapping[str, Path] = field(default_factory=dict)  # fields that are files FMUs read by path
    data: Mapping[str, Path] = field(
        default_factory=dict
    )  # a data folder's files by relative name, for scripts
    recorded: Recording | None = None
    start_time: float | None = None
    stop_time: float | None = None
    step: float | None = None
    natural_step: float | None = None  # the data's own period: the step when nothing else sets one
    sources: tuple[Path, ...] = ()  # every file it was read from: task ids hash them
    options: Mapping[str, Any] = field(default_factory=dict)  # the kind's own settings

    @property
    def dropouts(self) -> int:
        return self.recorded.missing if self.recorded is not None else 0

    def value_of(self, name: str) -> Value:
        """A named field: a file's local path, or a value."""
        if name in self.files:
            return str(self.files[name])
        if name in self.fields:
            return self.fields[name]
        have = sorted({*self.fields, *self.files})
        raise DseError(
            f"scenario {self.name}: no field {name!r}{did_you_mean(name, have)}"
            + (f"; it has {', '.join(have)}" if have else f" (a {self.kind} scenario has no fields)")
        )

    def with_files(self, files: Mapping[str, Path]) -> Scenario:
        """The same scenario reading its files from elsewhere (a worker's copies)."""
        return replace(self, files=dict(files))

    def with_data(self, data: Mapping[str, Path]) -> Scenario:
        """The same scenario with its data files elsewhere (a worker's copies)."""
        return replace(self, data=dict(data))

    def with_group(self, group: str) -> Scenario:
        return replace(self, group=group)


def nominal() -> Scenario:
    """The scenario of a space that names none: the experiment as it is."""
    return Scenario(NOMINAL)


def dropouts(scenarios: list[Scenario]) -> dict[str, int]:
    """Recorded samples skipped as dropouts, per scenario that has any: what the commands report."""
    return {s.name: s.dropouts for s in scenarios if s.dropouts}


def dropouts_line(counts: dict[str, int]) -> str:
    """The dropouts per scenario as one line, as every command prints them."""
    return "recorded values skipped as dropouts (empty or NaN): " + ", ".join(
        f"{name} {n}" for name, n in counts.items()
    )


# ---- the general file format (kind "signals") --------------------------------------------------


class SeriesSpec(BaseModel):
    """An input from a CSV: ``{csv: inflow.csv, column: q, interpolation: hold}``."""

    model_config = Strict
    csv: str  # relative to the file that names it
    column: str | None = None  # default: the variable's name
    time: str = "time"
    interpolation: Literal["hold", "linear"] = "linear"


class RecordedSpec(BaseModel):
    """A recording to compare with: every column of a CSV but its time column."""

    model_config = Strict
    csv: str
    time: str = "time"


# A mapping is a CSV series or recording, anything else a constant or a CSV's path: a wrong mapping gets that
# model's messages only, not one per kind of value.
InputSpec = Annotated[
    Annotated[SeriesSpec, Tag("mapping")] | Annotated[FiniteValue, Tag("scalar")],
    Discriminator(
        shape, custom_error_type="input", custom_error_message="expected a value or {csv, column, ...}"
    ),
]
RecordedEntry = Annotated[
    Annotated[RecordedSpec, Tag("mapping")] | Annotated[str, Tag("scalar")],
    Discriminator(
        shape, custom_error_type="recorded", custom_error_message="expected a CSV's path or {csv, time}"
    ),
]


class ScenarioSpec(BaseModel):
    """A scenario written inline in space.yaml, or as a folder's scenario.yaml."""

    model_config = Strict
    name: str = Field(pattern=r"^[A-Za-z0-9_.-]+$")
    group: str = DEFAULT_GROUP
    inputs: dict[str, InputSpec] = {}
    parameters: dict[str, FiniteValue] = {}
    recorded: RecordedEntry | None = None  # a CSV path, or {csv, time}
    start_time: float | None = None
    stop_time: PositiveFloat | None = None
    step: PositiveFloat | None = None
    data: str | None = (
        None  # a folder of files script objectives read (INTO-CPS: userMetricScripts/<scenario>)
    )


def read_data_folder(folder: Path, where: str) -> dict[str, Path]:
    """Every file under ``folder`` by its path relative to it."""
    if not folder.is_dir():
        raise DseError(f"{where}: data folder not found: {folder}")
    return {p.relative_to(folder).as_posix(): p.resolve() for p in sorted(folder.rglob("*")) if p.is_file()}


def from_spec(spec: ScenarioSpec, base: Path, source: str) -> Scenario:
    """Read the CSVs a scenario spec names; relative paths start at ``base``."""
    inputs: dict[str, Series | Value] = {}
    sources: list[Path] = []
    for ref, given in spec.inputs.items():
        try:
            split_ref(ref)
        except ValueError as e:
            raise DseError(f"{source}: inputs: {e}") from None
        if isinstance(given, SeriesSpec):
            path = _file(base, given.csv, f"{source}: inputs.{ref}")
            column = given.column or split_ref(ref)[1]
            table = read_table(path, (given.time, column))
            if table.columns[0].size == 0:
                raise DseError(f"{path}: no rows")
            inputs[ref] = Series(*table.columns, given.interpolation)
            sources.append(path)
        else:
            inputs[ref] = given
    recorded = None
    if spec.recorded is not None:
        recorded_spec = RecordedSpec(csv=spec.recorded) if isinstance(spec.recorded, str) else spec.recorded
        path = _file(base, recorded_spec.csv, f"{source}: recorded")
        recorded = read_recording(path, recorded_spec.time)
        sources.append(path)
    data = {}
    if spec.data is not None:
        data = read_data_folder(
            Path(spec.data) if Path(spec.data).is_absolute() else base / spec.data, f"{source}: data"
        )
        sources.extend(data.values())
    return Scenario(
        spec.name,
        spec.group,
        "signals",
        inputs,
        dict(spec.parameters),
        recorded=recorded,
        start_time=spec.start_time,
        stop_time=spec.stop_time,
        step=spec.step,
        sources=tuple(sources),
        data=data,
    )


def read_recording(path: Path, time: str = "time") -> Recording:
    """Every column of a CSV as recorded signals; an empty or NaN value is a missing sample."""
    names = [n for n in read_header(path) if n != time]
    if not names:
        raise DseError(f"{path}: a recording needs a column besides {time!r}")
    table = read_table(path, (time, *names), may_drop=tuple(names), drop_rows=False)
    missing = sum(int(np.isnan(c).sum()) for c in table.columns[1:])
    return Recording(path, table.columns[0], dict(zip(names, table.columns[1:])), missing)


def _file(base: Path, name: str, where: str) -> Path:
    path = Path(name) if Path(name).is_absolute() else base / name
    if not path.is_file():
        raise DseError(f"{where}: file not found: {path}")
    return path.resolve()


def parse_scenario(data: Any, source: str, base: Path) -> Scenario:
    """An inline scenario (a mapping in space.yaml)."""
    try:
        spec = ScenarioSpec.model_validate(data)
    except ValidationError as e:
        raise DseError(format_validation_error(source, e)) from None
    return from_spec(spec, base, source)


# ---- kinds: plug-ins that read other formats ----------------------------------------------------


class Simulated(Protocol):
    """What a kind's views read of one simulated result (run.SimulationResult is one)."""

    @property
    def scenario(self) -> Scenario: ...

    @property
    def time(self) -> np.ndarray: ...

    @property
    def trajectory(self) -> Trajectory: ...


@dataclass(frozen=True)
class Comparison:
    """One simulation next to its scenario's recording, as the dashboard and the report draw it
    (comparison.py makes the general one; a kind may make its own)."""

    recorded: tuple[np.ndarray, np.ndarray] | None  # x and y of the recorded points, if any
    simulated: tuple[np.ndarray, np.ndarray]
    x_label: str
    y_label: str
    equal_axes: bool = False  # a track on a map, not a signal over time


class ScenarioKind(ABC):
    """A scenario format: the contract of the plug-ins in the entry-point group ``dse_runner.scenarios``,
    which name an instance of a subclass (SignalsKind below; fielddata.FieldData, paths.PathKind).

    Lifecycle: when a space is read, a folder its ``scenarios`` name is offered to every installed
    kind's :meth:`detect` in turn (``general`` ones last), unless the entry names its ``kind``; the first
    that recognises it reads it with :meth:`load`, the entry's other keys as ``options``, into a
    :class:`Scenario` that travels to the workers (it must pickle), its ``kind`` this kind's ``name``
    (the entry point's).
    ``default_objectives`` are what a space of such scenarios scores when it names none. Afterwards,
    on the client only, the interfaces ask the kind for its views of one simulated result:
    :meth:`draw` (simulate's figure) and :meth:`compare` (the dashboard's and report's). Both are
    optional: the defaults draw and compare nothing, and the general views (signals over time, each
    over its recording) are shown instead.
    """

    name: ClassVar[str]
    default_objectives: ClassVar[tuple[str, ...]] = ()
    general: ClassVar[bool] = False  # recognises folders of any origin: offered a folder after the others

    @abstractmethod
    def detect(self, folder: Path) -> bool:
        """Whether ``folder`` is in this kind's format: cheap, and false rather than an error."""

    @abstractmethod
    def load(self, folder: Path, options: Mapping[str, Any] | None = None) -> Scenario:
        """The folder as a scenario; errors name the file, line and column (docs/recordings.md)."""

    def draw(self, result: Simulated, ax: Any) -> bool:
        """Draw ``result`` on one matplotlib axes; False (the default) draws nothing, and simulate's
        figure shows the recorded signals over time instead."""
        return False

    def compare(self, result: Simulated) -> Comparison | None:
        """The dashboard's and report's view of ``result`` against its scenario; None (the default):
        the ranking objective's signal over time."""
        return None


class SignalsKind(ScenarioKind):
    """The general kind: a folder whose scenario.yaml is a :class:`ScenarioSpec`."""

    name = "signals"
    general = True  # a scenario.yaml may sit in any folder

    def detect(self, folder: Path) -> bool:
        return (folder / INFO_FILE).is_file()

    def load(self, folder: Path, options: Mapping[str, Any] | None = None) -> Scenario:
        if options:
            raise DseError(f"scenario {folder}: a signals scenario takes no options ({', '.join(options)})")
        path = folder / INFO_FILE
        scenario = parse_scenario(load_yaml(path, "scenario file"), str(path), folder)
        return replace(scenario, sources=(path.resolve(), *scenario.sources))


SIGNALS = SignalsKind()  # the group's entry "signals" (pyproject.toml)
GROUP = "dse_runner.scenarios"


def _checked(entry: EntryPoint) -> ScenarioKind:
    """An installed kind, held to its contract: a plug-in that is not a ScenarioKind is named at once,
    not found out by a missing method halfway through a sweep."""
    found = plugins.loaded(entry, f"scenario kind {entry.name!r}")
    if not isinstance(found, ScenarioKind):
        raise DseError(
            f"scenario kind {entry.name!r} ({entry.value}) is not an instance of "
            "dse_runner.simulation.scenario.ScenarioKind"
        )
    return found


def kinds() -> dict[str, ScenarioKind]:
    """Installed kinds (entry-point group ``dse_runner.scenarios``) in the order they are tried on a folder:
    by name, the general ones (the built-in ``signals``, whose scenario.yaml any folder may hold) last."""
    found = sorted(
        ((name, _checked(entry)) for name, entry in plugins.entries(GROUP).items()),
        key=lambda named: (named[1].general, named[0]),
    )
    return dict(found)


def kind(name: str) -> ScenarioKind:
    """One kind by name, loading only its plug-in (a plain study never imports field data's)."""
    entry = plugins.entries(GROUP).get(name)
    if entry is None:
        raise DseError(
            f"unknown scenario kind {name!r}{did_you_mean(name, plugins.names(GROUP))}: installed are "
            f"{', '.join(plugins.names(GROUP))}"
        )
    return _checked(entry)


def load_scenario(
    folder: str | Path, kind_name: str | None = None, options: Mapping[str, Any] | None = None
) -> Scenario:
    """Read a scenario folder with the named kind, or the first kind that recognises it; ``options``
    are the kind's own settings (e.g. field data's ``position``)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DseError(f"scenario folder not found: {folder}")
    if kind_name is not None:
        return kind(kind_name).load(folder, options)
    for candidate in kinds().values():
        if candidate.detect(folder):
            return candidate.load(folder, options)
    raise DseError(
        f"scenario {folder}: no scenario.yaml, and no installed kind "
        f"({', '.join(kinds())}) recognises the folder"
    )
