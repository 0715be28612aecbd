"""A fresh process for each run, for FMUs that cannot be trusted with a second run in one process.

Some exported FMUs keep state in their shared library: they declare
``canBeInstantiatedOnlyOncePerProcess``, keep old outputs after ``fmi2Reset``,
or crash when instantiated again. The only safe way to run them many times
is the reference itself: every run in a process that has never loaded them.

A Dask worker can neither fork itself (it has threads) nor start
multiprocessing children (it is daemonic), so each thread that needs this
keeps a *zygote*: a Python process started once with :mod:`subprocess`,
single-threaded, that imports the simulation modules and describes the FMUs
but never loads one. For every run it forks a child, which calls the function
it was sent, sends back the result (or the exception) through a pipe and
exits without freeing anything. A child that dies (an FMU's ``abort`` or
segmentation fault) comes back as a :class:`~dse_runner.simulation.trajectory.CosimError`
naming the signal and the last line the process printed.
"""

from __future__ import annotations

import ctypes
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
import warnings
import weakref
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, BinaryIO

from ..errors import DseError
from .trajectory import CosimError

_HEADER = struct.Struct("!Q")
_LOCAL = threading.local()
KILL_GRACE = (
    10.0  # seconds past a run's own timeout before its fresh process is killed (it stops itself first)
)
_IN_CHILD = False  # true in a forked child: the run happens here, not in yet another process


def in_child() -> bool:
    """Whether this process is a fresh one forked for a single run."""
    return _IN_CHILD


def run(
    function: Callable[..., Any],
    *args: Any,
    preload: Iterable[tuple[Path, str]] = (),
    kill_after: float | None = None,
) -> Any:
    """``function(*args)`` in a fresh process; its result, or its exception raised here. ``preload``:
    the FMUs (path, interface) the zygote describes and extracts once, so a child only loads them.
    ``kill_after``: seconds after which the child is killed, for a run hung inside an FMU call, where
    the step loop's own timeout cannot reach."""
    if _IN_CHILD:  # never a zygote of a zygote's child: that would multiply processes
        raise DseError("a fresh process asked for another fresh process (a bug in dse-runner)")
    zygote = getattr(_LOCAL, "zygote", None)
    if zygote is None or zygote.process.poll() is not None:
        zygote = _LOCAL.zygote = _Zygote()
    ok, value = zygote.call(function, args, list(preload), kill_after)
    if not ok:
        raise value
    return value


class _Zygote:
    """The parent of the fresh processes of one thread; ends when its pipe closes (with this process)."""

    def __init__(self):
        from .fmu import extract_root

        package_parent = str(Path(__file__).resolve().parents[2])
        env = {
            **os.environ,
            "LIBC_FATAL_STDERR_": "1",
            "OPENBLAS_NUM_THREADS": "1",
            "OMP_NUM_THREADS": "1",
            "PYTHONPATH": os.pathsep.join(filter(None, (package_parent, os.environ.get("PYTHONPATH")))),
        }
        self.process = subprocess.Popen(
            [sys.executable, "-m", __name__, str(extract_root())],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=env,
        )
        weakref.finalize(self, _close, self.process)  # at exit too: the zygote ends with its pipe

    def call(
        self, function: Callable[..., Any], args: tuple, preload: list, kill_after: float | None = None
    ) -> tuple[bool, Any]:
        try:
            request = (function, args, preload, kill_after)
            _send(self.process.stdin, pickle.dumps(request, protocol=pickle.HIGHEST_PROTOCOL))
            reply = _receive(self.process.stdout)
        except (BrokenPipeError, OSError):
            reply = None
        if reply is None:
            self.process.kill()
            raise DseError(
                f"the process that starts fresh processes for FMU runs ended (exit code "
                f"{self.process.wait()}); see the worker's log"
            )
        return pickle.loads(reply)


def _close(process: subprocess.Popen) -> None:
    """Close the zygote's pipes (it then exits) and collect it."""
    for stream in (process.stdin, process.stdout):
        try:
            stream.close()
        except OSError:
            pass
    try:
        process.wait(timeout=5)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def _send(stream: BinaryIO, payload: bytes) -> None:
    stream.write(_HEADER.pack(len(payload)))
    stream.write(payload)
    stream.flush()


def _receive(stream: BinaryIO) -> bytes | None:
    header = stream.read(_HEADER.size)
    if len(header) < _HEADER.size:
        return None
    return stream.read(_HEADER.unpack(header)[0])


# ---- the zygote's side ---------------------------------------------------------------------------


def _serve(extract_root: str) -> None:
    """Answer requests until the parent closes the pipe. Frames travel on a copy of stdout; fd 1 then
    points at stderr, so that what an FMU prints cannot corrupt them."""
    frames_out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    from . import fmu as fmus

    # A request's function is imported here as the request is read (its module and all that one imports),
    # once and before any fork: each child only runs it.

    fmus.use_extract_root(Path(extract_root))
    warnings.simplefilter("ignore")  # the worker has warned about these FMUs already
    requests = sys.stdin.buffer
    while (request := _receive(requests)) is not None:
        try:
            function, args, preload, kill_after = pickle.loads(request)
        except Exception as e:  # noqa: BLE001  (a function this process cannot import: the caller's error)
            _send(frames_out, pickle.dumps((False, DseError(f"cannot run this in a fresh process: {e}"))))
            continue
        for path, interface in preload:
            try:
                fmus.load(Path(path), interface)  # describe and find the extraction once, for every child
            except DseError:
                pass  # the child meets the same error and reports it
        _send(frames_out, _fork(function, args, kill_after))


def _fork(function: Callable[..., Any], args: tuple, kill_after: float | None = None) -> bytes:
    """Run ``function(*args)`` in a forked child; its pickled (ok, value), or an error if it died or,
    after ``kill_after`` seconds, had to be killed."""
    read_end, write_end = os.pipe()
    with tempfile.TemporaryFile() as log:
        pid = os.fork()
        if pid == 0:  # the child: never returns
            os.close(read_end)
            os.dup2(log.fileno(), 1)
            os.dup2(log.fileno(), 2)
            _child(function, args, write_end)
        os.close(write_end)
        data, hung = _read_all(read_end, kill_after)
        if hung:
            os.kill(pid, signal.SIGKILL)
        _, status = os.waitpid(pid, 0)
        log.seek(0)
        said = log.read().decode("utf-8", "replace")
    if said:
        sys.stderr.write(said)
        sys.stderr.flush()
    if hung:
        return pickle.dumps(
            (
                False,
                CosimError(
                    f"timeout: the simulation did not end within {kill_after:g} s "
                    "(hung inside an FMU call); its fresh process was killed"
                ),
            )
        )
    if data and os.WIFEXITED(status):
        return data
    return pickle.dumps((False, _death(status, said)))


def _read_all(fd: int, seconds: float | None) -> tuple[bytes, bool]:
    """Everything written to ``fd`` until it closes; and whether ``seconds`` passed first (then what came)."""
    deadline = time.monotonic() + seconds if seconds else None
    chunks = []
    with os.fdopen(fd, "rb", buffering=0) as results:
        while True:
            if deadline is not None:
                left = deadline - time.monotonic()
                if left <= 0 or not select.select([results], [], [], left)[0]:
                    return b"".join(chunks), True
            chunk = results.read(1 << 16)
            if not chunk:
                return b"".join(chunks), False
            chunks.append(chunk)


def _child(function: Callable[..., Any], args: tuple, write_end: int) -> None:
    global _IN_CHILD
    _IN_CHILD = True
    try:
        reply: tuple[bool, Any] = (True, function(*args))
    except BaseException as e:  # noqa: BLE001  (the parent raises it)
        reply = (False, e)
    try:
        data = pickle.dumps(reply, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception as e:  # noqa: BLE001  (an exception or result that does not pickle)
        data = pickle.dumps((False, DseError(f"{type(reply[1]).__name__}: {reply[1]} ({e})")))
    with os.fdopen(write_end, "wb") as out:
        out.write(data)
    sys.stdout.flush()
    sys.stderr.flush()
    ctypes.CDLL(None).fflush(None)  # what the FMU printf'ed, before _exit skips the C library's flush
    os._exit(0)  # no atexit, no freeing: the FMU's library goes with the process


def _death(status: int, said: str) -> Exception:
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        try:
            how = f"was killed by {signal.Signals(number).name}"
        except ValueError:
            how = f"was killed by signal {number}"
    else:
        how = f"exited with code {os.WEXITSTATUS(status)}"
    last = next((line.strip() for line in reversed(said.splitlines()) if line.strip()), "")
    return CosimError(
        f"the fresh process running this simulation {how}: the FMU crashed" + (f" ({last})" if last else "")
    )


if __name__ == "__main__":  # run as a script, this is a copy of the module: serve from the real one
    from dse_runner.simulation import isolation  # noqa: PLW0406  (the module, not this script's copy)

    isolation._serve(sys.argv[1])
