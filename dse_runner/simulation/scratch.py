"""Temporary folders a process keeps for its whole life: the FMUs it extracts, the shipments a worker
unpacks, the data files objective scripts read. Each is named for the process and removed when it exits;
without that, every worker, client and command left one behind (thousands in a day of sweeps).

A process that does not exit normally (killed, crashed, or ended by ``os._exit`` before multiprocessing's
finalizers ran, as an isolated FMU's child is) cannot remove its own. So each folder holds a lock file that
its process keeps locked (``flock``) while it lives; the kernel drops the lock however the process ends. The
next process that makes a folder of the same kind removes those whose lock it can take. Folders without a
lock file are left alone: one being made, or one from before locks."""

from __future__ import annotations

import fcntl
import os
import shutil
import tempfile
import threading
from functools import cache
from multiprocessing.util import Finalize
from pathlib import Path

OWNER = ".owner"  # the lock file, locked by the folder's process for its whole life
_HELD: dict[Path, int] = {}  # this process's folders -> the open lock file that holds the lock
_CLAIMING = (
    threading.Lock()
)  # a worker's threads extract FMUs at once; two claims of one folder would deadlock


def _unlock_in_child() -> None:
    """A child forked while another thread claimed a folder gets the lock as it
    was, held by no thread of its own."""
    global _CLAIMING
    _CLAIMING = threading.Lock()


os.register_at_fork(after_in_child=_unlock_in_child)


def own_folder(prefix: str) -> Path:
    """``<tmp>/<prefix><pid>``, made once per process (again if something
    cleared it) and removed at its exit."""
    with _CLAIMING:
        folder = _folder(prefix, os.getpid())
        if not (folder / OWNER).exists():
            _claim(folder)
    return folder


@cache
def _folder(prefix: str, pid: int) -> Path:
    sweep(prefix)
    folder = Path(tempfile.gettempdir()) / f"{prefix}{pid}"
    # a finalizer of multiprocessing's: run at exit, and by a multiprocessing child (a Dask worker) as it
    # ends, also one started by fork or forkserver, which then leaves by os._exit without exit hooks
    Finalize(None, _remove, (folder, pid), exitpriority=0)
    return folder


def _claim(folder: Path) -> None:
    """Make the folder and lock its lock file, locked before it has its name: no sweep sees it unlocked."""
    folder.mkdir(parents=True, exist_ok=True)
    partial = folder / f"{OWNER}.{os.getpid()}"
    held = os.open(partial, os.O_CREAT | os.O_WRONLY, 0o600)  # not inherited by commands it runs (PEP 446)
    fcntl.flock(held, fcntl.LOCK_EX)
    os.replace(partial, folder / OWNER)
    if folder in _HELD:
        os.close(_HELD[folder])
    _HELD[folder] = held


def sweep(prefix: str) -> int:
    """Remove the ``<prefix>*`` folders whose process has ended without removing its own; how many went."""
    removed = 0
    for folder in Path(tempfile.gettempdir()).glob(f"{prefix}*"):  # this process's own are locked too
        try:
            lock = os.open(folder / OWNER, os.O_RDONLY)
        except OSError:  # no lock file: being made, or older than locks
            continue
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)  # fails while its process lives
            # and the file locked is still the folder's: a new process of a reused pid would have replaced it
            ended = os.fstat(lock).st_ino == os.stat(folder / OWNER).st_ino
        except OSError:
            ended = False
        if ended:
            shutil.rmtree(folder, ignore_errors=True)
            removed += 1
        os.close(lock)
    return removed


def _remove(folder: Path, owner: int) -> None:
    if os.getpid() == owner:  # a forked child inherits the registration, not the folder
        shutil.rmtree(folder, ignore_errors=True)
