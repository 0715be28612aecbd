"""Getting a sweep's FMUs and recordings to workers that share no file system with the client.

The client packs a :class:`Shipment`: the bytes of every FMU (keyed by
content hash), the multi-model pointing at those hashes, the scenarios as
read and checked (their signals and recordings travel with them), and the
files scenarios hand to FMUs by path (a steering log the replay controller
reads). It travels inside a Dask worker plugin, which is how
``distributed`` hands state to workers: the scheduler keeps the plugin and
gives it to every worker that joins later, so a worker restarted after a
crash, or one added by an HTCondor job that started late, has the model too.
A worker writes the files into its own temporary folder, keyed by content
hash, the first time a chunk needs them, and keeps the loaded plan for the
next chunk.

Plugins are named by the shipment's hash and registered idempotently, so the
rounds of a fit (many sweeps of one model) send the model once.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import uuid
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from distributed.diagnostics.plugin import WorkerPlugin

from ..errors import DseError
from ..simulation import scratch, user_modules
from ..simulation.multimodel import MultiModel
from ..simulation.plan import Plan, make_plan
from ..simulation.scenario import Scenario


@dataclass(frozen=True)
class Shipment:
    """Everything a worker needs to simulate a space's tasks; picklable, a few hundred kB."""

    key: str
    multimodel: MultiModel  # its ``fmus`` name content hashes, not paths
    fmus: dict[str, bytes]  # content hash -> .fmu archive
    scenarios: dict[str, Scenario]  # read and checked on the client; their data travel with them
    files: dict[
        str, bytes
    ]  # content hash -> a file an FMU or a script reads (a scenario's ``files``, ``data``)
    modules: dict[str, bytes] = field(default_factory=dict)  # name -> source: objective modules by the spec
    names: dict[str, str] = field(default_factory=dict)  # content hash -> the FMU's file name, for messages


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def _read(scenario: Scenario, path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as e:
        raise DseError(f"scenario {scenario.name}: cannot read {e.filename}: {e.strerror}") from None


def pack(plan: Plan, scenarios: list[Scenario], modules: dict[str, bytes] | None = None) -> Shipment:
    """Read the built FMUs and the files scenarios hand to FMUs into one shipment, with the sources of the
    user's objective modules (simulation/user_modules.py)."""
    archives = {name: Path(path).read_bytes() for name, path in plan.fmu_paths.items()}
    fmus = {_sha(data): data for data in archives.values()}
    names = {_sha(archives[name]): Path(path).name for name, path in plan.fmu_paths.items()}
    multimodel = plan.multimodel.model_copy(
        update={"fmus": {name: _sha(data) for name, data in archives.items()}}
    )
    files: dict[str, bytes] = {}
    packed = {}
    for scenario in scenarios:
        contents = {name: _read(scenario, path) for name, path in scenario.files.items()}
        data = {name: _read(scenario, path) for name, path in scenario.data.items()}
        files.update({_sha(content): content for content in (*contents.values(), *data.values())})
        # the scenario's files become content hashes, as the multi-model's FMUs do
        packed[scenario.name] = scenario.with_files(
            {name: Path(_sha(c)) for name, c in contents.items()}
        ).with_data({name: Path(_sha(c)) for name, c in data.items()})
    digest = hashlib.sha256()
    digest.update(multimodel.model_dump_json().encode())
    for sha in sorted(fmus) + sorted(files):
        digest.update(sha.encode())
    for name in sorted(packed):
        digest.update(pickle.dumps(packed[name]))
    modules = dict(modules or {})
    for name in sorted(modules):
        digest.update(f"{name}:{user_modules.digest(modules[name])}".encode())
    return Shipment(digest.hexdigest()[:24], multimodel, fmus, packed, files, modules, names)


@dataclass
class Unpacked:
    """A shipment on a worker: files written locally, FMUs checked and ready to instantiate."""

    plan: Plan
    scenarios: dict[str, Scenario]


_RECEIVED: dict[str, Shipment] = {}
_UNPACKED: dict[str, Unpacked] = {}


def local_root() -> Path:
    return scratch.own_folder("dse-runner-shipments-")


def _write_once(path: Path, data: bytes) -> Path:
    """Write under a temporary name and rename, so a path that exists is always complete."""
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f".{path.name}.{uuid.uuid4().hex}.partial")  # threads of one worker may race
        partial.write_bytes(data)
        os.replace(partial, path)
    return path


def unpack(shipment: Shipment) -> Unpacked:
    """Write the shipment's files under this process's temporary folder, once."""
    done = _UNPACKED.get(shipment.key)
    if done is not None:
        return done
    root = local_root()
    # under their own file names (in a folder named by content), so a worker's messages name the user's FMU
    paths = {
        sha: _write_once(root / "fmus" / sha / shipment.names.get(sha, f"{sha}.fmu"), data)
        for sha, data in shipment.fmus.items()
    }
    multimodel = shipment.multimodel.model_copy(
        update={"fmus": {name: str(paths[sha]) for name, sha in shipment.multimodel.fmus.items()}}
    )
    files = {sha: _write_once(root / "files" / sha, data) for sha, data in shipment.files.items()}
    for name, source in shipment.modules.items():  # named by hash: two versions of one module never mix
        path = _write_once(root / "modules" / user_modules.digest(source) / f"{name}.py", source)
        user_modules.load(name, path, source)
    scenarios = {
        name: s.with_files({field: files[str(sha)] for field, sha in s.files.items()}).with_data(
            {file: files[str(sha)] for file, sha in s.data.items()}
        )
        for name, s in shipment.scenarios.items()
    }
    done = _UNPACKED[shipment.key] = Unpacked(make_plan(multimodel), scenarios)
    return done


def received(key: str) -> Unpacked:
    """The unpacked shipment ``key``; on a worker it arrived through :class:`ShipmentPlugin`."""
    if key not in _UNPACKED and key in _RECEIVED:
        unpack(_RECEIVED[key])
    try:
        return _UNPACKED[key]
    except KeyError:
        raise DseError(
            f"this worker has no shipment {key}: its plugin was not registered with the "
            "scheduler (was the scheduler restarted? submitting again registers it)"
        ) from None


class ShipmentPlugin(WorkerPlugin):
    """Hands a shipment to every worker, present and future."""

    idempotent = True  # registering the same shipment twice sends it once

    def __init__(self, shipment: Shipment):
        self.shipment = shipment
        self.name = plugin_name(shipment.key)

    def setup(self, worker) -> None:
        _RECEIVED[self.shipment.key] = self.shipment
        warnings.formatwarning = _one_line  # our warnings on the worker's stderr as the command prints them

    def teardown(self, worker) -> None:
        _RECEIVED.pop(self.shipment.key, None)
        _UNPACKED.pop(self.shipment.key, None)


_PYTHON_FORMAT = warnings.formatwarning


def _one_line(message, category, filename, lineno, line=None) -> str:
    """dse-runner's own warnings as one line (``warning: …``, as the CLI prints them), where a worker prints
    them; any other as Python formats it."""
    if category.__module__.startswith("dse_runner."):
        return f"warning: {message}\n"
    return _PYTHON_FORMAT(message, category, filename, lineno, line)


def plugin_name(key: str) -> str:
    return f"dse-runner-shipment-{key}"


def send(client, shipment: Shipment) -> None:
    """Register the shipment with the scheduler (once per scheduler) and so with every worker. The
    workers unpickle it first thing: one that cannot import dse_runner fails here, and says so."""
    try:
        client.register_plugin(ShipmentPlugin(shipment), name=plugin_name(shipment.key))
    except Exception as e:
        if "dse_runner" not in str(e):
            raise
        raise DseError(
            f"the Dask workers of {client.scheduler.address} cannot import dse_runner ({e}): "
            "install dse-runner, the same version as here, where the workers run"
        ) from None
