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


# distributed keeps the last N messages each connection sent, for debugging; a sweep's
# messages carry chunks of tasks, so the default (1000) would hold a large sweep's tasks in
# the client. A short log keeps the client's memory flat.
MESSAGE_LOG_LENGTH = 20


@contextmanager
def connect(cluster: Cluster) -> Iterator["distributed.Client"]:  # noqa: F821
    import dask
    from distributed import Client, LocalCluster

    logging.getLogger("distributed").setLevel(logging.ERROR)
    with dask.config.set({"distributed.admin.low-level-log-length": MESSAGE_LOG_LENGTH}):
        with _client(cluster, Client, LocalCluster) as client:
            yield client


@contextmanager
def _client(cluster: Cluster, Client, LocalCluster) -> Iterator["distributed.Client"]:  # noqa: F821
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
