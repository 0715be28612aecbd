"""Sweeps on real clusters, and what happens when parts of them die.

Each test starts its own `dask scheduler` / `dask worker` processes through
their command lines (tests/support/cluster.py) unless it needs the embedded cluster.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from urllib.parse import urlparse

import pandas as pd
import pytest
import yaml
from conftest import FMU_SOURCES, MULTIMODEL, REPO, SCENARIOS, sleeper_multimodel, strict_loads, write_space
from support.cluster import CliCluster, can_hide_folders, make_certs

import dse_runner
from dse_runner.errors import DseError
from dse_runner.sweeps import store
from dse_runner.sweeps.cluster import connect
from dse_runner.sweeps.jobqueue import HTCondor
from dse_runner.sweeps.makers import Cluster, KubernetesOptions, kubernetes_cluster_spec
from dse_runner.sweeps.rank import rank
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import load_status, submit

# 2 points x 12 scenarios at a tenth of the default integration step (~0.1-0.3 s a task, 2 tasks a chunk):
# a dozen chunks, so that a kill after the first few lands mid-sweep however busy the machine is.
SLOW = {"vehicle.mass": [1000, 3000], "vehicle.rk4_step": [0.0001]}
SLOW_TASKS = 2 * 12


def raw_task_ids(output: Path) -> pd.Series:
    """Every task id in every result file, without the readers' de-duplication."""
    files = list((output / "results").rglob("part-*.parquet"))
    return pd.concat(pd.read_parquet(f, columns=["task_id"]) for f in files)["task_id"]


def reachable(host: str, port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(2)
        return s.connect_ex((host, port)) == 0


def wait_for_files(output: Path, n: int, timeout: float = 120) -> None:
    deadline = time.time() + timeout
    while len(list((output / "results").rglob("part-*.parquet"))) < n:
        assert time.time() < deadline, f"fewer than {n} result files after {timeout} s"
        time.sleep(0.05)


@pytest.fixture
def cli_cluster(tmp_path):
    clusters: list[CliCluster] = []

    def start(**options) -> CliCluster:
        folder = tmp_path / f"dask-{len(clusters)}"
        folder.mkdir()
        clusters.append(CliCluster(folder, **options))
        return clusters[-1]

    yield start
    for cluster in clusters:
        cluster.close()


@pytest.mark.skipif(not can_hide_folders(), reason="needs mount namespaces (unshare -m as root)")
def test_workers_need_no_shared_file_system(tmp_path, cli_cluster, fresh_fmu_cache):
    """Workers that cannot see the spec, the FMU sources, the built FMUs or the recordings still run
    the sweep: everything they need arrives through Dask."""
    hidden = (SCENARIOS, FMU_SOURCES, fresh_fmu_cache, MULTIMODEL.parent)
    cluster = cli_cluster(hide=hidden)
    with cluster.client() as client:
        sees = client.run(lambda: [os.path.exists(p) and bool(os.listdir(p)) for p in map(str, hidden)])
    assert all(not any(seen) for seen in sees.values()), sees  # the workers really see nothing there
    space = load_space(write_space(tmp_path, cluster={"address": cluster.address}))
    report = submit(space)
    assert (report.ok, report.failed) == (12, 0), report.errors
    assert len(store.read_results(space.output, "small", columns=[])) == 12
    assert all(store.has_trajectory(space.output, "small", s.name, 1) for s in space.scenarios)


@pytest.mark.skipif(not can_hide_folders(), reason="needs mount namespaces (unshare -m as root)")
@pytest.mark.skipif(
    not Path(dse_runner.__file__).is_relative_to(REPO), reason="dse_runner is installed, not this folder"
)
def test_workers_without_dse_runner_are_named_as_the_cause(tmp_path, cli_cluster):
    """A scheduler whose workers lack the package: one clear line at once, and the sweep marked failed."""
    cluster = cli_cluster(workers=1, hide=(Path(dse_runner.__file__).parent,))
    space = load_space(write_space(tmp_path, cluster={"address": cluster.address}))
    with pytest.raises(
        DseError,
        match=rf"^the Dask workers of {re.escape(cluster.address)} cannot import "
        r"dse_runner \(.*No module named 'dse_runner'.*\): install dse-runner",
    ):
        submit(space)
    assert load_status(space.output, "small").state == "failed"


def test_sigkilled_worker_loses_no_task_and_repeats_none(tmp_path, cli_cluster):
    cluster = cli_cluster()
    space = load_space(
        write_space(
            tmp_path,
            scenarios=[str(SCENARIOS / "*")],
            parameters=SLOW,
            chunk_seconds=0.5,
            keep_trajectories=0,
            cluster={"address": cluster.address},
        )
    )
    killed: list[str] = []
    with cluster.client() as client:

        def kill_a_busy_worker(report) -> None:
            if killed or report.chunks < 1:
                return
            busy = [w for w, keys in client.processing().items() if keys]
            if busy:
                pid = client.run(os.getpid, workers=busy[:1])[busy[0]]
                os.kill(pid, signal.SIGKILL)  # mid-chunk: the chunk's file is never written
                killed.append(busy[0])

        report = submit(space, progress=kill_a_busy_worker, client=client)
        assert killed and killed[0] not in client.scheduler_info()["workers"]
    assert (report.ok, report.failed) == (SLOW_TASKS, 0), report.errors
    ids = raw_task_ids(space.output)
    assert len(ids) == SLOW_TASKS and ids.is_unique  # each task exactly once on disk


def test_a_sweep_whose_workers_all_die_stops_with_its_finished_rows(tmp_path, cli_cluster):
    """Every worker killed with its nanny, none restarted: the sweep says so and stops (it used to wait for
    ever), keeps the rows of finished chunks, and a resubmission on new workers runs only the rest."""
    cluster = cli_cluster()
    spec = write_space(
        tmp_path,
        scenarios=[str(SCENARIOS / "*")],
        parameters=SLOW,
        chunk_seconds=0.5,
        keep_trajectories=0,
        cluster={"address": cluster.address, "connect_timeout": 2},
    )
    space = load_space(spec)

    def kill_every_worker(report) -> None:
        if report.chunks >= 1 and cluster.workers:
            cluster.kill_workers()

    started = time.monotonic()
    with pytest.raises(DseError, match=r"has had no worker for 4 s.*every finished chunk is in"):
        submit(space, progress=kill_every_worker)
    assert time.monotonic() - started < 120
    kept = raw_task_ids(space.output)
    assert 0 < len(kept) < SLOW_TASKS and kept.is_unique
    cluster.start_worker()
    cluster.wait_for_workers(
        1
    )  # the spec gives a worker 2 s to join: a slow machine takes longer to start one
    report = submit(load_space(spec))
    assert (report.skipped, report.ok + report.skipped) == (len(kept), SLOW_TASKS)


def test_a_sweep_whose_workers_all_die_while_it_probes_stops(tmp_path, cli_cluster):
    """The first simulation, timed to size the chunks, runs before any chunk: every worker killed while it
    runs (none restarted) stops the sweep with the same words, instead of waiting for the probe for ever."""
    from distributed import Client

    cluster = cli_cluster()
    # sin1 is 1680 steps: at 5 ms of sleep a step, one simulation takes 8 s, and the probe runs two
    spec = write_space(
        tmp_path,
        multimodel=str(sleeper_multimodel(tmp_path)),
        scenarios=[str(SCENARIOS / "sin1")],
        parameters={"sleeper.pause": [0.005]},
        keep_trajectories=0,
        cluster={"address": cluster.address, "connect_timeout": 2},
    )

    def kill_when_probing() -> None:
        with Client(cluster.address, timeout="30s") as client:
            deadline = time.monotonic() + 120
            while not any(k.startswith("probe") for keys in client.processing().values() for k in keys):
                assert time.monotonic() < deadline, "the probe never started"
                time.sleep(0.1)
        cluster.kill_workers()

    killer = threading.Thread(target=kill_when_probing, daemon=True)
    killer.start()
    started = time.monotonic()
    with pytest.raises(
        DseError, match=r"timed its first simulation, the Dask scheduler .* has had no worker for 4 s"
    ):
        submit(load_space(spec))
    assert time.monotonic() - started < 120
    killer.join(timeout=30)


def wait_until_idle(address: str, timeout: float = 120) -> None:
    """Until the scheduler at ``address`` holds no task and none of its workers runs one: a dead client's
    chunks are forgotten, except those already running, which run on to their end."""
    from distributed import Client

    with Client(address, timeout="30s") as client:
        deadline = time.time() + timeout
        while client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks)) or any(
            client.run(lambda dask_worker: len(dask_worker.active_threads)).values()
        ):
            assert time.time() < deadline, f"workers still busy after {timeout} s"
            time.sleep(0.1)


def test_killed_client_resumes_on_submit(tmp_path, dask_scheduler):
    path = write_space(
        tmp_path, scenarios=[str(SCENARIOS / "*")], parameters=SLOW, chunk_seconds=0.5, keep_trajectories=0
    )
    command = [
        sys.executable,
        "-m",
        "dse_runner",
        "submit",
        str(path),
        "--scheduler",
        dask_scheduler,
        "--json",
    ]
    first = subprocess.Popen(command, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wait_for_files(tmp_path / "out", 3)
    first.send_signal(signal.SIGKILL)
    first.wait(timeout=30)
    wait_until_idle(
        dask_scheduler
    )  # chunks running on workers finish and write; the scheduler forgets the rest
    before = len(store.read_results(tmp_path / "out", "small", columns=[]))
    assert 0 < before < SLOW_TASKS  # the client died mid-sweep
    second = subprocess.run(command, check=False, cwd=REPO, capture_output=True, text=True, timeout=600)
    assert second.returncode == 0, second.stderr
    report = strict_loads(second.stdout)
    assert report["skipped"] >= before and report["skipped"] + report["ran"] == SLOW_TASKS
    after = store.read_results(tmp_path / "out", "small", columns=["status"])
    assert len(after) == SLOW_TASKS and (after["status"] == "ok").all()


def test_scheduler_restart_resumes_from_the_store(tmp_path, cli_cluster):
    cluster = cli_cluster()
    space = load_space(
        write_space(
            tmp_path,
            scenarios=[str(SCENARIOS / "*")],
            parameters=SLOW,
            chunk_seconds=0.5,
            keep_trajectories=0,
            cluster={"address": cluster.address, "connect_timeout": 120},
        )
    )
    outcome: dict = {}

    def run() -> None:
        try:
            outcome["report"] = submit(space)
        except BaseException as e:  # noqa: BLE001  (raised by the test below)
            outcome["error"] = e

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    wait_for_files(space.output, 3)
    cluster.kill_scheduler()  # its workers exit too, as they do in distributed
    done_when_killed = len(store.read_results(space.output, "small", columns=[]))
    cluster.start_scheduler()  # same address; a supervisor would also restart the workers
    cluster.start_worker()
    cluster.start_worker()
    thread.join(timeout=600)
    if "error" in outcome:
        raise outcome["error"]
    report = outcome["report"]
    assert report.reconnects == 1
    assert report.ok + report.skipped >= SLOW_TASKS - done_when_killed
    rows = store.read_results(space.output, "small", columns=["status"])
    assert len(rows) == SLOW_TASKS and (rows["status"] == "ok").all()


CRASH_AT = 13.0


def crasher_space(tmp_path: Path, n_workers: int = 2) -> Path:
    """A multi-model whose FMU segfaults for one parameter point of sixteen: with two workers, chunks of two
    points, so the culprit's chunk is split once and the culprit then runs alone."""
    sources = tmp_path / "fmus"
    shutil.copytree(REPO / "tests" / "fmus" / "crasher", sources / "crasher")
    shutil.copytree(FMU_SOURCES / "common", sources / "common")
    multimodel = {
        "fmus": {"controller": str(FMU_SOURCES / "replay_controller"), "crasher": str(sources / "crasher")},
        "connections": {"controller.velocity": ["crasher.velocity"]},
        "parameters": {"crasher.crash_at": CRASH_AT},
        "scenario": {"controller.file": "steering_inputs"},
    }
    (tmp_path / "crasher.yaml").write_text(yaml.safe_dump(multimodel))
    return write_space(
        tmp_path,
        multimodel=str(tmp_path / "crasher.yaml"),
        scenarios=[str(SCENARIOS / "sin1")],
        parameters={"crasher.k": {"start": 0, "stop": 15, "step": 1}},
        chunk_seconds=100,
        keep_trajectories=0,
        cluster={"n_workers": n_workers},
    )


# One worker: every task Dask had given it is blamed for its death, and the worker is down most of the
# time, between lives; distributed's local cluster used to close its nanny for good at such a moment.
@pytest.mark.slow  # a sweep on a local cluster
@pytest.mark.parametrize("n_workers", [2, 1])
def test_segfaulting_fmu_fails_only_its_point(tmp_path, n_workers):
    space = load_space(crasher_space(tmp_path, n_workers))
    report = submit(space)
    assert report.chunk_size > 1 and report.crashed_chunks >= 1  # a chunk was split down to the culprit
    assert (report.ok, report.failed) == (15, 1)
    rows = store.read_results(space.output, "small", columns=["crasher.k", "status", "error", "lifecycle"])
    failed = rows[rows["status"] == "failed"]
    assert list(failed["crasher.k"]) == [CRASH_AT]
    # alone, it ran in a process of its own: that process died, not another worker
    assert "fresh process running this simulation was killed by SIGSEGV" in failed["error"].iloc[0]
    assert "process" in set(rows.loc[rows["status"] == "ok", "lifecycle"])  # its last half's sibling, alone
    ids = raw_task_ids(space.output)
    assert len(ids) == 16 and ids.is_unique


def test_tls_scheduler(tmp_path, cli_cluster):
    certs = make_certs(tmp_path / "certs")
    cluster = cli_cluster(certs=certs)
    assert cluster.address.startswith("tls://")
    tls = {
        "ca_file": "certs/ca.pem",
        "cert": "certs/cert.pem",
        "key": "certs/key.pem",
    }  # relative to the spec
    space = load_space(write_space(tmp_path, cluster={"address": cluster.address, "tls": tls}))
    report = submit(space)
    assert (report.ok, report.failed, report.workers) == (12, 0, 2)
    with (
        pytest.raises(DseError, match="needs cluster.tls"),
        connect(Cluster(address=cluster.address, connect_timeout=5)),
    ):
        pass


def test_htcondor_job_script(tmp_path):
    """No HTCondor pool exists here: check the submit description dask-jobqueue renders from our spec."""
    spec = Cluster.model_validate(
        {
            "kind": "htcondor",
            "htcondor": {
                "cores": 4,
                "memory": "8GiB",
                "disk": "2GiB",
                "job_extra": {"+ProjectName": '"robotti"'},
                "prologue": ["source /opt/venvs/dse/bin/activate"],
                "python": "/opt/venvs/dse/bin/python",
            },
        }
    )
    cluster = HTCondor().started(spec, None)
    try:
        script = cluster.job_script()
        link = urlparse(cluster.dashboard_link)  # named by the host's address, but bound to loopback only
        assert reachable("127.0.0.1", link.port) and (
            link.hostname == "127.0.0.1" or not reachable(link.hostname, link.port)
        )
    finally:
        cluster.close()
    assert "RequestCpus = MY.DaskWorkerCores" in script and "MY.DaskWorkerCores = 4" in script
    assert "MY.DaskWorkerMemory = 8589934592" in script and "MY.DaskWorkerDisk = 2147483648" in script
    assert '+ProjectName = "robotti"' in script
    assert "source /opt/venvs/dse/bin/activate" in script
    assert "/opt/venvs/dse/bin/python -m distributed.cli.dask_worker" in script
    assert "--nworkers 4" in script and "--nthreads 1" in script  # four single-threaded workers per job


def test_kubernetes_cluster_resource():
    """No Kubernetes cluster exists here: check the DaskCluster resource the operator would be given."""
    pytest.importorskip("dask_kubernetes")
    spec = Cluster.model_validate(
        {
            "kind": "kubernetes",
            "threads_per_worker": 1,
            "kubernetes": {
                "image": "registry.example/dse-runner:1",
                "env": {"AWS_ENDPOINT_URL": "http://minio:9000"},
            },
        }
    )
    resource = kubernetes_cluster_spec(
        spec, KubernetesOptions.model_validate(spec.block("kubernetes")), "dse-runner-test"
    )
    (scheduler,) = resource["spec"]["scheduler"]["spec"]["containers"]
    (worker,) = resource["spec"]["worker"]["spec"]["containers"]
    assert scheduler["args"][:2] == ["dask", "scheduler"]  # the command distributed still has
    assert worker["args"][:4] == ["dask", "worker", "--nthreads", "1"]
    assert worker["image"] == scheduler["image"] == "registry.example/dse-runner:1"
    assert {"name": "AWS_ENDPOINT_URL", "value": "http://minio:9000"} in worker["env"]
    assert worker["resources"]["limits"] == {"cpu": "1", "memory": "2Gi"}
    assert resource["spec"]["idleTimeout"] > 0  # a crashed client's cluster is removed


def test_cluster_choice_errors(tmp_path):
    with pytest.raises(DseError, match="not both"):
        load_space(write_space(tmp_path, cluster={"kind": "htcondor", "address": "tcp://127.0.0.1:8786"}))
    with pytest.raises(DseError, match="needs a protocol"):
        load_space(write_space(tmp_path, cluster={"address": "127.0.0.1:8786"}))
    space = load_space(write_space(tmp_path, cluster={"kind": "lsf"}))
    with pytest.raises(
        DseError, match=r"cluster.kind 'lsf' is unknown \(known: htcondor, kubernetes, local, slurm"
    ):
        submit(space)
    space = load_space(
        write_space(
            tmp_path,
            cluster={"address": "tls://127.0.0.1:1", "tls": {"ca_file": "x", "cert": "y", "key": "z"}},
        )
    )
    with pytest.raises(DseError, match="cluster.tls.ca_file: no file"):
        submit(space)
    overridden = load_space(write_space(tmp_path, cluster={"kind": "htcondor"})).with_overrides(
        address="tcp://127.0.0.1:8786"
    )
    assert (overridden.spec.cluster.kind, overridden.spec.cluster.address) == (
        "local",
        "tcp://127.0.0.1:8786",
    )


@pytest.mark.slow  # the command retries the address for its 3 s connect timeout
def test_unreachable_scheduler_names_it(tmp_path):
    spec = write_space(tmp_path, cluster={"connect_timeout": 3})  # refused at once, retried for 3 s, not 30
    result = subprocess.run(
        [sys.executable, "-m", "dse_runner", "submit", str(spec), "--scheduler", "tcp://127.0.0.1:9"],
        check=False,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in result.stderr
    assert load_status(tmp_path / "out", "small").state == "failed"  # a dashboard must not wait for it


@pytest.mark.slow  # a sweep on a local cluster, into a moto S3 server
def test_store_at_an_s3_url(tmp_path, monkeypatch):
    """Results written by the workers straight to an S3 bucket (moto's S3 server
    on loopback), ranked from there."""
    boto3 = pytest.importorskip("boto3")
    from moto.server import ThreadedMotoServer

    server = ThreadedMotoServer(ip_address="127.0.0.1", port=0)
    server.start()
    try:
        host, port = server.get_host_and_port()
        endpoint = f"http://{host}:{port}"
        for name, value in {
            "AWS_ACCESS_KEY_ID": "test",
            "AWS_SECRET_ACCESS_KEY": "test",
            "AWS_DEFAULT_REGION": "us-east-1",
            "AWS_ENDPOINT_URL": endpoint,
        }.items():
            monkeypatch.setenv(name, value)  # the local cluster's workers inherit these
        boto3.client("s3", endpoint_url=endpoint).create_bucket(Bucket="sweeps")
        space = load_space(write_space(tmp_path, output="s3://sweeps/robotti", cluster={"n_workers": 2}))
        report = submit(space)
        assert (report.ok, report.failed) == (12, 0), report.errors
        keys = [
            o["Key"]
            for o in boto3.client("s3", endpoint_url=endpoint).list_objects_v2(
                Bucket="sweeps", Prefix="robotti/results/"
            )["Contents"]
        ]
        assert keys and all(k.endswith(".parquet") for k in keys)
        assert (
            not (tmp_path / "s3:").exists() and not (tmp_path / "sweeps").exists()
        )  # nothing landed locally
        ranking = rank("s3://sweeps/robotti")
        assert len(ranking.totals) == 6
        assert store.read_trajectory("s3://sweeps/robotti", "small", "sin1", 1)["time"].size > 0
    finally:
        server.stop()


@pytest.mark.slow  # a dse-runner command that starts a scheduler
def test_htcondor_without_condor_submit_is_one_line_at_once(tmp_path):
    """No HTCondor here: the submit stops at once with one line naming the missing command, instead of
    logging a FileNotFoundError per job and waiting 30 minutes for a worker."""
    if shutil.which("condor_submit"):
        pytest.skip("HTCondor is installed here")
    spec = write_space(tmp_path)
    started = time.monotonic()
    result = subprocess.run(
        [sys.executable, "-m", "dse_runner", "submit", str(spec), "--cluster", "htcondor", "--no-dashboard"],
        check=False,
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )
    assert time.monotonic() - started < 30
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        (
            "error: cluster.kind htcondor: condor_submit is not on PATH: run dse-runner "
            "where HTCondor's commands are (a login or submit node), or install them"
        )
    ], result.stderr


@pytest.mark.slow  # a sweep's cluster started and stopped
def test_a_refused_htcondor_job_stops_the_sweep_with_its_words(tmp_path, monkeypatch):
    """HTCondor on the same path as Slurm: a condor_submit that fails as it does without a reachable schedd
    (no pool can run here) stops the sweep with its stderr in one line, not a 30-minute wait."""
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    (bin_ / "condor_submit").write_text(
        "#!/bin/sh\necho 'ERROR: Can'\"'\"'t find address of local schedd' >&2\nexit 1\n"
    )
    (bin_ / "condor_submit").chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_}:{os.environ['PATH']}")
    space = load_space(write_space(tmp_path, cluster={"kind": "htcondor"}))
    started = time.monotonic()
    with pytest.raises(
        DseError, match=r"^HTCondor refused a worker job: ERROR: Can't find address of local schedd$"
    ):
        submit(space)
    assert time.monotonic() - started < 60
    assert load_status(space.output, "small").state == "failed"


@pytest.mark.parametrize(
    "address, template",
    [
        ("127.0.0.1:0", "{scheme}://127.0.0.1:{port}/status"),
        ("192.0.2.7:8787", "{scheme}://192.0.2.7:{port}/status"),
        ("0.0.0.0:8787", None),  # every interface: distributed's link, naming the scheduler's host, is right
        (":8787", None),
        ("8787", None),  # a bare port: every interface too
    ],
)
def test_dashboard_links_name_the_host_the_dashboard_listens_on(address, template):
    from dse_runner.sweeps.cluster import dashboard_link_template

    assert dashboard_link_template(address) == template


@pytest.mark.parametrize(
    "cluster, message",
    [
        ({"min_workers": 1}, "min_workers needs max_workers"),
        ({"n_workers": 2, "max_workers": 4}, "give either n_workers .* or min_workers/max_workers"),
        ({"min_workers": 3, "max_workers": 2}, r"min_workers \(3\) is more than max_workers \(2\)"),
        ({"address": "tcp://127.0.0.1:8786", "max_workers": 2}, "scale a cluster dse-runner starts"),
    ],
)
def test_adaptive_bounds_are_checked(tmp_path, cluster, message):
    with pytest.raises(DseError, match=message):
        load_space(write_space(tmp_path, cluster=cluster))
    adaptive = load_space(
        write_space(tmp_path, cluster={"kind": "slurm", "min_workers": 0, "max_workers": 4})
    )
    fixed = adaptive.with_overrides(n_workers=3).spec.cluster  # --workers: a fixed count instead
    assert (fixed.n_workers, fixed.min_workers, fixed.max_workers) == (3, None, None)


def test_slurm_job_script():
    """The sbatch script dask-jobqueue renders from cluster.slurm, with dask-jobqueue's names and meanings."""
    from dse_runner.sweeps.jobqueue import Slurm

    spec = Cluster.model_validate(
        {
            "kind": "slurm",
            "slurm": {
                "queue": "short",
                "account": "proj42",
                "cores": 4,
                "memory": "8GiB",
                "walltime": "02:00:00",
                "job_extra_directives": ["--qos=low"],
                "job_script_prologue": ["source /opt/venvs/dse/bin/activate"],
                "python": "/opt/venvs/dse/bin/python",
                "log_directory": "/tmp/dse-logs",
            },
        }
    )
    cluster = Slurm().started(spec, None)
    try:
        script = cluster.job_script()
    finally:
        cluster.close()
    for line in (
        "#SBATCH -p short",
        "#SBATCH -A proj42",
        "#SBATCH --cpus-per-task=4",
        "#SBATCH --mem=8G",
        "#SBATCH -t 02:00:00",
        "#SBATCH --qos=low",
        "#SBATCH -e /tmp/dse-logs/dask-worker-%J.err",
        "source /opt/venvs/dse/bin/activate",
        "/opt/venvs/dse/bin/python -m distributed.cli.dask_worker",
    ):
        assert line in script, line
    assert "--nworkers 4" in script and "--nthreads 1" in script  # four single-threaded workers per job
