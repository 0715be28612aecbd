"""FMUs as a worker process holds them: extracted once, instantiated once, reset per run.

A sweep runs thousands of simulations of the same FMUs in each worker
process. Extracting a zip and loading a shared library per run would cost
more than the simulation, so this module keeps, per process, one extraction
per FMU content hash and one FMPy ``FMU2Slave`` per (content, instance name),
and hands it out reset. Messages the FMU logs are kept so that an error can
say what the FMU said.
"""

from __future__ import annotations

import hashlib
import itertools
import os
import tempfile
import zipfile
from collections import deque
from ctypes import byref
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from fmpy import extract, platform, sharedLibraryExtension
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.logging import addLoggerProxy
from fmpy.model_description import ModelDescription, read_model_description

from .errors import DseError

STATUS_NAMES = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")


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


@dataclass
class LoadedFmu:
    """An FMU extracted in this process."""

    path: Path
    sha: str
    unzip_dir: Path
    description: ModelDescription


_LOADED: dict[str, LoadedFmu] = {}


def extract_root() -> Path:
    root = Path(tempfile.gettempdir()) / f"dse-runner-fmus-{os.getpid()}"
    root.mkdir(parents=True, exist_ok=True)
    return root


@lru_cache(maxsize=256)
def _description(path: str, sha: str) -> ModelDescription:
    if not zipfile.is_zipfile(path):
        raise DseError(f"{path}: not an FMU: an FMU is a zip archive, and this file is not one")
    try:
        description = read_model_description(path, validate=False)
    except Exception as e:  # FMPy raises plain exceptions for bad archives and XML
        raise DseError(f"{path}: cannot read modelDescription.xml: {e}") from None
    return description


def _check_binary(path: Path, identifier: str) -> None:
    """The FMU must carry a binary this process can load, named as FMI requires. Checked where the FMU
    is loaded, not where it is described: a client may plan for workers of another platform."""
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
    if f"binaries/{platform}/{identifier}{sharedLibraryExtension}" in names:
        return
    platforms = sorted({n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2
                        and not n.endswith("/")})
    has = f"it has binaries for {', '.join(platforms)}" if platforms else "it has no binaries"
    raise DseError(f"{path}: no binary for this platform: binaries/{platform}/{identifier}{sharedLibraryExtension} "
                   f"is missing ({has})")


def describe(path: Path) -> ModelDescription:
    """The FMU's model description, without extracting it."""
    if not path.is_file():
        raise DseError(f"FMU not found: {path}")
    return _description(str(path), content_hash(path))


def load(path: Path) -> LoadedFmu:
    """Extract ``path`` once per process, keyed by content hash."""
    sha = content_hash(path)
    loaded = _LOADED.get(sha)
    if loaded is None:
        description = describe(path)
        if description.coSimulation is None:
            raise DseError(f"{path}: not a co-simulation FMU")
        _check_binary(path, description.coSimulation.modelIdentifier)
        unzip_dir = extract_root() / sha
        if not unzip_dir.is_dir():
            partial = Path(tempfile.mkdtemp(dir=extract_root(), prefix=f".{sha}-"))
            extract(str(path), str(partial))
            os.replace(partial, unzip_dir)
        loaded = _LOADED[sha] = LoadedFmu(path, sha, unzip_dir, description)
    return loaded


@dataclass(eq=False)
class Instance:
    """One instantiated FMU, reused across runs with fmi2Reset."""

    name: str
    fmu: LoadedFmu
    slave: FMU2Slave
    messages: deque = field(default_factory=lambda: deque(maxlen=20))
    used: bool = False
    callbacks: fmi2CallbackFunctions | None = None

    def explain(self, what: str) -> str:
        """An error message naming the instance, the FMU and what it logged."""
        said = "; ".join(self.messages)
        return f"{self.name} ({self.fmu.description.modelName}): {what}" + (f": {said}" if said else "")


def _log(environment, instance_name, status, category, message) -> None:
    """The one logger of this process: FMPy's varargs proxy keeps a single Python target,
    so messages are routed to their instance by the component environment."""
    instance = _BY_ENVIRONMENT.get(environment or 0)
    if instance is None:
        return
    text = message.decode("utf-8", "replace") if message else ""
    level = STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else str(status)
    instance.messages.append(text if status >= 3 else f"[{level}] {text}")


_LOGGER = fmi2CallbackLoggerTYPE(_log)
_ENVIRONMENTS = itertools.count(1)
_BY_ENVIRONMENT: dict[int, "Instance"] = {}


def _instantiate(name: str, fmu: LoadedFmu) -> Instance:
    cs = fmu.description.coSimulation
    slave = FMU2Slave(
        guid=fmu.description.guid,
        unzipDirectory=str(fmu.unzip_dir),
        modelIdentifier=cs.modelIdentifier,
        instanceName=name,
    )
    instance = Instance(name, fmu, slave)
    environment = next(_ENVIRONMENTS)
    _BY_ENVIRONMENT[environment] = instance
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = _LOGGER
    callbacks.allocateMemory = defaultCallbacks.allocateMemory
    callbacks.freeMemory = defaultCallbacks.freeMemory
    callbacks.componentEnvironment = environment
    addLoggerProxy(byref(callbacks))  # formats the C varargs before Python sees the message
    instance.callbacks = callbacks
    try:
        slave.instantiate(callbacks=callbacks)
    except Exception:
        raise DseError(instance.explain("fmi2Instantiate failed")) from None
    return instance


_INSTANCES: dict[tuple[str, str], Instance] = {}


def acquire(name: str, fmu: LoadedFmu) -> Instance:
    """A ready-to-set-up instance: fresh the first time, reset afterwards."""
    key = (fmu.sha, name)
    instance = _INSTANCES.get(key)
    if instance is None:
        instance = _INSTANCES[key] = _instantiate(name, fmu)
    elif instance.used:
        instance.messages.clear()
        try:
            instance.slave.reset()
        except Exception:
            discard(instance)
            return acquire(name, fmu)
    instance.used = True
    return instance


def discard(instance: Instance) -> None:
    """Drop an instance an error left in an unknown state; the next run gets a new one."""
    _INSTANCES.pop((instance.fmu.sha, instance.name), None)
    if instance.callbacks is not None:
        _BY_ENVIRONMENT.pop(instance.callbacks.componentEnvironment, None)
    try:
        instance.slave.freeInstance()
    except Exception:
        pass
