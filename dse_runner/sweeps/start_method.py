"""How a local cluster starts its worker processes: spawned (Dask's default), or forked from a forkserver.

A spawned worker imports Dask, pandas, pyarrow, FMPy and dse-runner itself (about 1.5 CPU s each); a
forkserver imports them once and forks every worker from itself. A module of its own, with nothing heavy
to import, so that the command line can ask for it at start-up at no cost to commands that make no cluster.
"""

from __future__ import annotations

import os
import sys

# What every worker imports before its first task: the forkserver imports them once.
WORKER_IMPORTS = ("distributed", "pandas", "pyarrow.parquet", "fmpy.validation", f"{__package__}.sweep")
START_METHOD_VARIABLE = "DASK_DISTRIBUTED__WORKER__MULTIPROCESSING_METHOD"
_fork_workers = False


def fork_local_workers() -> None:
    """Have this process's local clusters fork their workers from a server that has imported
    WORKER_IMPORTS once, instead of spawning each worker to import them anew.

    For a process that makes one cluster and ends: the command line calls it. A forkserver keeps the
    environment variables of the moment it started, so a Python program that changes them between two
    clusters keeps Dask's own setting (spawn). The setting in the environment, when given, wins; elsewhere
    than on Linux nothing changes."""
    global _fork_workers
    _fork_workers = True


def choose() -> None:
    """Called as a local cluster starts: the forkserver, if asked for and the environment does not say
    otherwise. On Linux only: macOS's system libraries may start threads that a fork breaks (why Python
    spawns there)."""
    if not _fork_workers or START_METHOD_VARIABLE in os.environ or not sys.platform.startswith("linux"):
        return
    import dask
    from distributed.utils import get_mp_context

    dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"})  # read at each worker start
    get_mp_context().set_forkserver_preload(list(WORKER_IMPORTS))
