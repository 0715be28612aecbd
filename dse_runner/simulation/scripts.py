"""Script objectives: a user's Python script scores a simulation in a subprocess.

The calling convention is INTO-CPS's (its DSE ``externalScripts``), so scripts
written for INTO-CPS run unchanged, Python 2 ones ported on the fly::

    python SCRIPT FOLDER NAME DATA ARG...      (DATA left out for a script written without it)

* ``FOLDER`` holds ``results.csv`` (columns ``time``, ``step-size``, then every
  recorded signal, also under the names ``columns`` gives it) and
  ``objectives.json`` (the other objectives' values so far);
* ``NAME`` is the objective's name: the script writes its value under that key
  in ``objectives.json``;
* ``DATA`` is the scenario's data folder (its files, in a folder of their own on
  the worker), or an empty folder;
* the ``args`` follow, as text.

Whether a script takes ``DATA`` is read from the script (script_convention.py)
unless ``data_folder`` says. A script runs on the worker with the worker's own
Python, in a subprocess, so it cannot take the worker down. A Python 2 script
is ported when the spec loads (python2.py); one that Python 3 cannot compile,
even ported, is an error then, before any task. A
script that exits non-zero, runs past its timeout, or writes no number under
its name fails the task; the failed row holds its message, the script's
exception line (the last line of its stderr) first, then the end of its
stderr. The script's text travels with the objective (read when the spec
loads), so workers need no shared files.
"""

from __future__ import annotations

import csv
import hashlib
import json
import re
import subprocess
import sys
import tempfile
import warnings
from collections.abc import Mapping
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, PositiveFloat, PrivateAttr

from ..errors import DseError
from ..schema import Strict
from . import python2, scratch
from .script_convention import convention

FAULT_TAIL = 600  # characters of a failing script's stderr kept in its task's error
FRAME = re.compile(r'^\s*File "(.+)", line (\d+)', re.MULTILINE)  # a traceback's frame


class Script(BaseModel):
    """``{script: metrics/settle.py, args: [...], columns: {header:
    signal}}`` (paths relative to the spec)."""

    model_config = Strict
    script: str
    args: list[str] = []
    columns: dict[str, str] = {}  # results.csv header -> recorded signal (INTO-CPS: {fmu}.instance.variable)
    timeout: PositiveFloat = 60.0  # seconds one run of the script may take
    # pass the scenario's data folder as the third argument; None: as the script reads (script_convention.py)
    data_folder: bool | None = None
    digest: str | None = None  # the script's sha256, filled when loaded: a changed script is a changed model
    _code: str | None = PrivateAttr(None)  # its text, which travels to the workers

    def loaded(self, base: Path, where: str) -> Script:
        """This objective with its script read: path made absolute, digest and text filled in."""
        path = (Path(self.script) if Path(self.script).is_absolute() else base / self.script).resolve()
        try:
            code = path.read_text()
        except OSError as e:
            raise DseError(f"{where}: cannot read script {path}: {e.strerror}") from None
        try:
            runs, ported = python2.as_python3(code, path)  # before any task runs it
        except DseError as e:
            raise DseError(f"{where}: {e}") from None
        if ported is not None:
            _say(path, code, f"{path} {ported}")
        data_folder = self.data_folder
        if data_folder is None:
            chosen = convention(runs, len(self.args), str(path))
            if chosen.note is not None:
                _say(path, code, chosen.note)
            data_folder = chosen.data_folder
        loaded = self.model_copy(
            update={
                "script": str(path),
                "data_folder": data_folder,
                "digest": hashlib.sha256(code.encode()).hexdigest()[:16],
            }
        )
        loaded._code = runs
        return loaded

    def takes_data_folder(self) -> bool:
        """Whether its command line has the scenario's data folder third (as loaded, or as it reads)."""
        if self.data_folder is not None:
            return self.data_folder
        return convention(self.code(), len(self.args), self.script).data_folder

    def code(self) -> str:
        if self._code is None:  # made through the API, not loaded from a spec
            return self.loaded(Path.cwd(), "objective")._code
        return self._code


class ScriptWarning(UserWarning):
    """A user's script run otherwise than as written (a Python 2 script, ported for the run), or called on a
    command line it did not tell."""


_SAID: set[tuple[str, str, str]] = set()  # what was said of which script's text: once per process


def _say(path: Path, code: str, line: str) -> None:
    """``line`` as a warning, once per script text: a space loads several times (checks, each submission)."""
    key = (str(path), hashlib.sha256(code.encode()).hexdigest(), line)
    if key not in _SAID:
        _SAID.add(key)
        warnings.warn(ScriptWarning(line), stacklevel=3)


def write_results(path: Path, trajectory, columns: Mapping[str, str]) -> None:
    """``results.csv`` as INTO-CPS's co-simulation (Maestro) writes it: time, step-size, then the signals.
    The step-size of a row is the step that reached it, ``time[i] - time[i-1]``, and 0 on the first row:
    a script that sums ``value × step-size`` gets INTO-CPS's number, not one step more."""
    time = trajectory.time
    steps = np.diff(time, prepend=time[:1])
    names = [*trajectory.names, *columns]
    data = np.column_stack(
        [time, steps, trajectory.values, *(trajectory.column(signal) for signal in columns.values())]
    )
    with open(path, "w", newline="") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(["time", "step-size", *names])
        writer.writerows([f"{v:.16g}" for v in row] for row in data)


@cache
def _data_folder(files: tuple[tuple[str, Path], ...]) -> Path:
    """A scenario's data files laid out under their own names, once per process, in its
    scratch folder (removed at its exit)."""
    folder = Path(tempfile.mkdtemp(dir=scratch.own_folder("dse-runner-data-")))
    for name, source in files:
        target = folder / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.symlink_to(Path(source).resolve())
    return folder


def _script_file(spec: Script, folder: Path) -> Path:
    """The script where it was written when this machine has it unchanged (its own imports work),
    else a copy of the text it travelled with."""
    original = Path(spec.script)
    code = spec.code()
    if original.is_file() and original.read_text() == code:
        return original
    copy = folder / original.name
    copy.write_text(code)
    return copy


def _failure(stderr: str, script: str) -> str:
    """What a failing script said, its exception line first: a row's first line is what the command
    prints, and a traceback's first line says nothing. The end of stderr follows, for the traceback."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    if not lines:
        return ": (nothing on stderr)"
    frames = [int(n) for file, n in FRAME.findall(stderr) if Path(file).name == Path(script).name]
    where = f" at line {frames[-1]}" if frames else ""
    tail = stderr.strip()[-FAULT_TAIL:]
    return f"{where}: {lines[-1]}" + (f"\n{tail}" if tail != lines[-1] else "")


def _value(name: str, spec: Script, objectives: Path, result: subprocess.CompletedProcess) -> float:
    """The number the script wrote under ``name``; anything else is an error quoting the script."""
    what = f"objective {name!r}: script {Path(spec.script).name}"
    if result.returncode != 0:
        raise DseError(f"{what} failed (exit code {result.returncode}){_failure(result.stderr, spec.script)}")
    try:
        written = json.loads(objectives.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise DseError(f"{what} left objectives.json unreadable: {e}") from None
    if name not in written:
        raise DseError(f"{what} wrote no value for {name!r} in objectives.json")
    value = written[name]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise DseError(f"{what} wrote {value!r}, not a finite number")  # INTO-CPS's fault strings land here
    return float(value)


def run_scripts(
    scripts: Mapping[str, Script], trajectory, data: Mapping[str, Path], known: Mapping[str, Any]
) -> dict[str, float]:
    """Run every script objective of one simulation in one folder; ``known``: the values computed so far."""
    columns = {header: signal for spec in scripts.values() for header, signal in spec.columns.items()}
    values: dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="dse-runner-script-") as work:
        folder = Path(work) / "simulation"
        folder.mkdir()
        write_results(folder / "results.csv", trajectory, columns)
        objectives = folder / "objectives.json"
        objectives.write_text(json.dumps({k: v for k, v in known.items() if isinstance(v, float)}))
        data_folder = _data_folder(tuple(sorted(data.items())))
        for name, spec in scripts.items():
            passed = [str(data_folder)] if spec.takes_data_folder() else []
            script = str(_script_file(spec, Path(work)))
            argv = [sys.executable, script, str(folder), name, *passed, *spec.args]
            try:
                own = Path(spec.script).parent  # INTO-CPS runs scripts from their folder (a ported one's too)
                result = subprocess.run(
                    argv,
                    capture_output=True,
                    text=True,
                    timeout=spec.timeout,
                    check=False,
                    cwd=own if own.is_dir() else Path(argv[1]).parent,
                )
            except subprocess.TimeoutExpired:
                raise DseError(
                    f"objective {name!r}: script {Path(spec.script).name} ran past its timeout of "
                    f"{spec.timeout:g} s"
                ) from None
            values[name] = _value(name, spec, objectives, result)
    return values
