"""A diagnosis runs its own linear algebra on one BLAS thread.

Why: a diagnosis solves thousands of small least-squares problems in its client process (STLSQ's fits in
discovery, the screens' bounded least squares, the look-alike fits), each a few thousand rows by tens of
columns. OpenBLAS splits each over every core, and its threads spin while they wait for each other: on a
2-core machine whose cores the cluster's workers keep busy, one such problem takes many times longer than
on one thread, and the spinning takes CPU the workers need (benchmarks/blas_threads.py). Dask's workers
already run with one thread each (distributed's nanny sets OPENBLAS_NUM_THREADS=1); this does the same for
the client while a diagnosis runs, and gives the caller's setting back after (threadpoolctl).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import ParamSpec, TypeVar

from threadpoolctl import threadpool_limits

BLAS_THREADS: int | None = 1  # None: leave the BLAS libraries as they are (the benchmark's "before")

P = ParamSpec("P")
R = TypeVar("R")


def one_thread(function: Callable[P, R]) -> Callable[P, R]:
    """``function`` run with every loaded BLAS library limited to BLAS_THREADS threads."""

    @functools.wraps(function)
    def run(*args: P.args, **kwargs: P.kwargs) -> R:
        with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
            return function(*args, **kwargs)

    return run
