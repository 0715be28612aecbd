"""A real single-node Slurm for tests: Debian's munged, slurmctld and slurmd on loopback, as root.

Everything is private to one folder: its own munge key and socket, its own ports, state and spool,
so it neither needs nor disturbs a Slurm or munge the machine may already run. The daemons run in
the foreground as our children (told to end when pytest does, even killed); :meth:`SingleNodeSlurm.close`
cancels every job, stops the daemons, and kills whatever process a job left behind (found by the
``SLURM_CONF`` every job inherits), so nothing outlives the tests.

No cgroups are needed: ``ProctrackType=proctrack/linuxproc`` tracks a job's processes by parentage, and
``TaskPlugin=task/none`` binds nothing. The node is named ``localhost`` (``slurmd -N``), whatever the host is
called.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

from support.cluster import _end_with_parent, free_port

DAEMONS = {"munged": "/usr/sbin/munged", "slurmctld": "/usr/sbin/slurmctld", "slurmd": "/usr/sbin/slurmd"}
CLIENTS = ("sbatch", "squeue", "scancel", "sinfo", "scontrol")
PARTITION = "debug"


def why_not() -> str | None:
    """Why a single-node Slurm cannot start here, or None if it can."""
    if os.geteuid() != 0:
        return "a single-node Slurm needs root (slurmd runs jobs as their users)"
    missing = [name for name, path in DAEMONS.items() if not os.access(path, os.X_OK)]
    missing += [name for name in CLIENTS if shutil.which(name) is None]
    if missing or not shutil.which("mungekey"):
        return (
            f"no {', '.join(missing or ['mungekey'])}: needs Debian's slurmctld, "
            "slurmd, slurm-client and munge (.ci/install adds them as root)"
        )
    return None


def node_memory_mb() -> int:
    """What the node offers jobs: the machine's memory less 1 GiB for everything else."""
    with open("/proc/meminfo") as f:
        total_kb = next(int(line.split()[1]) for line in f if line.startswith("MemTotal"))
    return total_kb // 1024 - 1024


class SingleNodeSlurm:
    """munged, slurmctld and slurmd for one node ``localhost`` with all its cores, in ``folder``."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.conf = folder / "slurm.conf"
        self.env = {**os.environ, "SLURM_CONF": str(self.conf)}
        self.daemons: dict[str, subprocess.Popen] = {}
        for sub in ("state", "spool", "log"):
            (folder / sub).mkdir(parents=True, exist_ok=True)
        self.socket = folder / "munge.socket"
        try:
            self._munge()
            self._write_conf()
            self._start("slurmctld", [DAEMONS["slurmctld"], "-D", "-i"])
            self._start("slurmd", [DAEMONS["slurmd"], "-D", "-N", "localhost"])
            self._wait_idle()
        except BaseException:
            self.close()
            raise

    def _munge(self) -> None:
        key = self.folder / "munge.key"
        subprocess.run(["mungekey", "--create", f"--keyfile={key}"], check=True, capture_output=True)
        key.chmod(0o400)
        self._start(
            "munged",
            [
                DAEMONS["munged"],
                "--foreground",
                "--force",
                f"--socket={self.socket}",
                f"--key-file={key}",
                f"--pid-file={self.folder / 'munged.pid'}",
                f"--log-file={self.folder / 'log' / 'munged.log'}",
                f"--seed-file={self.folder / 'munged.seed'}",
            ],
        )
        self._until(lambda: self.socket.exists(), 30, "munged made no socket")

    def _write_conf(self) -> None:
        d = self.folder
        auth = f"socket={self.socket}"
        self.conf.write_text(
            "\n".join(
                [
                    "ClusterName=dsetest",
                    "SlurmctldHost=localhost(127.0.0.1)",
                    f"SlurmctldPort={free_port()}",
                    f"SlurmdPort={free_port()}",
                    "SlurmUser=root",
                    "AuthType=auth/munge",
                    "CredType=cred/munge",
                    f"AuthInfo={auth}",
                    f"StateSaveLocation={d / 'state'}",
                    f"SlurmdSpoolDir={d / 'spool'}",
                    f"SlurmctldPidFile={d / 'slurmctld.pid'}",
                    f"SlurmdPidFile={d / 'slurmd.pid'}",
                    f"SlurmctldLogFile={d / 'log' / 'slurmctld.log'}",
                    f"SlurmdLogFile={d / 'log' / 'slurmd.log'}",
                    "ProctrackType=proctrack/linuxproc",
                    "TaskPlugin=task/none",
                    "JobAcctGatherType=jobacct_gather/none",
                    "AccountingStorageType=accounting_storage/none",
                    "SchedulerType=sched/backfill",
                    "SelectType=select/cons_tres",
                    "SelectTypeParameters=CR_Core_Memory",
                    "MpiDefault=none",
                    "MailProg=/bin/true",
                    "ReturnToService=2",
                    "KillWait=5",  # seconds between a cancelled job's SIGTERM and SIGKILL
                    (
                        f"NodeName=localhost NodeAddr=127.0.0.1 CPUs={os.cpu_count()} "
                        f"RealMemory={node_memory_mb()} State=UNKNOWN"
                    ),
                    f"PartitionName={PARTITION} Nodes=localhost Default=YES MaxTime=INFINITE State=UP",
                    "",
                ]
            )
        )

    def _start(self, name: str, command: list[str]) -> None:
        with open(self.folder / "log" / f"{name}.out", "ab") as out:
            self.daemons[name] = subprocess.Popen(
                command,
                env=self.env,
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                preexec_fn=_end_with_parent,  # noqa: PLW1509  (a parent-death signal is set in the child)
            )

    def _until(self, done, timeout: float, failure: str) -> None:
        deadline = time.monotonic() + timeout
        while not done():
            for name, daemon in self.daemons.items():
                if daemon.poll() is not None:
                    raise RuntimeError(f"{name} exited ({daemon.returncode}); see {self.folder / 'log'}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"{failure} within {timeout:g} s; see {self.folder / 'log'}")
            time.sleep(0.2)

    def _wait_idle(self) -> None:
        def idle() -> bool:
            out = self.run("sinfo", "-h", "-o", "%t", check=False)
            return out.returncode == 0 and out.stdout.split() == ["idle"]

        self._until(idle, 60, "the node did not come up idle")

    def run(self, *command: str, check: bool = True) -> subprocess.CompletedProcess:
        """A Slurm command against this cluster."""
        return subprocess.run(
            list(command), env=self.env, capture_output=True, text=True, check=check, timeout=60
        )

    def jobs(self, states: str = "PENDING,RUNNING,CONFIGURING,COMPLETING") -> list[str]:
        """Ids of the jobs in those states."""
        return self.run("squeue", "-h", "-t", states, "-o", "%i").stdout.split()

    def running(self) -> list[str]:
        return self.jobs("RUNNING")

    def ever(self) -> list[str]:
        """Every job slurmctld still remembers (MinJobAge: 300 s after it ended), of any state."""
        return self.run("squeue", "-h", "-t", "all", "-o", "%i").stdout.split()

    def cancel(self, job: str) -> None:
        self.run("scancel", job)

    def wait_for_no_jobs(self, timeout: float = 60) -> None:
        self._until(lambda: not self.jobs(), timeout, "jobs still queued or running")

    def close(self) -> None:
        """Cancel every job, stop the daemons (slurmd, slurmctld, munged) and kill what jobs left behind."""
        if "slurmd" in self.daemons and self.daemons["slurmd"].poll() is None:
            self.run("scancel", "--full", "--user=root", check=False)
            try:
                self.wait_for_no_jobs(30)
            except RuntimeError:
                pass
        for name in ("slurmd", "slurmctld", "munged"):
            daemon = self.daemons.get(name)
            if daemon is None or daemon.poll() is not None:
                continue
            daemon.send_signal(signal.SIGTERM)
            try:
                daemon.wait(timeout=30)
            except subprocess.TimeoutExpired:
                daemon.kill()
                daemon.wait(timeout=30)
        deadline = time.monotonic() + 30  # a killed process takes a moment to go, longer on a busy machine
        while (left := self.leftovers()) and time.monotonic() < deadline:
            for pid in left:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            time.sleep(0.2)

    def leftovers(self) -> list[int]:
        """Processes still running with this cluster's SLURM_CONF: a job's, or a daemon's."""
        mark = f"SLURM_CONF={self.conf}".encode()
        found = []
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit() or int(entry.name) == os.getpid():
                continue
            try:
                if mark in (entry / "environ").read_bytes().split(b"\0"):
                    found.append(int(entry.name))
            except OSError:
                continue
        return found
