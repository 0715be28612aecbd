"""Where a sweep runs: an existing scheduler, or a cluster started for it.

``cluster.address`` connects to a scheduler someone else runs (``tcp://`` or
``tls://``). Otherwise ``cluster.kind`` names a *cluster maker* (makers.py:
``local``, ``slurm``, ``htcondor``, ``kubernetes`` built in, more through the
``dse_runner.clusters`` entry-point group), which starts a ``distributed``
deploy cluster here and closes it afterwards. Everything downstream sees
only a ``distributed.Client``, and asks :func:`failure_of` it whether its
cluster has failed for good (a batch system refused a job).

Schedulers we start bind their dashboards to 127.0.0.1 unless
``dashboard_address`` says otherwise, and the links printed name the host
the dashboard listens on (:func:`dashboard_link_template`).
"""

from __future__ import annotations

import functools
import logging
import signal
import threading
import time
import weakref
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

from ..errors import DseError
from .makers import Cluster, maker

if TYPE_CHECKING:  # distributed is imported when a sweep connects, not when the CLI starts
    import distributed

# distributed keeps the last N messages each connection sent, for debugging; a sweep's
# messages carry chunks of tasks, so the default (1000) would hold a large sweep's tasks in
# the client. A short log keeps the client's memory flat.
MESSAGE_LOG_LENGTH = 20

# Each client of a cluster we started -> its maker's failure check (makers.ClusterMaker.failure)
_FAILURES: weakref.WeakKeyDictionary[Any, Callable[[], str | None]] = weakref.WeakKeyDictionary()


def failure_of(client: Any) -> str | None:
    """Why the cluster behind ``client`` cannot get workers any more, or None
    (also for one we did not start)."""
    check = _FAILURES.get(client)
    return check() if check else None


def dashboard_link_template(dashboard_address: str) -> str | None:
    """distributed's dashboard link naming the host the dashboard listens on, when that is one host.

    distributed names the scheduler's host in the link; a batch cluster's scheduler listens on the
    machine's network address, so the link said e.g. 192.0.2.2 while the dashboard listened on 127.0.0.1
    only. None when it listens on every interface (``0.0.0.0``, ``:8787``): distributed's link is right."""
    host = dashboard_address.rsplit(":", 1)[0] if ":" in dashboard_address else dashboard_address
    if host.isdigit():  # a bare port: every interface
        host = ""
    if host in ("", "0.0.0.0", "[::]", "::"):
        return None
    return f"{{scheme}}://{host}:{{port}}/status"


def security(spec: Cluster, base: Path | None = None) -> Any:
    """distributed's Security for the spec's TLS section, or None; certificate paths are checked here."""
    if spec.tls is None:
        return None
    from distributed.security import Security

    files = {}
    for name in ("ca_file", "cert", "key"):
        path = Path(getattr(spec.tls, name))
        path = path if path.is_absolute() or base is None else base / path
        if not path.is_file():
            raise DseError(f"cluster.tls.{name}: no file {path}")
        files[name] = str(path)
    return Security(
        tls_ca_file=files["ca_file"],
        tls_client_cert=files["cert"],
        tls_client_key=files["key"],
        tls_scheduler_cert=files["cert"],
        tls_scheduler_key=files["key"],
        tls_worker_cert=files["cert"],
        tls_worker_key=files["key"],
        require_encryption=True,
    )


@contextmanager
def connect(spec: Cluster, base: Path | None = None) -> Iterator[distributed.Client]:
    """A client of the spec's scheduler, with at least one worker; the cluster is closed afterwards
    if we started it. ``base`` is the folder relative certificate paths start from."""
    import dask

    logging.getLogger("distributed").setLevel(logging.ERROR)
    sec = security(spec, base)
    settings: dict[str, Any] = {"distributed.admin.low-level-log-length": MESSAGE_LOG_LENGTH}
    link = None if spec.address else dashboard_link_template(spec.dashboard_address)
    if link:
        settings["distributed.dashboard.link"] = link
    chosen = None if spec.address else maker(spec.kind)
    if chosen is not None:
        settings.update(chosen.settings)  # held until the cluster is closed
    with dask.config.set(settings), quiet_once_interrupted():
        if chosen is None:
            with _client(spec.address, sec, spec.connect_timeout, wait=spec.connect_timeout) as client:
                yield client
            return
        cluster = None
        try:
            with sigint_held():  # a Ctrl-C meanwhile is raised once the cluster exists, and it is closed
                cluster = chosen.started(spec, sec)
            if spec.max_workers is not None:
                chosen.adapt(cluster, spec.min_workers or 0, spec.max_workers)
            else:
                chosen.scale(cluster, spec.n_workers)
            failure = functools.partial(chosen.failure, cluster)
            # adapting from no worker, the cluster starts one only once a task waits: the sweep's first
            wait = 0.0 if spec.max_workers is not None and not spec.min_workers else chosen.first_worker_wait
            with _client(cluster, sec, spec.connect_timeout, wait, failure) as client:
                _FAILURES[client] = failure
                try:
                    yield client
                finally:
                    _FAILURES.pop(client, None)
                    settle(client)
        finally:
            if cluster is not None:
                chosen.close(cluster)


@contextmanager
def sigint_held() -> Iterator[None]:
    """Start a cluster whose processes never see the terminal's Ctrl-C, and keep a Ctrl-C that comes
    meanwhile until the cluster exists.

    A terminal sends SIGINT to its whole foreground process group, so the worker processes a
    LocalCluster spawns get the user's Ctrl-C as well, and distributed leaves them to die of it
    mid-chunk with a KeyboardInterrupt traceback each (dask/distributed#1925). A signal blocked in a
    thread stays blocked in the threads it starts and, through fork and exec, in the processes they
    spawn; the cluster's event-loop thread, started here, spawns every worker process (also those a
    nanny restarts later) from threads of its own, or the forkserver that forks them (makers.py). So
    only the client takes the Ctrl-C, and it stops the workers by closing the cluster. Python runs
    signal handlers in the main thread only, hence the check: elsewhere nothing is changed."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    from multiprocessing import resource_tracker

    # The standard library starts its resource tracker the same way, and then unblocks SIGINT in the
    # thread that started it: the cluster's event loop, were the tracker not running before.
    resource_tracker.ensure_running()
    previous = signal.getsignal(signal.SIGINT)
    caught: list[int] = []
    if callable(previous):
        signal.signal(signal.SIGINT, lambda number, frame: caught.append(number))
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # one that waited is recorded now
        if callable(previous):
            signal.signal(signal.SIGINT, previous)
    if caught:
        previous(signal.SIGINT, None)  # handled as it would have been when it came


NOISY_AFTER_CTRL_C = ("tornado.application", "asyncio")  # loggers of the event loop Dask runs in the client


@contextmanager
def quiet_once_interrupted() -> Iterator[None]:
    """From the first Ctrl-C on, the loggers of Dask's event loop in this process say nothing.

    Ctrl-C raises KeyboardInterrupt in the client wherever it is, inside distributed's waits too. What
    a wait leaves behind then fails in the event loop, and tornado and asyncio log each failure with
    its traceback, some only as Python exits: the tasks of a gather, or a wait that distributed's
    ``sync`` cancels before it has started, which fails with a NameError. Until a Ctrl-C they speak as
    before, and afterwards, if none came."""
    previous = signal.getsignal(signal.SIGINT)
    if threading.current_thread() is not threading.main_thread() or not callable(previous):
        yield
        return
    interrupted = threading.Event()

    def mark(number: int, frame: Any) -> None:
        interrupted.set()
        previous(number, frame)

    def keep(record: logging.LogRecord) -> bool:
        return not interrupted.is_set()

    loggers = [logging.getLogger(name) for name in NOISY_AFTER_CTRL_C]
    for logger in loggers:
        logger.addFilter(keep)
    signal.signal(signal.SIGINT, mark)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if not interrupted.is_set():  # after a Ctrl-C they stay quiet: some failures are logged at exit
            for logger in loggers:
                logger.removeFilter(keep)


@contextmanager
def _client(
    target: Any, sec: Any, timeout: float, wait: float, failure: Callable[[], str | None] = lambda: None
) -> Iterator[Any]:
    """A connected client, after waiting up to ``wait`` seconds for the first worker; a ``failure`` (a
    refused job) meanwhile ends the wait at once."""
    from distributed import Client

    where = target if isinstance(target, str) else type(target).__name__
    try:
        client = Client(target, security=sec, timeout=f"{timeout}s")
    except (OSError, TimeoutError, TypeError) as e:  # TypeError: distributed's word for "tls:// without TLS"
        hint = (
            " (a tls:// scheduler needs cluster.tls)"
            if str(target).startswith("tls://") and sec is None
            else ""
        )
        raise DseError(f"cannot reach the Dask scheduler at {where}{hint}: {e}") from None
    try:
        if wait:
            _first_worker(client, wait, failure)
        yield client
    finally:
        client.close()


def _first_worker(client: Any, wait: float, failure: Callable[[], str | None]) -> None:
    """Until a worker joins; a failure, or ``wait`` seconds without one, is an error."""
    deadline = time.monotonic() + wait
    while True:
        problem = failure()
        if problem:
            raise DseError(problem)
        try:
            client.wait_for_workers(1, timeout=min(WorkerWatch.EVERY, max(0.1, deadline - time.monotonic())))
            return
        except TimeoutError:
            if time.monotonic() >= deadline:
                raise DseError(
                    f"no worker joined the scheduler at {client.scheduler.address} within {wait:g} s "
                    "(for Slurm, HTCondor or Kubernetes: are the jobs or pods queued? squeue, condor_q, "
                    "kubectl get pods)"
                ) from None


def worker_grace(spec: Cluster) -> float:
    """How long a sweep waits, mid-run, for a cluster that has lost every worker to get one back: a
    batch system's job may wait in its queue as long as a first one (its maker's ``first_worker_wait``);
    elsewhere a supervisor or a nanny restarts a worker in seconds, so twice the connect timeout is ample."""
    wait = 0.0 if spec.address else maker(spec.kind).first_worker_wait
    return wait or 2 * spec.connect_timeout


class WorkerWatch:
    """Watches, beside a running sweep, that its cluster still has a worker. When it has had none for
    ``grace`` seconds (killed, and none restarted), or its cluster has failed for good (:func:`failure_of`:
    a batch system refused a job), it says why in ``stranded`` and cancels the chunks in flight, which ends
    the sweep's wait; without it the sweep would wait for ever. Finished chunks are in the store already."""

    EVERY = 2.0  # seconds between looks: a call to the scheduler each time

    def __init__(self, client: Any, grace: float, in_flight: Callable[[], list[Any]]):
        self.client, self.grace, self.in_flight = client, grace, in_flight
        self.stranded: str | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="dse-runner worker watch", daemon=True)

    def __enter__(self) -> Self:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=self.EVERY)  # a look under way on a lost scheduler need not be waited for

    def _watch(self) -> None:
        alone_since: float | None = None
        while not self._stop.wait(self.EVERY):
            problem = failure_of(self.client)
            if problem:
                self.stranded = problem
                self.client.cancel(self.in_flight())
                return
            try:
                workers = len(
                    self.client.scheduler_info(n_workers=1)["workers"]
                )  # is there one? no more asked
            except Exception:  # noqa: BLE001  (the scheduler itself went: the sweep's reconnection deals with it)
                alone_since = None
                continue
            if self._stop.is_set():
                return
            if workers:
                alone_since = None
                continue
            alone_since = alone_since or time.monotonic()
            if time.monotonic() - alone_since >= self.grace:
                self.stranded = (
                    f"the Dask scheduler at {self.client.scheduler.address} has had no worker for "
                    f"{self.grace:g} s: its workers died or were lost and none came back"
                )
                self.client.cancel(self.in_flight())
                return


def wait_until_ended(client, keys: Collection[str] | None = None, every: float = 0.1) -> None:
    """Until no worker runs a task of ``keys`` (None: any task). Dask cannot stop a task that has started:
    a chunk cancelled while it runs goes on to write its rows, and the store holds its final rows only
    after that."""
    wanted = None if keys is None else frozenset(keys)

    def running(dask_worker) -> list[str]:
        return [key for key in list(dask_worker.active_threads.values()) if wanted is None or key in wanted]

    while wanted is None or wanted:
        try:
            if not any(client.run(running, on_error="ignore").values()):
                return
        except OSError:  # the scheduler went: nothing more can be learnt from it
            return
        time.sleep(every)


def settle(client) -> None:
    """Cancel what the client still has on a cluster we started, and wait until no worker runs a task, so
    that the cluster then closes at once and quietly (after Ctrl-C, say, while the first simulation is
    timed). A worker closed while it runs a task waits for it, heartbeating to a scheduler that has let
    it go already, and distributed logs each failed heartbeat as an error with its traceback."""
    from distributed import Future

    if client.status != "running":
        return
    try:
        client.cancel([Future(key, client) for key in list(client.futures)])
        wait_until_ended(client)
        client.run(_closing, on_error="ignore")
    except Exception:  # noqa: BLE001  (at worst the close is noisy: this must not hide why the sweep stopped)
        return


def _closing() -> None:
    """In each worker of a cluster about to be closed, idle: distributed's log says nothing more. On a busy
    machine a worker can still miss the scheduler's goodbye and log a failed heartbeat with its traceback."""
    logging.getLogger("distributed").setLevel(logging.CRITICAL)


def total_threads(client) -> int:
    return sum(w["nthreads"] for w in client.scheduler_info()["workers"].values()) or 1
