"""Worker jobs on a batch system through dask-jobqueue: what the ``slurm`` and ``htcondor`` kinds share.

dask-jobqueue writes the job script and submits one job per ``cores`` workers; Dask's SpecCluster
then keeps the count. Left alone, that misses two things a sweep needs:

- **A refused job is only logged.** sbatch's or condor_submit's error is raised inside the cluster's
  event loop, where tornado logs it, and the sweep waits out its queue timeout for workers that will
  never come. Here each job class is wrapped (:func:`refusable`) so that a refused submission is kept
  with the batch system's own words, and :meth:`JobQueueMaker.failure` hands them to the sweep, which
  stops at once.
- **An ended job is not replaced.** When a job is cancelled, reaches its walltime or loses its node,
  its workers leave the scheduler, but the cluster still counts the job. :class:`JobKeeper` notices
  that a job's workers came and went, and lets SpecCluster submit a new job in its place.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import shutil
import time
from abc import abstractmethod
from importlib import import_module
from typing import Any, ClassVar

from pydantic import BaseModel, PositiveInt

from ..errors import DseError
from ..schema import Strict
from .makers import Cluster, ClusterMaker

log = logging.getLogger(__name__)

KEEP_EVERY = 1.0  # seconds between the keeper's looks at the cluster's jobs


def refusal(error: BaseException, command: str) -> str:
    """One line from a failed submission: the batch system's stderr (dask-jobqueue's RuntimeError carries
    it after ``stderr:``), else the error itself."""
    text = str(error)
    if isinstance(error, FileNotFoundError):
        return f"{command} not found on PATH"
    stderr = text.split("stderr:", 1)[1] if "stderr:" in text else text
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    prefix = f"{command}: error: "
    return "; ".join(line.removeprefix(prefix) for line in lines) or text.strip()


@functools.cache
def refusable(job_cls: type) -> type:
    """``job_cls`` whose failed submission is kept in ``refused`` instead of raised into the event loop,
    where it would only be logged. The job then counts as started, without a job id: closing it cancels
    nothing, and the maker's :meth:`~JobQueueMaker.failure` reports it."""

    class Refusable(job_cls):
        refused: str | None = None

        async def start(self) -> None:
            try:
                await super().start()
            except (RuntimeError, OSError) as e:
                from distributed.deploy.spec import ProcessInterface

                self.refused = refusal(e, self.submit_command.split()[0])
                self.job_id = None
                await ProcessInterface.start(self)  # marks it started; submits nothing

    Refusable.__name__ = Refusable.__qualname__ = f"Refusable{job_cls.__name__}"
    return Refusable


class JobKeeper:
    """Keeps a dask-jobqueue cluster at the jobs it was asked for: a job whose workers joined the scheduler
    and then all left for ``lost_after`` seconds ended on the batch system, and another is submitted in its
    place. Runs on the cluster's event loop."""

    def __init__(self, cluster: Any, lost_after: float):
        from tornado.ioloop import PeriodicCallback

        self.cluster, self.lost_after = cluster, lost_after
        self.joined: set[str] = set()  # jobs whose workers have been seen on the scheduler
        self.absent: dict[str, float] = {}  # such jobs with no worker now: since when (monotonic)
        self.replaced = 0
        self.closing: set[asyncio.Future] = (
            set()
        )  # ended jobs being cancelled: held, so none is collected mid-way
        self._busy = False
        self._callback = PeriodicCallback(self._tick, KEEP_EVERY * 1000)
        cluster.loop.add_callback(self._callback.start)

    def stop(self) -> None:
        self.cluster.loop.add_callback(self._callback.stop)

    @staticmethod
    async def _close(job: Any) -> None:
        """Cancel an ended job's remains; a batch command that fails or is missing is only logged."""
        try:
            await job.close()
        except (RuntimeError, OSError) as e:
            log.warning("could not cancel ended job %s: %s", getattr(job, "job_id", "?"), e)

    def refused(self) -> str | None:
        """The batch system's words for the first job it refused, if any."""
        for job in list(self.cluster.workers.values()):
            if getattr(job, "refused", None):
                return job.refused
        return None

    async def _tick(self) -> None:
        if self._busy or self.cluster.status.name in ("closing", "closed"):
            return
        self._busy = True
        try:
            self._forget_ended_jobs()
            if set(self.cluster.worker_spec) - set(self.cluster.workers) and not self.refused():
                await self.cluster._correct_state()  # submits the jobs SpecCluster is missing
        except Exception:
            log.exception("dse-runner's job keeper")
        finally:
            self._busy = False

    def _forget_ended_jobs(self) -> None:
        """Drop (and cancel, should it linger) each wanted job whose workers have all been gone for
        ``lost_after`` seconds: SpecCluster then sees a job missing and submits a new one."""
        present = {str(w.get("name")) for w in self.cluster.scheduler_info.get("workers", {}).values()}
        now = time.monotonic()
        for name, job in list(self.cluster.workers.items()):
            if any(
                worker == name or worker.startswith(f"{name}-") for worker in present
            ):  # groups: name-0, …
                self.joined.add(name)
                self.absent.pop(name, None)
                continue
            if name not in self.joined or name not in self.cluster.worker_spec:  # queued, or being retired
                continue
            since = self.absent.setdefault(name, now)
            if now - since >= self.lost_after:
                del self.cluster.workers[name]
                self.joined.discard(name)
                self.absent.pop(name, None)
                self.replaced += 1
                closing = asyncio.ensure_future(
                    self._close(job)
                )  # scancel / condor_rm: harmless if it has ended
                self.closing.add(closing)
                closing.add_done_callback(self.closing.discard)
                log.warning("worker job %s (%s) ended; submitting another", name, job.job_id)


class JobQueueMaker(ClusterMaker):
    """A cluster kind whose workers are batch jobs submitted by dask-jobqueue; the scheduler runs here, in
    the client's process. Subclasses name the system and build its cluster class's arguments."""

    system: ClassVar[str]  # the batch system's name, for messages
    extra: ClassVar[str]  # the pip extra that installs dask-jobqueue for this kind
    cluster_name: ClassVar[str]  # dask-jobqueue's cluster class for this system, imported when a sweep starts

    def __init__(self) -> None:
        self._keepers: dict[int, JobKeeper] = {}

    @abstractmethod
    def arguments(self, spec: Cluster, options: Any) -> dict[str, Any]:
        """The cluster class's job arguments from the kind's validated block."""

    def start(self, spec: Cluster, options: Any, security: Any) -> Any:
        try:
            cls = getattr(import_module("dask_jobqueue"), self.cluster_name)
        except ImportError:
            raise DseError(
                f"cluster.kind {spec.kind} needs dask-jobqueue: pip install 'dse-runner[{self.extra}]'"
            ) from None
        import dask

        lost_after = dask.config.get("distributed.deploy.lost-worker-timeout")
        cluster = cls(
            job_cls=refusable(cls.job_cls),
            security=security,
            protocol="tls://" if security else None,
            scheduler_options={"dashboard_address": spec.dashboard_address},
            silence_logs="error",
            **self.arguments(spec, options),
        )
        from dask.utils import parse_timedelta

        self._keepers[id(cluster)] = JobKeeper(cluster, parse_timedelta(lost_after))
        return cluster

    def scale(self, cluster: Any, n_workers: int | None) -> None:
        self._can_submit(cluster)
        cluster.scale(n_workers or 1)

    def adapt(self, cluster: Any, minimum: int, maximum: int) -> None:
        self._can_submit(cluster)
        cluster.adapt(minimum=minimum, maximum=maximum)

    def _can_submit(self, cluster: Any) -> None:
        """The submit command is on PATH: else every job would fail the same way, one by one, in the event
        loop. Checked before the first job, not in start: a cluster built without one still shows its job
        script (``cluster.job_script()``)."""
        command = cluster.job_cls.submit_command.split()[0]
        if shutil.which(command) is None:
            raise DseError(
                f"cluster.kind {self.system.lower()}: {command} is not on PATH: run dse-runner where "
                f"{self.system}'s commands are (a login or submit node), or install them"
            )

    def failure(self, cluster: Any) -> str | None:
        keeper = self._keepers.get(id(cluster))
        reason = keeper.refused() if keeper else None
        return f"{self.system} refused a worker job: {reason}" if reason else None

    def replaced(self, cluster: Any) -> int:
        """How many ended jobs have been replaced so far."""
        keeper = self._keepers.get(id(cluster))
        return keeper.replaced if keeper else 0

    def close(self, cluster: Any) -> None:
        keeper = self._keepers.pop(id(cluster), None)
        if keeper is not None:
            keeper.stop()
        cluster.close()


# ---- the kinds ----------------------------------------------------------------------------------


class SlurmOptions(BaseModel):
    """``cluster.slurm``: dask-jobqueue's SLURMCluster, one ``sbatch`` job per ``cores`` single-threaded
    workers. The names and meanings are dask-jobqueue's; None leaves an option to its defaults (and to
    the site's ``jobqueue.slurm`` Dask config)."""

    model_config = Strict
    queue: str | None = None  # the partition (sbatch -p); default: the site's default partition
    account: str | None = None  # sbatch -A
    cores: PositiveInt = 1  # per job; each core runs one single-threaded worker process
    memory: str = "2GiB"  # per job (sbatch --mem), split evenly between its workers
    walltime: str | None = None  # sbatch -t, e.g. "04:00:00"; dask-jobqueue's default is 00:30:00
    job_extra_directives: list[str] = []  # more #SBATCH lines, e.g. ["--qos=short", "--constraint=avx2"]
    job_script_prologue: list[
        str
    ] = []  # shell lines before the worker starts, e.g. activating an environment
    python: str | None = None  # the worker's Python on the compute nodes; default: this one's path
    interface: str | None = None  # network interface the scheduler and workers use, e.g. ib0
    log_directory: str | None = None  # the jobs' stdout and stderr files; default: sbatch's (where you run)


class Slurm(JobQueueMaker):
    """One Slurm job per ``slurm.cores`` single-threaded workers; the scheduler runs here (a login node)."""

    Options = SlurmOptions
    system, extra, cluster_name = "Slurm", "slurm", "SLURMCluster"

    def arguments(self, spec: Cluster, options: SlurmOptions) -> dict[str, Any]:
        return {
            "cores": options.cores,
            "processes": options.cores,
            "memory": options.memory,
            "queue": options.queue,
            "account": options.account,
            "walltime": options.walltime,
            "job_extra_directives": list(options.job_extra_directives),
            "job_script_prologue": list(options.job_script_prologue),
            "python": options.python,
            "interface": options.interface,
            "log_directory": options.log_directory,
        }


class HTCondorOptions(BaseModel):
    """``cluster.htcondor``: dask-jobqueue's HTCondorCluster, one HTCondor job per ``cores`` workers."""

    model_config = Strict
    cores: PositiveInt = 1  # per job; each core runs one single-threaded worker process
    memory: str = "2GiB"  # per job
    disk: str = "1GiB"  # per job: extracted FMUs and scenario files, a few MB
    job_extra: dict[str, str] = {}  # extra submit-description lines, e.g. {"+ProjectName": '"robotti"'}
    prologue: list[str] = []  # shell lines before the worker starts, e.g. activating an environment
    python: str | None = None  # the worker's Python on the execute nodes; default: this one
    interface: str | None = None  # network interface the scheduler listens on, e.g. eth0


class HTCondor(JobQueueMaker):
    """One HTCondor job per ``htcondor.cores`` single-threaded workers; the scheduler runs here."""

    Options = HTCondorOptions
    system, extra, cluster_name = "HTCondor", "htcondor", "HTCondorCluster"

    def arguments(self, spec: Cluster, options: HTCondorOptions) -> dict[str, Any]:
        return {
            "cores": options.cores,
            "processes": options.cores,
            "memory": options.memory,
            "disk": options.disk,
            "job_extra_directives": dict(options.job_extra),
            "job_script_prologue": list(options.prologue),
            "python": options.python,
            "interface": options.interface,
        }
