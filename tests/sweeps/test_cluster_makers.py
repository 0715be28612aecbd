"""The cluster-maker contract (makers.ClusterMaker): every installed kind is one, a plug-in with only
``start`` runs a sweep with the default scale and close, and a plug-in's own block under its kind's name
is validated with the spec, its errors naming the key. The command line's local cluster forks its workers
from a forkserver unless Dask's own variable chooses the start method."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from conftest import write_space
from pydantic import BaseModel, ValidationError
from support.plugins import register

from dse_runner.errors import DseError
from dse_runner.sweeps import makers, start_method
from dse_runner.sweeps.cluster import connect
from dse_runner.sweeps.makers import Cluster
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import submit

PLUGIN = """
import logging

from distributed import LocalCluster
from pydantic import BaseModel, ConfigDict, PositiveFloat

from dse_runner.sweeps.makers import ClusterMaker

STARTED, CLOSED = [], []


class Bare(ClusterMaker):
    '''Only what the contract requires: workers come from the default scale.'''

    def start(self, spec, options, security):
        cluster = LocalCluster(n_workers=0, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address=spec.dashboard_address, silence_logs=logging.ERROR)
        STARTED.append(cluster)
        return cluster


class TaggedOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")
    resource: str
    amount: PositiveFloat = 1.0


class Tagged(ClusterMaker):
    '''A block of its own: a resource every worker declares.'''

    Options = TaggedOptions
    first_worker_wait = 0.0

    def start(self, spec, options, security):
        return LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                            dashboard_address=spec.dashboard_address, silence_logs=logging.ERROR,
                            resources={options.resource: options.amount})

    def scale(self, cluster, n_workers):
        '''Nothing: it started with its worker.'''

    def close(self, cluster):
        CLOSED.append(cluster)
        cluster.close()


class Function:  # what a maker was before the contract: refused by name
    pass
"""

KINDS = {"bare": "maker_plugin:Bare", "tagged": "maker_plugin:Tagged", "function": "maker_plugin:Function"}


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    register(monkeypatch, tmp_path / "plugin", "maker_plugin", PLUGIN, {"dse_runner.clusters": KINDS})
    import maker_plugin

    return maker_plugin


def test_every_built_in_kind_holds_to_the_contract():
    for kind in makers.installed():
        found = makers.maker(kind)
        assert isinstance(found, makers.ClusterMaker), kind
        assert issubclass(found.Options, BaseModel), kind
        assert isinstance(found.options(None, kind), found.Options)  # a kind's block is optional
        assert Cluster.model_validate({"kind": kind}).kind == kind


def test_a_maker_with_only_start_runs_a_sweep(tmp_path, plugin):
    space = load_space(write_space(tmp_path, cluster={"kind": "bare", "n_workers": 2}))
    assert (
        makers.maker("bare").first_worker_wait == makers.QUEUE_WAIT
    )  # the defaults: a queue may be slow ...
    report = submit(space)
    assert (report.ok, report.failed, report.workers) == (12, 0, 2)  # ... and it scaled to n_workers
    [cluster] = plugin.STARTED
    assert cluster.status.name == "closed"  # and the default close closed it


def test_a_makers_own_block_reaches_it(tmp_path, plugin):
    spec = Cluster.model_validate({"kind": "tagged", "tagged": {"resource": "plugged", "amount": 2}})
    with connect(spec) as client:
        [worker] = client.scheduler_info()["workers"].values()
        assert worker["resources"] == {"plugged": 2.0}
    [cluster] = plugin.CLOSED
    assert cluster.status.name == "closed"


@pytest.mark.parametrize(
    "cluster, message",
    [
        (
            {"kind": "tagged", "tagged": {"resource": "x", "amount": -1}},
            r"cluster: tagged\.amount: input should be greater than 0 \(an option of cluster kind tagged\)",
        ),
        (
            {"kind": "tagged"},
            r"cluster: tagged\.resource: field required",
        ),  # the spec's block, though not given
        (
            {"kind": "tagged", "taged": {"resource": "x"}},
            (
                r"cluster: unknown key 'taged': besides its own keys, cluster "
                r"takes a block named by a cluster kind \(installed: bare, "
                r"function, htcondor, kubernetes, local, slurm, tagged\)"
            ),
        ),
        ({"kind": "bare", "bare": {"cores": 4}}, r"cluster: bare\.cores: extra inputs are not permitted"),
        (
            {"kind": "htcondor", "htcondor": {"cores": 0}},
            r"cluster: htcondor\.cores: input should be greater than 0",
        ),
        (
            {"kind": "function"},
            (
                r"cluster: cluster\.kind 'function' \(maker_plugin:Function\) is not a subclass of "
                r"dse_runner\.sweeps\.makers\.ClusterMaker"
            ),
        ),
    ],
)
def test_cluster_blocks_are_checked_when_the_spec_loads(tmp_path, plugin, cluster, message):
    with pytest.raises(DseError, match=message):
        load_space(write_space(tmp_path, cluster=cluster))


def test_a_block_for_a_kind_not_installed_here_waits_for_the_sweep(tmp_path):
    """A space may name a plug-in kind this machine lacks (to be ranked or
    viewed here): the sweep names it."""
    spec = Cluster.model_validate({"kind": "lsf", "lsf": {"queue": "short"}})
    assert spec.block("lsf") == {"queue": "short"}
    with pytest.raises(ValidationError, match="unknown key 'lsf'"):
        Cluster.model_validate({"kind": "local", "lsf": {"queue": "short"}})
    with (
        pytest.raises(
            DseError, match=r"cluster.kind 'lsf' is unknown \(known: htcondor, kubernetes, local, slurm"
        ),
        connect(spec),
    ):
        pass


# A process like the command line's: it asks for forked workers, makes its local cluster and
# reports each worker's parent. A spawned worker's parent is this process (its nanny lives
# here), a forked one's the server.
LOCAL_PARENTS = """
import json, os
from dse_runner.sweeps import start_method
from dse_runner.sweeps.cluster import connect
from dse_runner.sweeps.makers import Cluster

start_method.fork_local_workers()
with connect(Cluster(n_workers=2)) as client:
    parents = sorted(client.run(os.getppid).values())
print(json.dumps({"own": os.getpid(), "parents": parents}))
"""


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the forkserver is used on Linux only")
@pytest.mark.parametrize("method, forked", [(None, True), ("spawn", False)])
def test_the_command_lines_workers_fork_unless_dasks_variable_chooses(method, forked):
    env = {key: value for key, value in os.environ.items() if key != start_method.START_METHOD_VARIABLE}
    if method:
        env[start_method.START_METHOD_VARIABLE] = method
    done = subprocess.run(
        [sys.executable, "-c", LOCAL_PARENTS],
        check=False,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout.splitlines()[-1])
    assert len(seen["parents"]) == 2, seen
    assert [parent != seen["own"] for parent in seen["parents"]] == [forked, forked], seen
