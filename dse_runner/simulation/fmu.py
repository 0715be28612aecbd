"""FMUs as a worker process holds them: described, extracted once, instantiated once, reset per run.

A sweep runs thousands of simulations of the same FMUs in each worker
process. Extracting a zip and loading a shared library per run would cost
more than the simulation, so this module keeps, per process, one extraction
per FMU content hash and one FMPy instance (``FMU2Slave``, ``FMU3Slave``,
``FMU2Model`` or ``FMU3Model``) per (content, instance name, interface), and
hands it out reset. Messages the FMU logs are kept so that an error can say
what the FMU said.

FMUs as they are found in the wild load where that is safe, with a one-line
:class:`FmuWarning` (docs/multimodel.md): a modelDescription.xml that breaks
the schema or FMPy's checks but still reads, or a binary named otherwise than
the model identifier when it is the only one for this platform. What cannot
work (no binary, several candidates, FMI 1.0, no interface) is an error.
"""

from __future__ import annotations

import hashlib
import itertools
import os
import shutil
import sys
import tempfile
import warnings
import zipfile
from collections import deque
from ctypes import byref
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

from fmpy import extract, platform, platform_tuple, sharedLibraryExtension
from fmpy.fmi2 import FMU2Model, FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.logging import addLoggerProxy
from fmpy.model_description import ModelDescription, read_model_description

from ..errors import DseError
from . import scratch

STATUS_NAMES = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
Interface = Literal["cs", "me"]
INTERFACE_NAMES = {"cs": "co-simulation", "me": "model exchange"}


class FmuWarning(UserWarning):
    """An FMU that breaks a rule but can be run safely; the CLI prints it as one line."""


@lru_cache(maxsize=256)
def _file_hash(path: str, size: int, mtime_ns: int) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()[:16]


def content_hash(path: Path) -> str:
    stat = path.stat()
    return _file_hash(str(path), stat.st_size, stat.st_mtime_ns)


# ---- describing ----------------------------------------------------------------------------------


@lru_cache(maxsize=256)
def _description(path: str, sha: str) -> ModelDescription:
    if not zipfile.is_zipfile(path):
        raise DseError(f"{path}: not an FMU: an FMU is a zip archive, and this file is not one")
    check_version(path, _declared_version(path))  # first: FMPy's reader fails obscurely on other layouts
    try:
        return read_model_description(path, validate=True)
    except Exception as strict:  # noqa: BLE001  (FMPy's ValidationError, or any exception for broken XML)
        problems = getattr(strict, "problems", None)
    try:
        description = read_model_description(path, validate=False)
    except Exception as e:  # noqa: BLE001  (FMPy's reader raises what its XML parser does)
        raise DseError(f"{path}: cannot read modelDescription.xml: {e}") from None
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        first = " ".join(str(problems[0]).split()).rstrip(".")  # one line, whatever FMPy's text
        warnings.warn(
            FmuWarning(
                f"{Path(path).name}: modelDescription.xml breaks the FMI standard: "
                f"{first}{more}; loaded anyway"
            ),
            stacklevel=2,
        )
    return description


def _declared_version(path: str) -> str:
    """The root's fmiVersion attribute, read without interpreting the rest of the XML."""
    from xml.etree.ElementTree import ParseError, iterparse

    try:
        with zipfile.ZipFile(path) as archive, archive.open("modelDescription.xml") as xml:
            _, root = next(iterparse(xml, events=("start",)))
    except (KeyError, ParseError, StopIteration) as e:
        raise DseError(f"{path}: cannot read modelDescription.xml: {e}") from None
    return root.get("fmiVersion") or "?"


def check_version(path, version: str | None) -> None:
    """FMI 2.0 and 3.0 only: FMI 1.0's API differs and FMPy's 1.0 support is not wired in."""
    version = version or "?"
    if not version.startswith(("2.", "3.")):
        raise DseError(
            f"{path}: FMI {version}: dse-runner runs FMI 2.0 and 3.0 FMUs; export this model "
            "as FMI 2.0 or 3.0"
        )


def describe(path: Path) -> ModelDescription:
    """The FMU's model description, without extracting it (once per content, warnings included)."""
    if not path.is_file():
        raise DseError(f"FMU not found: {path}")
    return _description(str(path), content_hash(path))


def model_identifiers(path: Path) -> set[str]:
    """The model identifiers an FMU declares (none if it is not a readable FMU): cheap, no check."""
    from xml.etree.ElementTree import ParseError, fromstring

    try:
        with zipfile.ZipFile(path) as archive:
            root = fromstring(archive.read("modelDescription.xml"))
    except (OSError, KeyError, ParseError, zipfile.BadZipFile):
        return set()
    return {part.get("modelIdentifier") for part in root if part.get("modelIdentifier")}


def choose_interface(path: Path, description: ModelDescription, wanted: Interface | None) -> Interface:
    """Co-simulation when the FMU offers it, unless model exchange is asked for; an error if the
    FMU cannot be run the way asked."""
    check_version(path, description.fmiVersion)
    offered = [i for i, part in (("cs", description.coSimulation), ("me", description.modelExchange)) if part]
    if not offered:
        raise DseError(f"{path}: offers neither co-simulation nor model exchange")
    if wanted is None:
        return offered[0]
    if wanted not in offered:
        raise DseError(
            f"{path}: {INTERFACE_NAMES[wanted]} was asked for, but the FMU offers only "
            f"{INTERFACE_NAMES[offered[0]]}"
        )
    return wanted


def _identifier(description: ModelDescription, interface: Interface) -> str:
    part = description.coSimulation if interface == "cs" else description.modelExchange
    return part.modelIdentifier


def _binary_dir(description: ModelDescription) -> str:
    return f"binaries/{platform_tuple if description.fmiVersion.startswith('3') else platform}"


def binary_in_archive(path: Path, description: ModelDescription, interface: Interface) -> str:
    """The archive member that is this platform's binary; warns if it is a stand-in for the one
    FMI names, errors if there is none or it is ambiguous. Checked where the FMU is described for a
    run, not where a client plans for workers of another platform."""
    folder = _binary_dir(description)
    expected = f"{folder}/{_identifier(description, interface)}{sharedLibraryExtension}"
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
    if expected in names:
        return expected
    here = [
        n
        for n in names
        if n.startswith(folder + "/") and n.endswith(sharedLibraryExtension) and n.count("/") == 2
    ]
    if len(here) == 1:
        warnings.warn(
            FmuWarning(f"{path.name}: no {expected}; using {here[0]}, the only binary for this platform"),
            stacklevel=2,
        )
        return here[0]
    platforms = sorted(
        {
            n.split("/")[1]
            for n in names
            if n.startswith("binaries/") and n.count("/") >= 2 and not n.endswith("/")
        }
    )
    has = (
        f"it has {', '.join(here)}"
        if here
        else f"it has binaries for {', '.join(platforms)}"
        if platforms
        else "it has no binaries"
    )
    raise DseError(f"{path}: no binary for this platform: {expected} is missing ({has})")


# ---- loading -------------------------------------------------------------------------------------


@dataclass
class LoadedFmu:
    """An FMU extracted in this process, with the interface it is run through."""

    path: Path
    sha: str
    unzip_dir: Path
    description: ModelDescription
    interface: Interface

    @property
    def version(self) -> int:
        return 3 if self.description.fmiVersion.startswith("3") else 2

    @property
    def identifier(self) -> str:
        return _identifier(self.description, self.interface)


_LOADED: dict[tuple[str, Interface], LoadedFmu] = {}


_EXTRACT_ROOT: Path | None = None  # set where a process shares its parent's extractions (isolation.py)


def extract_root() -> Path:
    """Where this process extracts FMUs: a folder of its own, or the one it was given."""
    if _EXTRACT_ROOT is not None:
        _EXTRACT_ROOT.mkdir(parents=True, exist_ok=True)
        return _EXTRACT_ROOT
    return scratch.own_folder("dse-runner-fmus-")


def use_extract_root(root: Path) -> None:
    """Extract into ``root`` from now on: the fresh processes of isolation.py
    find their parent's FMUs there."""
    global _EXTRACT_ROOT
    _EXTRACT_ROOT = root


_LAST: dict[tuple[str, Interface | None], tuple[tuple[int, int], LoadedFmu]] = {}


def load(path: Path, interface: Interface | None = None) -> LoadedFmu:
    """Extract ``path`` once per process, keyed by content hash; check it can run as asked. The same
    file unchanged (size and modification time) is found again with one ``stat``: a sweep loads its
    FMUs for every run."""
    try:
        stat = os.stat(path)
    except OSError:
        raise DseError(f"FMU not found: {path}") from None
    last = _LAST.get((str(path), interface))
    if last is not None and last[0] == (stat.st_size, stat.st_mtime_ns):
        return last[1]
    loaded = _load(path, interface)
    _LAST[(str(path), interface)] = ((stat.st_size, stat.st_mtime_ns), loaded)
    return loaded


def _load(path: Path, interface: Interface | None) -> LoadedFmu:
    sha = content_hash(path)
    description = describe(path)
    chosen = choose_interface(path, description, interface)
    loaded = _LOADED.get((sha, chosen))
    if loaded is None:
        member = binary_in_archive(path, description, chosen)  # warns once per process: loads are kept
        unzip_dir = extract_root() / sha
        if not unzip_dir.is_dir():
            _extract(path, unzip_dir)
        loaded = LoadedFmu(path, sha, unzip_dir, description, chosen)
        expected = unzip_dir / _binary_dir(description) / f"{loaded.identifier}{sharedLibraryExtension}"
        if not expected.is_file():  # a stand-in binary: give it the name FMPy loads, whole or not at all
            partial = expected.with_name(f".{expected.name}-{os.getpid()}")
            shutil.copyfile(unzip_dir / member, partial)
            os.replace(partial, expected)
        _LOADED[(sha, chosen)] = loaded
    return loaded


def _extract(path: Path, unzip_dir: Path) -> None:
    """Extract into ``unzip_dir`` whole or not at all; another process may be extracting the same FMU."""
    partial = Path(tempfile.mkdtemp(dir=unzip_dir.parent, prefix=f".{unzip_dir.name}-"))
    extract(str(path), str(partial))
    try:
        os.replace(partial, unzip_dir)
    except OSError:
        if not unzip_dir.is_dir():
            raise
        shutil.rmtree(partial, ignore_errors=True)  # the other one was first


# ---- instances -----------------------------------------------------------------------------------


@dataclass(eq=False)
class Instance:
    """One instantiated FMU, reused across runs with reset."""

    name: str
    fmu: LoadedFmu
    slave: Any  # FMU2Slave, FMU3Slave, FMU2Model or FMU3Model
    messages: deque = field(default_factory=lambda: deque(maxlen=20))
    used: bool = False
    environment: int = 0  # FMI 2: routes the C logger's messages here
    keep: Any = None  # callbacks ctypes must not collect

    def explain(self, what: str) -> str:
        """An error message naming the instance, the FMU and what it logged."""
        said = "; ".join(self.messages)
        return f"{self.name} ({self.fmu.description.modelName}): {what}" + (f": {said}" if said else "")

    def note(self, status: int, message: bytes | None) -> None:
        text = message.decode("utf-8", "replace") if message else ""
        level = STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else str(status)
        self.messages.append(text if status >= 3 else f"[{level}] {text}")


def _log2(environment, instance_name, status, category, message) -> None:
    """The one FMI 2 logger of this process: FMPy's varargs proxy keeps a single Python target,
    so messages are routed to their instance by the component environment. Messages of FMUs that
    FMPy itself instantiated (simulate_fmu, default callbacks), or that give no environment, are
    printed as FMPy would, but on stderr: stdout may be carrying ``--json``."""
    instance = _BY_ENVIRONMENT.get(environment or 0)
    if instance is not None:
        instance.note(status, message)
    else:
        level = STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else str(status)
        name = instance_name.decode("utf-8", "replace") if instance_name else "?"
        text = message.decode("utf-8", "replace") if message else ""
        print(f"[{level}] {name}: {text}", file=sys.stderr)


_LOGGER2 = fmi2CallbackLoggerTYPE(_log2)
_ENVIRONMENTS = itertools.count(1)
_BY_ENVIRONMENT: dict[int, Instance] = {}
_CLASSES = {(2, "cs"): FMU2Slave, (2, "me"): FMU2Model, (3, "cs"): FMU3Slave, (3, "me"): FMU3Model}


def _instantiate(name: str, fmu: LoadedFmu) -> Instance:
    slave = _CLASSES[(fmu.version, fmu.interface)](
        guid=fmu.description.guid,
        unzipDirectory=str(fmu.unzip_dir),
        modelIdentifier=fmu.identifier,
        instanceName=name,
    )
    instance = Instance(name, fmu, slave)
    try:
        if fmu.version == 2:
            _instantiate2(instance)
        else:
            instance.keep = lambda env, status, category, message: instance.note(status, message)
            slave.instantiate(logMessage=instance.keep)
    except Exception:  # noqa: BLE001  (whatever FMPy raised, the FMU's own log says why)
        raise DseError(instance.explain(f"fmi{fmu.version}Instantiate failed ({fmu.path.name})")) from None
    return instance


def _instantiate2(instance: Instance) -> None:
    instance.environment = next(_ENVIRONMENTS)
    _BY_ENVIRONMENT[instance.environment] = instance
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = _LOGGER2
    callbacks.allocateMemory = defaultCallbacks.allocateMemory
    callbacks.freeMemory = defaultCallbacks.freeMemory
    callbacks.componentEnvironment = instance.environment
    addLoggerProxy(byref(callbacks))  # formats the C varargs before Python sees the message
    instance.keep = callbacks
    instance.slave.instantiate(callbacks=callbacks)


_INSTANCES: dict[tuple[str, str, str], Instance] = {}


def acquire(name: str, fmu: LoadedFmu) -> Instance:
    """A ready-to-set-up instance: fresh the first time, reset afterwards."""
    key = (fmu.sha, name, fmu.interface)
    instance = _INSTANCES.get(key)
    if instance is None:
        instance = _INSTANCES[key] = _instantiate(name, fmu)
    elif instance.used:
        instance.messages.clear()
        try:
            instance.slave.reset()
        except Exception:  # noqa: BLE001  (an FMU that cannot reset gets a fresh instance)
            discard(instance)
            return acquire(name, fmu)
    instance.used = True
    return instance


def discard(instance: Instance) -> None:
    """Drop an instance an error left in an unknown state; the next run gets a new one."""
    _INSTANCES.pop((instance.fmu.sha, instance.name, instance.fmu.interface), None)
    try:
        instance.slave.freeInstance()
    except Exception:  # noqa: BLE001, S110  (it is being thrown away: a failing free changes nothing)
        pass
    _BY_ENVIRONMENT.pop(instance.environment, None)  # after: what it logs while freed is not printed
