"""Where a sweep runs: the embedded local Dask cluster, or an existing scheduler.

The local cluster's workers are separate processes with one thread each:
FMUs are C code that may not be thread-safe, and one simulation per core is
what keeps both cores busy without contention.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager

from .errors import DseError
from .spec import Cluster


@contextmanager
def connect(cluster: Cluster) -> Iterator["distributed.Client"]:  # noqa: F821
    from distributed import Client, LocalCluster

    logging.getLogger("distributed").setLevel(logging.ERROR)
    if cluster.address:
        try:
            client = Client(cluster.address, timeout="20s")
        except OSError as e:
            raise DseError(f"cannot reach the Dask scheduler at {cluster.address}: {e}") from None
        try:
            yield client
        finally:
            client.close()
        return
    local = LocalCluster(
        n_workers=cluster.n_workers or os.cpu_count() or 1,
        threads_per_worker=cluster.threads_per_worker,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
        silence_logs=logging.ERROR,
    )
    client = Client(local)
    try:
        yield client
    finally:
        client.close()
        local.close()


def total_threads(client) -> int:
    return sum(w["nthreads"] for w in client.scheduler_info()["workers"].values()) or 1
