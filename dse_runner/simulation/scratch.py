"""Temporary folders a process keeps for its whole life: the FMUs it extracts, the shipments a worker
unpacks, the data files objective scripts read. Each is named for the process and removed when it exits; without that, every worker, client and
command left one behind (thousands in a day of sweeps). A process killed outright still leaves its own."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from functools import cache
from pathlib import Path


def own_folder(prefix: str) -> Path:
    """``<tmp>/<prefix><pid>``, made once per process (again if something cleared it) and removed at its exit."""
    folder = _folder(prefix, os.getpid())
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@cache
def _folder(prefix: str, pid: int) -> Path:
    folder = Path(tempfile.gettempdir()) / f"{prefix}{pid}"
    atexit.register(_remove, folder, pid)
    return folder


def _remove(folder: Path, owner: int) -> None:
    if os.getpid() == owner:  # a forked child inherits the registration, not the folder
        shutil.rmtree(folder, ignore_errors=True)
