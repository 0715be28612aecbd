"""What ships inside the package: our FMUs' C sources (the checkout's top-level fmus/, installed as
``dse_runner.bundled.fmus``) and the Robotti example's multi-model and calibration space, found at run
time wherever the package is installed.

Files name them with the ``bundled:`` prefix, e.g. ``bundled:fmus/robotti_vehicle`` in a
multi-model or ``bundled:robotti/calibration.yaml`` as a space, so a job folder keeps working
when it is copied away from the repository or used from an installed wheel.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from ..errors import DseError

PREFIX = "bundled:"


def root() -> Path:
    """The folder of bundled files (this package's own folder; wheels install it unzipped)."""
    return Path(str(files(__name__)))


def fmus_root() -> Path:
    """The folder of our FMUs' C sources: the checkout's top-level fmus/, installed as the package
    ``dse_runner.bundled.fmus`` (pyproject.toml maps it there)."""
    return Path(str(files(f"{__name__}.fmus")))


def _located(relative: str) -> Path:
    """Where a bundled name's file is: ``fmus/...`` among the FMU sources, anything else in this folder."""
    first, _, rest = relative.partition("/")
    return fmus_root() / rest if first == "fmus" else root() / relative


def is_bundled(reference: str | Path) -> bool:
    return str(reference).startswith(PREFIX)


def bundled_path(reference: str) -> Path:
    """``bundled:fmus/robotti_vehicle`` -> the installed folder or file it names."""
    relative = reference.removeprefix(PREFIX).strip("/")
    path = _located(relative)
    if not relative or ".." in Path(relative).parts or not path.exists():
        available = ", ".join(_name(p) for p in listing())
        raise DseError(f"{reference!r}: dse-runner bundles no such file (it bundles {available})")
    return path


def listing() -> list[Path]:
    """The bundled FMU source folders and example files: what an error about a bundled name lists."""
    folder = fmus_root()
    fmus = (
        [p for p in sorted(folder.iterdir()) if (p / "modelDescription.xml").is_file()]
        if folder.is_dir()
        else []
    )
    examples = sorted(p for p in root().glob("*/*.yaml"))
    return fmus + examples


def _name(path: Path) -> str:
    """The ``bundled:`` name of a listed file."""
    if path.is_relative_to(fmus_root()):
        return f"{PREFIX}fmus/{path.relative_to(fmus_root())}"
    return f"{PREFIX}{path.relative_to(root())}"


def resolve(reference: str | Path, base: Path) -> Path:
    """A path as a file names it: ``bundled:...``, absolute, or relative to ``base``."""
    if is_bundled(reference):
        return bundled_path(str(reference))
    path = Path(reference)
    return path if path.is_absolute() else (base / path).resolve()
