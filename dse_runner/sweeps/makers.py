"""Cluster makers: what ``cluster.kind`` names, the way a sweep gets a Dask cluster started for it.

A maker is a subclass of :class:`ClusterMaker`. Four are built in: ``local``
(distributed's LocalCluster), ``slurm`` and ``htcondor`` (dask-jobqueue's
SLURMCluster and HTCondorCluster, in jobqueue.py) and ``kubernetes`` (the
dask-kubernetes operator's KubeCluster). A package adds
one as ``distributed``'s own deploy projects do, through an entry point::

    [project.entry-points."dse_runner.clusters"]
    mine = "my_package.deploy:MyMaker"   # a subclass of dse_runner.sweeps.makers.ClusterMaker

A maker may take a block of its own in the spec, named by its kind
(``cluster: {kind: mine, mine: {...}}``), declared as a pydantic model, its
``Options``: the block is validated with the spec. Connecting to a scheduler
someone else runs (``cluster.address``) needs no maker (cluster.py).
"""

from __future__ import annotations

import logging
import os
import uuid
from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import Any, ClassVar

from pydantic import (
    BaseModel,
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    ValidationError,
    model_validator,
)

from .. import plugins
from ..errors import DseError, did_you_mean
from ..schema import Extensible, Strict
from . import start_method

GROUP = "dse_runner.clusters"
QUEUE_WAIT = 30 * 60.0  # seconds a started cluster's first job or pod may wait in the queue


# ---- the spec's cluster block -------------------------------------------------------------------


class Tls(BaseModel):
    """Certificates for a TLS scheduler (distributed's Security); paths relative to the spec."""

    model_config = Strict
    ca_file: str  # the authority that signed the scheduler's and workers' certificates
    cert: str  # this client's certificate
    key: str  # its private key


class Cluster(BaseModel):
    """Where tasks run: ``address`` of an existing scheduler, or a cluster of ``kind`` started for the sweep.
    Keys besides these are cluster kinds' own blocks, each named by its kind (``htcondor: {cores: 4}``)
    and validated by that kind's maker (makers.py)."""

    model_config = Extensible
    kind: str = "local"  # local, slurm, htcondor, kubernetes, or a plug-in's (see makers.py)
    address: str | None = None  # tcp://host:8786 or tls://host:8786: use this scheduler, start nothing
    n_workers: PositiveInt | None = None  # workers to start; local default: the number of cores
    min_workers: NonNegativeInt | None = None  # with max_workers: Dask's adaptive scaling between the two,
    max_workers: PositiveInt | None = None  # workers (jobs) started as tasks wait and given back when idle
    threads_per_worker: PositiveInt = 1
    tls: Tls | None = None
    dashboard_address: str = "127.0.0.1:0"  # of a scheduler we start; loopback unless asked otherwise
    connect_timeout: PositiveFloat = 30.0  # seconds to reach a scheduler, or get it back after a restart; a
    # sweep whose local or addressed cluster has had no worker for twice this stops (cluster.worker_grace)

    @model_validator(mode="after")
    def _address_or_kind(self) -> Cluster:
        if self.address is not None and self.kind != "local":
            raise ValueError(
                f"give either 'address' (an existing scheduler) or 'kind: {self.kind}', not both"
            )
        if self.address is not None and not self.address.startswith(
            ("tcp://", "tls://", "ucx://", "inproc://")
        ):
            raise ValueError(f"address {self.address!r} needs a protocol: tcp://host:port or tls://host:port")
        return self

    @model_validator(mode="after")
    def _fixed_or_adaptive(self) -> Cluster:
        """A fixed ``n_workers``, or ``min_workers`` to ``max_workers`` for Dask's adapt: not both."""
        if self.min_workers is not None and self.max_workers is None:
            raise ValueError("min_workers needs max_workers (adaptive scaling between the two)")
        if self.max_workers is None:
            return self
        if self.n_workers is not None:
            raise ValueError(
                "give either n_workers (a fixed count) or min_workers/max_workers (adaptive), not both"
            )
        if self.address is not None:
            raise ValueError(
                "min_workers/max_workers scale a cluster dse-runner starts, not one at 'address'"
            )
        if (self.min_workers or 0) > self.max_workers:
            raise ValueError(
                f"min_workers ({self.min_workers}) is more than max_workers ({self.max_workers})"
            )
        return self

    @model_validator(mode="after")
    def _kind_blocks(self) -> Cluster:
        """Every block, and the chosen kind's even when absent (its required options), if installed here."""
        blocks = dict(self.model_extra or {})
        if self.address is None:
            blocks.setdefault(self.kind, None)
        for key, block in blocks.items():
            try:
                check_block(key, block, self.kind)
            except DseError as e:
                raise ValueError(str(e)) from None
        return self

    def block(self, kind: str) -> Any:
        """The block ``cluster.<kind>`` as written; None if the spec has none (the maker's defaults)."""
        return (self.model_extra or {}).get(kind)


# ---- the plug-in contract -----------------------------------------------------------------------


class NoOptions(BaseModel):
    """A maker's block when it declares none: it must be empty."""

    model_config = Strict


class ClusterMaker(ABC):
    """How a sweep starts a Dask cluster of one kind: the contract of ``cluster.kind`` and of the plug-ins
    in the entry-point group ``dse_runner.clusters``, which name a subclass (built with no arguments).

    Lifecycle (cluster.connect, on the client). When the space is read, the kind's own block
    ``cluster.<kind>`` is validated with ``Options`` (a plug-in that is not installed there is named when the
    sweep starts). When a sweep that names no ``address`` starts, :meth:`start` is called once with the spec,
    the validated block and distributed's Security (None without ``cluster.tls``), the terminal's Ctrl-C held
    off until it returns; it returns a ``distributed`` deploy cluster (what a ``distributed.Client`` connects
    to). Then :meth:`scale` is called once with ``cluster.n_workers`` (or :meth:`adapt` with ``min_workers``
    and ``max_workers``, when given), a client connects and waits up to ``first_worker_wait`` seconds for a
    first worker, and the sweep runs; :meth:`failure` is asked meanwhile, every 2 s, and a reason stops the
    sweep at once; a cluster that loses every worker mid-sweep gets as long to get one back (twice
    ``connect_timeout`` when it is 0). :meth:`close` is called once when the sweep ends, fails or is
    interrupted, after the client has cancelled its tasks.

    Optional parts, with defaults: ``Options`` (none: the block, if given, must be empty), :meth:`scale`
    (``cluster.scale(n_workers or 1)``: a batch system starts with no job), :meth:`adapt`
    (``cluster.adapt(minimum=, maximum=)``, Dask's adaptive scaling), :meth:`failure` (None), :meth:`close`
    (``cluster.close()``), ``first_worker_wait`` (30 minutes: a job may wait in its queue), ``settings``
    (none: Dask configuration held from before :meth:`start` until after :meth:`close`, for what
    distributed's objects read while the cluster runs, not only when it is built).
    """

    Options: ClassVar[type[BaseModel]] = NoOptions
    first_worker_wait: ClassVar[float] = QUEUE_WAIT
    settings: ClassVar[Mapping[str, Any]] = {}

    @abstractmethod
    def start(self, spec: Cluster, options: Any, security: Any) -> Any:
        """A started deploy cluster for ``spec``; ``options`` is the validated block (an ``Options``)."""

    def scale(self, cluster: Any, n_workers: int | None) -> None:
        cluster.scale(n_workers or 1)

    def adapt(self, cluster: Any, minimum: int, maximum: int) -> None:
        cluster.adapt(minimum=minimum, maximum=maximum)

    def failure(self, cluster: Any) -> str | None:
        """Why ``cluster`` cannot get workers any more (a batch system refused its job), or None. Without
        it a sweep would wait ``first_worker_wait`` for workers that cannot come."""
        return None

    def close(self, cluster: Any) -> None:
        cluster.close()

    def started(self, spec: Cluster, security: Any) -> Any:
        """:meth:`start` given the spec's own block for its kind, validated: what connect calls."""
        return self.start(spec, self.options(spec.block(spec.kind), spec.kind), security)

    def options(self, block: Any, kind: str) -> BaseModel:
        """The block ``cluster.<kind>`` validated; errors name the key within it."""
        try:
            return self.Options.model_validate({} if block is None else block)
        except ValidationError as e:
            problem = e.errors()[0]
            where = ".".join(str(p) for p in (kind, *problem["loc"]))
            raise DseError(
                f"{where}: {problem['msg'][:1].lower()}{problem['msg'][1:]} "
                f"(an option of cluster kind {kind})"
            ) from None


# ---- the built-in makers ------------------------------------------------------------------------

# Dask's own housekeeping, made less frequent on the clusters we start: an idle 2-worker local
# cluster then costs about 0.02 CPU-seconds per second instead of 0.15 (on 2 cores that is 7% of
# the machine a sweep or search could simulate with). Nothing a sweep relies on needs them faster:
# the profiler feeds Dask's profile page only, and our dashboard reads memory and CPU once a second.
QUIET = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.system-monitor.gil.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "1s",
    "distributed.worker.memory.monitor-interval": "1s",
}


class Local(ClusterMaker):
    """Worker processes on this machine, one thread each: FMUs are C code that may not be thread-safe, and
    one simulation per core keeps every core busy without contention."""

    first_worker_wait = 0.0  # its workers exist when it returns
    settings: ClassVar[Mapping[str, Any]] = {
        # A worker that died under a chunk gets one rerun elsewhere before the sweep splits the
        # chunk (sweep.py): a segfaulting FMU then costs two worker restarts per level, not four.
        "distributed.scheduler.allowed-failures": 1,
        **QUIET,
        # A worker process that dies is restarted by its nanny, here in the client's process. distributed
        # also closes, for good, the nanny of a worker that has not come back this long after a death,
        # judged at one instant: under an FMU that kills worker after worker (or a restart slower than
        # that on a loaded machine) the instant may fall between two lives of the same worker, and the
        # cluster lost the worker for the rest of the sweep.
        "distributed.deploy.lost-worker-timeout": "3650 days",
    }

    def start(self, spec: Cluster, options: Any, security: Any) -> Any:
        from distributed import LocalCluster

        start_method.choose()
        return LocalCluster(
            n_workers=(spec.min_workers or 0) if spec.max_workers else spec.n_workers or os.cpu_count() or 1,
            threads_per_worker=spec.threads_per_worker,
            processes=True,
            host="127.0.0.1",
            protocol="tls://" if security else None,
            security=security,
            dashboard_address=spec.dashboard_address,
            silence_logs=logging.ERROR,
        )

    def scale(self, cluster: Any, n_workers: int | None) -> None:
        """Nothing: it started with its workers."""


KUBERNETES_IDLE_TIMEOUT = 600  # seconds: the operator deletes a cluster its crashed client left behind


class KubernetesOptions(BaseModel):
    """``cluster.kubernetes``: the dask-kubernetes operator's KubeCluster, a DaskCluster resource in a
    namespace."""

    model_config = Strict
    image: str = "ghcr.io/dse-runner/dse-runner:latest"  # see deploy/Dockerfile
    namespace: str | None = None  # default: the current kube context's
    resources: dict[str, dict[str, str]] = {
        "requests": {"cpu": "1", "memory": "2Gi"},
        "limits": {"cpu": "1", "memory": "2Gi"},
    }
    env: dict[str, str] = {}


def kubernetes_cluster_spec(spec: Cluster, options: KubernetesOptions, name: str) -> dict[str, Any]:
    """The DaskCluster resource for the operator: our image, one single-threaded worker per pod."""
    from dask_kubernetes.operator import make_cluster_spec

    resource = make_cluster_spec(
        name=name,
        image=options.image,
        n_workers=0,
        resources=options.resources,
        env=dict(options.env),
        idle_timeout=KUBERNETES_IDLE_TIMEOUT,
        worker_command=["dask", "worker", "--nthreads", str(spec.threads_per_worker)],
    )
    # make_cluster_spec still starts the scheduler with `dask-scheduler`, a command distributed
    # removed in 2026.6; `dask scheduler` is the same program under its current name.
    (scheduler,) = resource["spec"]["scheduler"]["spec"]["containers"]
    scheduler["args"] = ["dask", "scheduler", *scheduler["args"][1:]]
    return resource


class Kubernetes(ClusterMaker):
    """A DaskCluster resource, served by the dask-kubernetes operator running in the cluster."""

    Options = KubernetesOptions

    def start(self, spec: Cluster, options: KubernetesOptions, security: Any) -> Any:
        try:
            from dask_kubernetes.operator import KubeCluster
        except ImportError:
            raise DseError(
                "cluster.kind kubernetes needs dask-kubernetes: pip install 'dse-runner[kubernetes]'"
            ) from None
        if security is not None:
            raise DseError(
                "cluster.tls: the dask-kubernetes operator does not set up TLS; keep the scheduler "
                "inside the cluster network and reach it by port-forward (deploy/kubernetes/README.md)"
            )
        name = f"dse-runner-{uuid.uuid4().hex[:8]}"  # two sweeps in one namespace get two clusters
        return KubeCluster(
            custom_cluster_spec=kubernetes_cluster_spec(spec, options, name), namespace=options.namespace
        )


# ---- finding a kind's maker: the built-in kinds are the group's entries too (pyproject.toml) ----


def installed() -> list[str]:
    """Every kind: the built-in ones and those installed packages declare."""
    return plugins.names(GROUP)


def find(kind: str) -> ClusterMaker | None:
    """The maker of ``kind``, or None if no installed package declares it."""
    entry = plugins.entries(GROUP).get(kind)
    return (
        None if entry is None else plugins.instance_of_subclass(entry, ClusterMaker, f"cluster.kind {kind!r}")
    )


def maker(kind: str) -> ClusterMaker:
    """The maker of ``kind``; an unknown kind is an error naming the known ones."""
    found = find(kind)
    if found is None:
        known = installed()
        raise DseError(
            f"cluster.kind {kind!r} is unknown{did_you_mean(kind, known)} (known: {', '.join(known)})"
        )
    return found


def check_block(key: str, block: Any, kind: str) -> None:
    """A key of ``cluster`` besides its own fields: a kind's block, valid for that kind's maker. A block
    for the chosen kind whose plug-in is not installed here passes: starting the sweep names the kind."""
    found = find(key)
    if found is None:
        if key == kind:
            return
        raise DseError(
            f"unknown key {key!r}: besides its own keys, cluster takes a block named by a cluster "
            f"kind (installed: {', '.join(installed())})"
        )
    found.options(block, key)
