"""The test suite's wall time beside the CPU time it needs: how close a machine's cores can bring it.

    python benchmarks/test_suite.py [-- PYTEST_ARGS...]      # default: the README's command, pytest -q
    python benchmarks/test_suite.py --by-file 30 [-- ...]    # one process, CPU per test file
    python benchmarks/test_suite.py --by-process 12 [-- ...] # CPU per kind of process: workers, commands

Runs the tests as the README does (``.venv``'s python, ``-m pytest -q`` plus any arguments given after
``--``) in a subprocess and prints, side by side:

* ``wall``: the run's wall time;
* ``cpu``: the CPU seconds the machine spent busy over the run (``/proc/stat``, every core): the tests'
  processes, their Dask schedulers and workers, the commands they run, the browser, the Slurm daemons and
  jobs; other work counts too, so run it on a quiet machine;
* ``cpu_own``: the CPU seconds of the run's own processes and everything they started, counted by
  the kernel in a cpuacct control group of its own (cgroup v1, as root; absent elsewhere): the
  machine's background (kernel threads reclaiming memory, other work) left out; on a quiet machine it
  is a few seconds under ``cpu``;
* ``cpu_waited``: the CPU seconds of the processes the run started and waited for (``getrusage``), a lower
  bound: processes that end otherwise (killed, reaped by others) are not counted;
* ``floor``: ``cpu`` spread over every core, the least wall time this CPU work can take here, and its
  ratio to the issue's target of 8 minutes.

Before and after the run, a **speed probe** runs one process per core at once, each a fixed piece of plain
Python (JSON out and back, a sort, a sum over 5000 rows, ``PROBE_ROUNDS`` times) that uses nothing of the
package, so that a change to the package cannot move it; it prints its CPU seconds, and the run's CPU in
probes (``cpu_in_probes``: its own CPU over the probes' mean). This shared machine's speed drifts by half
with nothing else running: one diagnosis took 16.6 client CPU seconds at 11:42 and 36.0 after the 13:29 run,
on one day and the same code. The probe tells a slow machine from slow code, but only roughly: the suite's
work is not the probe's, and the two do not slow alike (docs/performance.md), so compare runs made close
together. (Until 2026-11-26 17:00 the probe simulated the Robotti, whose FMU was then made faster: figures
in probes from before then are in other units.)
``--no-probe`` skips it.

``--timeline`` adds, per test process, the test files that ran longest with their start and end (seconds
into the run), and the machine's busy share in every 30 s of the run with the core-seconds left idle: which
files ran side by side when the cores were not full (plugin benchmarks/test_timeline.py).

``--by-process N`` adds the N kinds of process that used the most CPU over the run, each with how many ran
(plain Python reading /proc every 0.25 s: a process is counted up to its last sample): the test processes, the
Dask workers their clusters spawned, the schedulers, dse-runner's commands by subcommand, the browser; a
process a forkserver forked (the commands' Dask workers) shows the server's command line: it is counted apart.

``--by-file N`` runs the tests in one process (``-n 0``, with the plugin benchmarks/cpu_per_test.py) and adds
the N test files that cost the machine the most CPU seconds, each with its wall time: where to look first.
``--json`` prints the figures as JSON; ``--log FILE`` keeps pytest's whole output, which a failed run always
keeps (in a temporary folder) and names, beside its failed tests. Why it exists: the suite's wall time is
its CPU work over the cores it keeps busy; speeding it up means less work or busier cores, and this tells
which is left.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TARGET = 8 * 60.0  # s: issue 29's full suite, quiet


def busy_jiffies() -> tuple[int, int]:
    """(busy, total) jiffies of the whole machine so far."""
    with open("/proc/stat") as f:
        fields = [int(x) for x in f.readline().split()[1:]]
    idle = fields[3] + fields[4]  # idle + iowait
    return sum(fields) - idle, sum(fields)


CPUACCT = Path("/sys/fs/cgroup/cpuacct")


def own_group(name: str = "dse-test-suite") -> Path | None:
    """A cpuacct control group ``name``-PID for the run, or None where this
    machine does not let us make one."""
    group = CPUACCT / f"{name}-{os.getpid()}"
    try:
        group.mkdir()
    except OSError:
        return None
    return group


def group_cpu(group: Path | None) -> float | None:
    """CPU seconds used so far by every process that has been in ``group``."""
    return int((group / "cpuacct.usage").read_text()) / 1e9 if group else None


PROBE_ROUNDS = (
    200  # 5.4 CPU s here at 17:05 on 2026-11-26, when 200 runs of the Robotti took 5.2 (half speed)
)
PROBE = f"""
import json, random, time
rng = random.Random(0)
rows = [{{"task": i, "x": rng.random(), "name": f"p{{i}}"}} for i in range(5000)]
started = time.process_time()
for _ in range({PROBE_ROUNDS}):
    back = json.loads(json.dumps(rows))
    back.sort(key=lambda r: r["x"])
    total = sum(r["x"] * r["task"] for r in back)
print(time.process_time() - started)
"""


def speed_probe(python: str, cores: int) -> float:
    """CPU seconds of the probe's PROBE_ROUNDS rounds, the mean of one probe per core run at once:
    the machine's speed now, which on a shared machine drifts by half with nothing else of ours
    running (docs/performance.md)."""
    probes = [
        subprocess.Popen([python, "-c", PROBE], cwd=REPO, stdout=subprocess.PIPE, text=True)
        for _ in range(cores)
    ]
    return sum(float(p.communicate()[0]) for p in probes) / cores


def close_group(group: Path | None, grace: float = 10.0) -> float | None:
    """The group's CPU seconds once its last process has ended (a forkserver or a worker may outlive pytest by
    a moment, and its CPU is the run's), then the group removed; a process still alive after ``grace`` seconds
    leaves it behind."""
    if group is None:
        return None
    deadline = time.monotonic() + grace
    while (group / "tasks").read_text().strip() and time.monotonic() < deadline:
        time.sleep(0.2)
    cpu = group_cpu(group)
    try:
        group.rmdir()
    except OSError:  # still in use
        pass
    return cpu


class BusySampler(threading.Thread):
    """The machine's busy share in each second, while the run lasts."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.shares: list[float] = []
        self.stopping = threading.Event()

    def run(self) -> None:
        busy, total = busy_jiffies()
        while not self.stopping.wait(1.0):
            now_busy, now_total = busy_jiffies()
            self.shares.append((now_busy - busy) / max(now_total - total, 1))
            busy, total = now_busy, now_total


class ProcessSampler(threading.Thread):
    """Every process started after the run began, with the CPU seconds it had used when last seen (/proc,
    every ``period`` seconds): where the suite's CPU goes by kind of process. A process is counted up to
    its last sample, so one that lives less than a period, and what a process used after its last sample,
    are missed."""

    def __init__(self, period: float = 0.25) -> None:
        super().__init__(daemon=True)
        self.period = period
        self.since = _boot_ticks()
        # (pid, start tick) -> (command line, CPU s, parent's pid)
        self.seen: dict[tuple[str, int], tuple[str, float, str]] = {}
        self.stopping = threading.Event()

    def run(self) -> None:
        while not self.stopping.wait(self.period):
            self.sample()

    def sample(self) -> None:
        tick = os.sysconf("SC_CLK_TCK")
        for pid in filter(str.isdigit, os.listdir("/proc")):
            try:
                stat = Path(f"/proc/{pid}/stat").read_text()
                fields = stat[stat.rfind(")") + 2 :].split()  # after the command name, which may hold spaces
                cpu, start, parent = (int(fields[11]) + int(fields[12])) / tick, int(fields[19]), fields[1]
                if start < self.since:
                    continue
                # read every time, since a child seen between its fork and its exec still shows its parent's
                # line; but kept once the process has ended, when it shows none (a zombie's)
                raw = Path(f"/proc/{pid}/cmdline").read_bytes()
                command = raw.replace(b"\0", b" ").decode(errors="replace")
                kept = self.seen.get((pid, start), ("",))[0]
                self.seen[(pid, start)] = (command.strip() or kept, cpu, parent)
            except (OSError, IndexError, ValueError):  # ended between the listing and the read
                continue

    def by_kind(self) -> list[dict]:
        """CPU seconds and process count per kind of process (:func:`process_kind`), the costliest first;
        kernel threads (no command line) left out."""
        kinds: dict[str, dict] = {}
        commands = {pid: command for (pid, _), (command, _, _) in self.seen.items()}
        for command, cpu, parent in self.seen.values():
            if command:
                # a forkserver's children show the server's command line: it forked them
                forked = FORKSERVER in command and commands.get(parent) == command
                kind = FORKED if forked else process_kind(command)
                entry = kinds.setdefault(kind, {"kind": kind, "processes": 0, "cpu_s": 0.0})
                entry["processes"] += 1
                entry["cpu_s"] += cpu
        ranked = sorted(kinds.values(), key=lambda e: -e["cpu_s"])
        return [{**e, "cpu_s": round(e["cpu_s"], 1)} for e in ranked]


def _boot_ticks() -> int:
    """Clock ticks since boot now: the unit of a process's start time in /proc/PID/stat."""
    return int(float(Path("/proc/uptime").read_text().split()[0]) * os.sysconf("SC_CLK_TCK"))


FORKSERVER = "multiprocessing.forkserver"
FORKED = "forked by a forkserver (the commands' Dask workers, tests/support/wild.py's runs)"
PROCESS_KINDS = (  # (what the command line holds, the kind), first match wins
    ("spawn_main", "Dask worker processes (a nanny's or a local cluster's)"),
    ("exec(eval(sys.stdin.readline()))", "pytest-xdist's test processes"),
    (" -m pytest", "pytest"),
    ("dask_scheduler", "Dask schedulers (dask scheduler)"),
    ("dask_worker", "Dask nannies (dask worker)"),
    ("dse_runner.simulation.isolation", "FMU isolation processes"),
    (FORKSERVER, "multiprocessing forkservers"),
    ("resource_tracker", "multiprocessing resource trackers"),
    ("chrom", "the browser (Chromium)"),
    ("playwright", "the browser's driver (Playwright)"),
    ("slurm", "Slurm daemons"),
)


def process_kind(command: str) -> str:
    """A readable kind for a process's command line: dse-runner's commands by subcommand, other Python by its
    module or script, any other program by its name."""
    words = command.split()
    for marker in ("-m dse_runner ", "dse-runner "):
        if marker in command:
            rest = command.split(marker, 1)[1].split()
            return f"dse-runner {rest[0] if rest else ''}".strip()
    for marker, kind in PROCESS_KINDS:
        if marker in command:
            return kind
    program = Path(words[0]).name if words else "?"
    return _python_kind(words[1:]) if program.startswith("python") else program


def _python_kind(args: list[str]) -> str:
    """``python -m MODULE``, ``python -c`` or ``python SCRIPT``: what the interpreter's arguments run."""
    k = 0
    while k < len(args) and args[k].startswith("-") and args[k] not in ("-m", "-c"):
        k += 2 if args[k] in ("-X", "-W") else 1  # options that take a value
    if k >= len(args):
        return "python"
    if args[k] == "-m":
        return f"python -m {args[k + 1]}" if k + 1 < len(args) else "python -m"
    return "python -c" if args[k] == "-c" else f"python {Path(args[k]).name}"


def timeline(folder: Path, started: float, shares: list[float], cores: int, longest: float = 10.0) -> dict:
    """Per test process, its files of more than ``longest`` seconds (start and end, seconds into the run);
    the machine's busy share per 30 s; the core-seconds the run left idle."""
    processes: dict[str, list[dict]] = {}
    for path in sorted(folder.glob("*.txt")):
        spans: dict[str, list[float]] = {}
        for line in path.read_text().splitlines():
            start, end, nodeid = line.split(" ", 2)
            span = spans.setdefault(nodeid.split("::")[0], [float(start), float(end)])
            span[0], span[1] = min(span[0], float(start)), max(span[1], float(end))
        processes[path.stem] = [
            {"file": name, "start_s": round(a - started, 1), "end_s": round(b - started, 1)}
            for name, (a, b) in sorted(spans.items(), key=lambda kv: kv[1][0])
            if b - a > longest
        ]
    windows = [shares[i : i + 30] for i in range(0, len(shares), 30)]
    return {
        "processes": processes,
        "busy_per_30_s": [round(sum(w) / len(w), 2) for w in windows],
        "idle_core_s": round(sum((1 - share) * cores for share in shares), 1),
    }


def by_file(rows: list[list]) -> list[dict]:
    """Per-test rows (nodeid, CPU s, wall s) summed per test file, the costliest first."""
    files: dict[str, dict] = {}
    for nodeid, cpu, wall in rows:
        name = nodeid.split("::")[0]
        entry = files.setdefault(name, {"file": name, "cpu_s": 0.0, "wall_s": 0.0, "tests": 0})
        entry["cpu_s"] += cpu
        entry["wall_s"] += wall
        entry["tests"] += 1
    ranked = sorted(files.values(), key=lambda e: -e["cpu_s"])
    return [{**e, "cpu_s": round(e["cpu_s"], 1), "wall_s": round(e["wall_s"], 1)} for e in ranked]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--by-file",
        type=int,
        default=0,
        metavar="N",
        help="one test process; list the N test files that cost the most CPU",
    )
    parser.add_argument(
        "--timeline",
        action="store_true",
        help="which test files ran side by side, and how busy the machine was meanwhile",
    )
    parser.add_argument(
        "--by-process",
        type=int,
        default=0,
        metavar="N",
        help="the N kinds of process that used the most CPU (workers, schedulers, commands)",
    )
    parser.add_argument(
        "--no-probe", action="store_true", help="skip the speed probes before and after the run"
    )
    parser.add_argument(
        "--log", type=Path, help="keep pytest's whole output here (on a failure it is always kept)"
    )
    parser.add_argument("pytest_args", nargs="*", help="after --: arguments added to pytest -q")
    args = parser.parse_args()
    python = REPO / ".venv" / "bin" / "python"
    command = [str(python if python.exists() else sys.executable), "-m", "pytest", "-q", *args.pytest_args]
    env = dict(os.environ)
    per_test = Path(tempfile.mkdtemp()) / "cpu_per_test.json" if args.by_file else None
    if per_test:
        command += ["-n", "0", "-p", "cpu_per_test"]
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO / "benchmarks"), env.get("PYTHONPATH")]))
        env["CPU_PER_TEST_OUT"] = str(per_test)
    lines = Path(tempfile.mkdtemp()) if args.timeline else None
    if lines:
        command += ["-p", "test_timeline"]
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO / "benchmarks"), env.get("PYTHONPATH")]))
        env["TEST_TIMELINE_DIR"] = str(lines)
    cores = os.cpu_count() or 1
    probes = [speed_probe(command[0], cores)] if not args.no_probe else []
    sampler = BusySampler() if lines else None
    processes = ProcessSampler() if args.by_process else None
    group = own_group()
    join = (lambda: (group / "tasks").write_text(str(os.getpid()))) if group else None
    before_cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
    busy0, total0 = busy_jiffies()
    started, started_at = time.perf_counter(), time.time()
    if sampler:
        sampler.start()
    if processes:
        processes.start()
    done = subprocess.run(
        command, cwd=REPO, capture_output=True, text=True, check=False, env=env, preexec_fn=join
    )
    wall = time.perf_counter() - started
    if sampler:
        sampler.stopping.set()
    if processes:
        processes.stopping.set()
        processes.join()
        processes.sample()
    busy1, total1 = busy_jiffies()
    after_cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
    waited = (after_cpu.ru_utime - before_cpu.ru_utime) + (after_cpu.ru_stime - before_cpu.ru_stime)
    cpu = (busy1 - busy0) / os.sysconf("SC_CLK_TCK")
    own = close_group(group)
    if probes:
        probes.append(speed_probe(command[0], cores))
    figures = {
        "command": " ".join(command[1:]),
        "exit_code": done.returncode,
        "summary": (done.stdout.strip().splitlines() or [""])[-1],
        "failures": [line for line in done.stdout.splitlines() if line.startswith(("FAILED ", "ERROR "))],
        "wall_s": round(wall, 1),
        "cpu_s": round(cpu, 1),
        "cpu_own_s": round(own, 1) if own is not None else None,
        "cpu_waited_s": round(waited, 1),
        "cores": cores,
        "machine_busy": round((busy1 - busy0) / max(total1 - total0, 1), 3),
        "floor_s": round(cpu / cores, 1),
        "target_s": TARGET,
        "floor_over_target": round(cpu / cores / TARGET, 2),
        "wall_over_floor": round(wall / (cpu / cores), 2) if cpu else None,
        "probe_s": [round(p, 2) for p in probes],
        "cpu_in_probes": round((own if own is not None else cpu) / (sum(probes) / len(probes)), 1)
        if probes
        else None,
    }
    if per_test and per_test.exists():
        figures["by_file"] = by_file(json.loads(per_test.read_text()))[: args.by_file]
        shutil.rmtree(per_test.parent)
    if processes:
        figures["by_process"] = processes.by_kind()[: args.by_process]
    if lines:
        figures["timeline"] = timeline(lines, started_at, sampler.shares, cores)
        shutil.rmtree(lines)
    if args.log or done.returncode != 0:  # a failure under the suite's load is worth its whole story
        log = args.log or Path(tempfile.mkdtemp(prefix="test-suite-")) / "pytest.log"
        log.write_text(done.stdout + done.stderr)
        figures["log"] = str(log)
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        print(f"{figures['command']}: {figures['summary']} (exit {done.returncode})")
        mine = f"{own:.0f} s in its own processes, " if own is not None else ""
        print(
            f"wall {wall:.0f} s; CPU {cpu:.0f} s busy on {cores} cores (machine "
            f"{figures['machine_busy']:.0%} busy; {mine}{waited:.0f} s in processes it "
            f"waited for): floor {cpu / cores:.0f} s = {figures['floor_over_target']}x the "
            f"{TARGET / 60:.0f}-minute target; wall = {figures['wall_over_floor']}x the floor"
        )
        if probes:
            print(
                f"speed probe ({PROBE_ROUNDS} rounds, one per core at once): {probes[0]:.2f} CPU s before, "
                f"{probes[1]:.2f} after; the run's {'own ' if own is not None else ''}CPU = "
                f"{figures['cpu_in_probes']} probes"
            )
        for line in figures["failures"]:
            print(line)
        if "log" in figures:
            print(f"pytest's whole output: {figures['log']}")
        if "timeline" in figures:
            for process, files in figures["timeline"]["processes"].items():
                print(
                    f"{process}: "
                    + (
                        "; ".join(f"{f['start_s']:.0f}-{f['end_s']:.0f} s {f['file']}" for f in files)
                        or "no file over 10 s"
                    )
                )
            print(
                "machine busy per 30 s: " + " ".join(f"{b:.2f}" for b in figures["timeline"]["busy_per_30_s"])
            )
            print(f"idle over the run: {figures['timeline']['idle_core_s']:.0f} core-seconds")
        for row in figures.get("by_process", []):
            print(f"{row['cpu_s']:8.1f} CPU s {row['processes']:6d} processes  {row['kind']}")
        for row in figures.get("by_file", []):
            print(
                f"{row['cpu_s']:8.1f} CPU s {row['wall_s']:8.1f} "
                f"s wall {row['tests']:5d} tests  {row['file']}"
            )
    sys.exit(0 if done.returncode == 0 else 1)


if __name__ == "__main__":
    main()
