"""A real Dask cluster for tests: `dask scheduler` and `dask worker` started through their command lines.

Options cover what the cluster tests need: TLS certificates, a fixed port (so
a restarted scheduler comes back at the same address), and workers that see
none of the client's files (each started in its own mount namespace, with
tmpfs laid over the folders to hide).
"""

from __future__ import annotations

import ctypes
import datetime
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

DASK_SCHEDULER = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
DASK_WORKER = [sys.executable, "-m", "distributed.cli.dask_worker"]


def _end_with_parent() -> None:
    """In the child before exec: SIGTERM when the process that started it dies (Linux's PR_SET_PDEATHSIG)."""
    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # 1: PR_SET_PDEATHSIG


@dataclass(frozen=True)
class Certs:
    ca_file: Path
    cert: Path
    key: Path

    def flags(self) -> list[str]:
        return ["--tls-ca-file", str(self.ca_file), "--tls-cert", str(self.cert), "--tls-key", str(self.key)]


def make_certs(folder: Path) -> Certs:
    """A throw-away certificate authority and one certificate for 127.0.0.1 that it signed."""
    import ipaddress

    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    now = datetime.datetime.now(datetime.UTC)
    window = (now - datetime.timedelta(days=1), now + datetime.timedelta(days=2))

    def certificate(subject: str, key, issuer: str, issuer_key, ca: bool) -> x509.Certificate:
        builder = (
            x509.CertificateBuilder()
            .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, subject)]))
            .issuer_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, issuer)]))
            .public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(window[0])
            .not_valid_after(window[1])
            .add_extension(x509.BasicConstraints(ca=ca, path_length=None), critical=True)
        )
        if not ca:
            builder = builder.add_extension(
                x509.SubjectAlternativeName(
                    [x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]
                ),
                critical=False,
            )
        return builder.sign(issuer_key, hashes.SHA256())

    ca_key, key = ec.generate_private_key(ec.SECP256R1()), ec.generate_private_key(ec.SECP256R1())
    ca = certificate("dse-runner test CA", ca_key, "dse-runner test CA", ca_key, ca=True)
    leaf = certificate("127.0.0.1", key, "dse-runner test CA", ca_key, ca=False)
    folder.mkdir(parents=True, exist_ok=True)
    certs = Certs(folder / "ca.pem", folder / "cert.pem", folder / "key.pem")
    certs.ca_file.write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    certs.cert.write_bytes(leaf.public_bytes(serialization.Encoding.PEM))
    certs.key.write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
        )
    )
    return certs


def _ephemeral_ports() -> range:
    try:
        low, high = map(int, Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split())
    except (OSError, ValueError):
        low, high = 32768, 60999
    return range(low, high + 1)


def free_port() -> int:
    """A free port outside the kernel's ephemeral range: a scheduler restarted on it must find it free,
    and while it is down the client's reconnection attempts (or any other connection) could otherwise
    be given that very port as their source port, a self-connection that keeps the port taken."""
    ephemeral = _ephemeral_ports()
    for port in random.sample(range(20000, 32768), 200):
        if port in ephemeral:
            continue
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise OSError("no free port below the ephemeral range")


def can_hide_folders() -> bool:
    """Whether this machine lets us start a process in its own mount namespace (needs root)."""
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(
        ["unshare", "-m", "sh", "-c", "mount -t tmpfs none /mnt"], check=False, capture_output=True
    )
    return probe.returncode == 0


def quiet_environment() -> dict[str, str]:
    """dse-runner's own local cluster's Dask settings (makers.QUIET) as environment variables: the test
    clusters then spend as little on Dask's housekeeping as that cluster does. One per test process idles
    beside the whole suite, and with Dask's defaults each cost 0.12-0.19 of a core (docs/testing.md)."""
    from dse_runner.sweeps.makers import QUIET

    return {
        "DASK_" + "__".join(part.upper().replace("-", "_") for part in key.split(".")): str(value)
        for key, value in QUIET.items()
    }


class CliCluster:
    """A scheduler and ``workers`` single-threaded workers on loopback, each its own process."""

    def __init__(
        self, folder: Path, workers: int = 2, certs: Certs | None = None, hide: tuple[Path, ...] = ()
    ):
        self.folder, self.certs, self.hide = folder, certs, hide
        self.port = free_port()
        self.protocol = "tls" if certs else "tcp"
        self.address = f"{self.protocol}://127.0.0.1:{self.port}"
        self.env = {**os.environ, **quiet_environment()}
        self.scheduler: subprocess.Popen | None = None
        self.workers: list[subprocess.Popen] = []
        self.start_scheduler()
        for _ in range(workers):
            self.start_worker()
        self.wait_for_workers(workers)

    def _popen(self, command: list[str], log: str) -> subprocess.Popen:
        with open(self.folder / log, "ab") as out:
            # Each process leads its own process group, so that close() can kill a nanny and its
            # worker at once; and is told to end when pytest does, even killed (no teardown
            # then), so no daemon outlives a run.
            return subprocess.Popen(
                command,
                env=self.env,
                cwd=self.folder,
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                preexec_fn=_end_with_parent,  # noqa: PLW1509  (a parent-death signal is set in the child)
            )

    def start_scheduler(self) -> None:
        tls = self.certs.flags() if self.certs else []
        self.scheduler = self._popen(
            [
                *DASK_SCHEDULER,
                "--protocol",
                self.protocol,
                "--host",
                "127.0.0.1",
                "--port",
                str(self.port),
                "--dashboard-address",
                "127.0.0.1:0",
                *tls,
            ],
            "scheduler.log",
        )
        deadline = time.time() + 60
        while time.time() < deadline:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", self.port)) == 0:
                    return
            time.sleep(0.1)
        raise RuntimeError(f"dask scheduler did not start; see {self.folder / 'scheduler.log'}")

    def start_worker(self) -> None:
        index = len(self.workers)
        tls = self.certs.flags() if self.certs else []
        command = [
            *DASK_WORKER,
            self.address,
            "--nthreads",
            "1",
            "--name",
            f"worker-{index}",
            "--no-dashboard",
            *tls,
        ]
        if self.hide:
            mounts = " && ".join(f"mount -t tmpfs none '{p}'" for p in self.hide)
            command = ["unshare", "-m", "sh", "-c", f'{mounts} && exec "$@"', "sh", *command]
        self.workers.append(self._popen(command, f"worker-{index}.log"))

    def client(self, timeout: str = "30s"):
        from distributed import Client
        from distributed.security import Security

        security = None
        if self.certs:
            c = self.certs
            security = Security(
                tls_ca_file=str(c.ca_file),
                tls_client_cert=str(c.cert),
                tls_client_key=str(c.key),
                require_encryption=True,
            )
        return Client(self.address, security=security, timeout=timeout)

    def wait_for_workers(self, n: int) -> None:
        with self.client() as client:
            client.wait_for_workers(n, timeout=120)

    def kill_workers(self) -> None:
        """SIGKILL every worker with its nanny (a process group each); none is restarted."""
        for worker in self.workers:
            os.killpg(worker.pid, signal.SIGKILL)
            worker.wait(timeout=30)
        self.workers = []

    def kill_scheduler(self) -> None:
        """SIGKILL the scheduler; its workers exit on their own when they lose it."""
        self.scheduler.send_signal(signal.SIGKILL)
        self.scheduler.wait(timeout=30)
        for worker in self.workers:
            try:
                worker.wait(timeout=60)
            except subprocess.TimeoutExpired:
                worker.kill()
        self.workers = []

    def close(self) -> None:
        """SIGKILL every process group: a test cluster has nothing to save, and a graceful close waits
        seconds for each worker (the nanny's grace period)."""
        for proc in [*self.workers, self.scheduler]:
            if proc is not None and proc.poll() is None:
                try:
                    os.killpg(proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        for proc in [*self.workers, self.scheduler]:
            if proc is not None:
                proc.wait(timeout=30)
