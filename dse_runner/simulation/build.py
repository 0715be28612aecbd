"""Build FMUs from our C sources with the system C compiler.

An FMU source folder holds ``modelDescription.xml`` and the model's ``*.c``;
the shared FMI layer is the ``common`` folder beside it, or else the one the
package bundles (``bundled:fmus/common``), so a user's own model.c needs no copy. The built ``.fmu`` is cached
under a name that includes a hash of every input, so an edit to any source
rebuilds and an unchanged source is never rebuilt. The FMU carries its own
sources (``sources/``), as FMI allows, so it can be rebuilt elsewhere.

``common`` holds one layer per kind of FMU and the description picks it (see ``layer_of``):
FMI 2.0 co-simulation (``slave.c``), FMI 2.0 model exchange (``me2.c``), FMI 3.0 co-simulation
(``slave3.c``), FMI 3.0 model exchange (``me3.c``). A layer builds with what the two layers of its
FMI version share (``fmi2_common.c``, ``fmi3_common.c``) and what all four share (``fmi_common.c``).
Only the chosen layer's files, those shared ones and common's other headers (``bicycle.h``,
``file_parameter.h``) are compiled, hashed and shipped.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import fmpy

from .. import bundled
from ..errors import DseError

COMMON_DIR_NAME = "common"
CFLAGS = ("-O2", "-std=c11", "-fPIC", "-shared", "-Wall", "-Wextra", "-fvisibility=default")
PLATFORM_DIR = "binaries/linux64"  # FMI 2.0's platform folder
PLATFORM_DIR_FMI3 = "binaries/x86_64-linux"  # FMI 3.0 names platforms by tuple


@dataclass(frozen=True)
class Layer:
    """One of common's FMI layers: ``<stem>.c`` and ``<stem>.h``, built with the files it shares."""

    stem: str
    interface: str  # the description's element the layer implements: CoSimulation or ModelExchange
    platform_dir: str
    shared: tuple[
        str, ...
    ]  # stems of the .c/.h it builds with: its FMI version's common part, then every layer's


FMI2_SHARED = ("fmi2_common", "fmi_common")
FMI3_SHARED = ("fmi3_common", "fmi_common")
CS2 = Layer("slave", "CoSimulation", PLATFORM_DIR, FMI2_SHARED)
ME2 = Layer("me2", "ModelExchange", PLATFORM_DIR, FMI2_SHARED)
CS3 = Layer("slave3", "CoSimulation", PLATFORM_DIR_FMI3, FMI3_SHARED)
ME3 = Layer("me3", "ModelExchange", PLATFORM_DIR_FMI3, FMI3_SHARED)
LAYERS = (CS2, ME2, CS3, ME3)


class BuildError(DseError):
    """An FMU's C sources did not compile."""


def default_cache_dir() -> Path:
    """Where built FMUs are kept: $DSE_RUNNER_CACHE or ~/.cache/dse-runner."""
    root = os.environ.get("DSE_RUNNER_CACHE") or Path.home() / ".cache" / "dse-runner"
    return Path(root) / "fmus"


def fmi_headers_dir() -> Path:
    """FMPy ships the FMI 2.0 and 3.0 headers; we compile against those."""
    return Path(fmpy.__file__).parent / "c-code"


def is_source_dir(path: Path) -> bool:
    return path.is_dir() and (path / "modelDescription.xml").is_file() and any(path.glob("*.c"))


def read_description(source_dir: Path):
    from fmpy.model_description import read_model_description

    try:
        return read_model_description(str(source_dir / "modelDescription.xml"), validate=False)
    except Exception as e:  # FMPy raises plain Exceptions for malformed descriptions
        raise BuildError(f"{source_dir}/modelDescription.xml cannot be read: {e}") from e


def real_parameters(source_dir: Path) -> dict[str, float]:
    """The start values of the real parameters of the FMU built from ``source_dir``."""
    return {
        v.name: float(v.start)
        for v in read_description(source_dir).modelVariables
        if v.causality == "parameter" and v.type == "Real" and v.start is not None
    }


def layer_of(source_dir: Path) -> Layer:
    """The layer the description asks for: its FMI version's model-exchange layer (me2, me3) if it
    declares only <ModelExchange>, else its co-simulation layer (slave, slave3)."""
    md = read_description(source_dir)
    if md.fmiVersion not in ("2.0", "3.0"):
        raise BuildError(
            f"{source_dir}/modelDescription.xml: fmiVersion {md.fmiVersion!r} is not built here (2.0 or 3.0)"
        )
    if md.coSimulation is None and md.modelExchange is None:
        raise BuildError(
            f"{source_dir}/modelDescription.xml declares neither <CoSimulation> nor <ModelExchange>"
        )
    co_simulation, model_exchange = (CS3, ME3) if md.fmiVersion == "3.0" else (CS2, ME2)
    return co_simulation if md.coSimulation is not None else model_exchange


def common_dir(source_dir: Path, layer: Layer | None = None) -> Path:
    """The shared FMI layer a source folder compiles with: its sibling ``common`` if that has the
    layer, else the bundled one."""
    layer = layer or layer_of(source_dir)
    beside = source_dir.parent / COMMON_DIR_NAME
    return beside if (beside / f"{layer.stem}.c").is_file() else bundled_sources() / COMMON_DIR_NAME


def bundled_sources() -> Path:
    """The FMU source folders that ship inside the package."""
    return bundled.fmus_root()


def source_files(source_dir: Path, layer: Layer | None = None) -> list[Path]:
    """The model's own C files, then the chosen layer's, then the files it shares with the other layer
    of its FMI version and with all layers, then common's other files (headers such as bicycle.h);
    the other layers' files are left out. A shared file a ``common`` folder lacks is skipped: a
    folder of older, self-contained layers still builds."""
    layer = layer or layer_of(source_dir)
    common = common_dir(source_dir, layer)
    if not (common / f"{layer.stem}.c").is_file():
        raise BuildError(
            f"{source_dir}: the shared FMI layer {common}/{layer.stem}.c is missing"
            f" (it implements {layer.interface} for this modelDescription.xml)"
        )
    own = sorted(source_dir.glob("*.c")) + sorted(source_dir.glob("*.h"))
    stems = (layer.stem, *layer.shared)
    chosen = [p for stem in stems for p in (common / f"{stem}.c", common / f"{stem}.h") if p.is_file()]
    layer_stems = {stem for other in LAYERS for stem in (other.stem, *other.shared)}
    rest = [p for p in sorted(common.glob("*.c")) + sorted(common.glob("*.h")) if p.stem not in layer_stems]
    return own + chosen + rest


def model_identifier(source_dir: Path, layer: Layer | None = None) -> str:
    """The modelIdentifier of the interface the layer implements (CoSimulation or ModelExchange)."""
    layer = layer or layer_of(source_dir)
    md = read_description(source_dir)
    interface = md.coSimulation if layer.interface == "CoSimulation" else md.modelExchange
    return interface.modelIdentifier


def source_hash(source_dir: Path, layer: Layer | None = None) -> str:
    """Hash of everything that determines the binary: sources, description, flags."""
    digest = hashlib.sha256()
    for path in [source_dir / "modelDescription.xml", *source_files(source_dir, layer)]:
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    digest.update(" ".join(CFLAGS).encode())
    return digest.hexdigest()[:16]


def compiler() -> str:
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if not cc:
        raise BuildError("no C compiler found: install gcc (Debian: apt-get install gcc) or set CC")
    return cc


def build_fmu(source_dir: str | Path, cache_dir: Path | None = None) -> Path:
    """Return the path of the built FMU for ``source_dir``, compiling it if needed."""
    source_dir = Path(source_dir).resolve()
    if not is_source_dir(source_dir):
        raise BuildError(f"{source_dir} is not an FMU source folder (modelDescription.xml and *.c)")
    layer = layer_of(source_dir)
    identifier = model_identifier(source_dir, layer)
    cache_dir = Path(cache_dir or default_cache_dir())
    target = cache_dir / f"{identifier}-{source_hash(source_dir, layer)}.fmu"
    if target.is_file():
        return target
    cache_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f"build-{identifier}-") as tmp:
        library = Path(tmp) / f"{identifier}.so"
        sources = source_files(source_dir, layer)
        command = [
            compiler(),
            *CFLAGS,
            f"-I{fmi_headers_dir()}",
            f"-I{common_dir(source_dir, layer)}",
            "-o",
            str(library),
            *[str(p) for p in sources if p.suffix == ".c"],
            "-lm",
        ]
        done = subprocess.run(command, check=False, capture_output=True, text=True)
        if done.returncode != 0:
            raise BuildError(f"compiling {source_dir.name} failed:\n{done.stderr.strip()}")
        # Zip beside the target, then rename: a concurrent builder never sees half a zip.
        handle, partial = tempfile.mkstemp(dir=cache_dir, prefix=f".{identifier}-", suffix=".partial")
        os.close(handle)
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as fmu:
            fmu.write(source_dir / "modelDescription.xml", "modelDescription.xml")
            fmu.write(library, f"{layer.platform_dir}/{identifier}.so")
            for path in sources:
                fmu.write(path, f"sources/{path.name}")
        os.replace(partial, target)
    return target


def find_source_dirs(root: str | Path | None = None) -> list[Path]:
    """Every FMU source folder directly under ``root`` (default: the bundled ones)."""
    root = Path(root) if root is not None else bundled_sources()
    if not root.is_dir():
        raise BuildError(f"{root} is not a folder of FMU sources")
    return [p for p in sorted(root.iterdir()) if p.name != COMMON_DIR_NAME and is_source_dir(p)]


def resolve_fmu(path: str | Path, cache_dir: Path | None = None) -> Path:
    """An FMU reference is a built ``.fmu`` or a source folder, built on first use."""
    path = Path(path)
    if path.is_dir():
        return build_fmu(path, cache_dir)
    if path.is_file():
        return path
    raise DseError(f"FMU not found: {path}")
