"""What ships inside the package: our FMUs' C sources and the Robotti example's multi-model and
calibration space, found at run time wherever the package is installed.

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


def is_bundled(reference: str | Path) -> bool:
    return str(reference).startswith(PREFIX)


def bundled_path(reference: str) -> Path:
    """``bundled:fmus/robotti_vehicle`` -> the installed folder or file it names."""
    relative = reference.removeprefix(PREFIX).strip("/")
    path = root() / relative
    if not relative or ".." in Path(relative).parts or not path.exists():
        available = ", ".join(f"{PREFIX}{p.relative_to(root())}" for p in listing())
        raise DseError(f"{reference!r}: dse-runner bundles no such file (it bundles {available})")
    return path


def listing() -> list[Path]:
    """The bundled FMU source folders and example files: what an error about a bundled name lists."""
    folder = root() / "fmus"
    fmus = [p for p in sorted(folder.iterdir()) if (p / "modelDescription.xml").is_file()] if folder.is_dir() else []
    examples = sorted(p for p in root().glob("*/*.yaml"))
    return fmus + examples


def resolve(reference: str | Path, base: Path) -> Path:
    """A path as a file names it: ``bundled:...``, absolute, or relative to ``base``."""
    if is_bundled(reference):
        return bundled_path(str(reference))
    path = Path(reference)
    return path if path.is_absolute() else (base / path).resolve()
