"""A user's own objective module beside their space.yaml: found without PYTHONPATH, and shipped to workers.

``objectives: {overshoot: scores:overshoot}`` with ``scores.py`` next to the space names the function
``overshoot`` of that file, as a script imports a module from its own folder. Why not PYTHONPATH: Dask's
workers run in other processes, maybe on other machines, that never see the client's folder. So the file
is read where the spec is loaded, imported under its module name there, and its source travels to the
workers inside the sweep's shipment (sweeps/ship.py), where it is imported the same way. A file beside
the spec wins over an installed module of the same name, as a script's own folder does.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
import traceback
from collections.abc import Iterable
from pathlib import Path

from ..errors import DseError

_LOADED: dict[str, str] = {}  # module name -> the hash of the source it was imported from


def module_name(objective: object) -> str | None:
    """The top-level module an objective written ``module:function`` names; None for any other."""
    if not isinstance(objective, str) or ":" not in objective:
        return None
    name = objective.partition(":")[0]
    return name if name.isidentifier() else None


def beside(objectives: Iterable[object], folder: Path) -> dict[str, bytes]:
    """The sources of the objectives' modules that are files ``NAME.py`` in ``folder``, by module name."""
    found: dict[str, bytes] = {}
    for name in filter(None, map(module_name, objectives)):
        path = folder / f"{name}.py"
        if path.is_file():
            try:
                found[name] = path.read_bytes()
            except OSError as e:
                raise DseError(f"objective module {path}: cannot read it: {e.strerror}") from None
    return found


def digest(source: bytes) -> str:
    return hashlib.sha256(source).hexdigest()[:16]


def load(name: str, path: Path, source: bytes | None = None) -> None:
    """Import the file ``path`` as module ``name`` (again when its source changed): ``import name`` and
    ``module:function`` then find it. An error while importing it is one error naming the file and line."""
    source = path.read_bytes() if source is None else source
    if _LOADED.get(name) == digest(source) and name in sys.modules:
        return
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    previous = sys.modules.get(name)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as e:  # noqa: BLE001  (a user's module may raise anything while it is imported)
        if previous is None:
            sys.modules.pop(name, None)
        else:
            sys.modules[name] = previous
        raise DseError(f"objective module {path}: {_where(e, path)}{type(e).__name__}: {e}") from None
    _LOADED[name] = digest(source)


def _where(error: Exception, path: Path) -> str:
    """``line N: `` of the innermost frame in the user's file, or of a syntax error in it."""
    if isinstance(error, SyntaxError) and error.lineno:
        return f"line {error.lineno}: "
    lines = [f.lineno for f in traceback.extract_tb(error.__traceback__) if Path(f.filename) == path]
    return f"line {lines[-1]}: " if lines else ""


def import_beside(objectives: Iterable[object], folder: Path) -> dict[str, bytes]:
    """Import the objectives' modules that are files in ``folder``; their sources, to ship to workers."""
    modules = beside(objectives, folder)
    for name, source in modules.items():
        load(name, folder / f"{name}.py", source)
    return modules
