"""A process's own temporary folders (simulation/scratch.py: its extracted FMUs, its unpacked shipments) go
when it exits, and only the process that made one removes it; one its process could not remove (ended by
``os._exit`` or killed) goes when the next process makes a folder of its kind."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

FORK_THEN_EXIT = """
import os, sys
from dse_runner.simulation import scratch
folder = scratch.own_folder("dse-runner-test-")
child = os.fork()
if child == 0:
    sys.exit(0)  # a normal exit: runs the atexit registrations the child inherited
os.waitpid(child, 0)
print(folder, folder.is_dir())
"""


def test_a_process_folder_outlives_a_forked_child_and_goes_at_its_own_exit(tmp_path):
    done = subprocess.run(
        [sys.executable, "-c", FORK_THEN_EXIT],
        check=False,
        capture_output=True,
        text=True,
        env={**os.environ, "TMPDIR": str(tmp_path)},
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    folder, after_child = done.stdout.split()
    assert Path(folder).parent == tmp_path and after_child == "True"
    assert not Path(folder).exists()


IN_A_CHILD = """
import multiprocessing, sys
from dse_runner.simulation import scratch

def make(made):
    made.put(str(scratch.own_folder("dse-runner-test-")))

if __name__ == "__main__":
    context = multiprocessing.get_context(sys.argv[1])
    made = context.Queue()
    child = context.Process(target=make, args=(made,))
    child.start()
    print(made.get(), flush=True)
    child.join()
"""


@pytest.mark.parametrize("method", ["spawn", "fork", "forkserver"])
def test_a_multiprocessing_child_removes_its_folder_as_it_ends(tmp_path, method):
    """Dask's local workers are multiprocessing children, and the command line forks them from a forkserver:
    such a child leaves by os._exit, past the exit hooks, yet its folder goes."""
    script = tmp_path / "child.py"
    script.write_text(IN_A_CHILD)
    done = subprocess.run(
        [sys.executable, str(script), method],
        check=False,
        capture_output=True,
        text=True,
        env={**os.environ, "TMPDIR": str(tmp_path)},
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    folder = Path(done.stdout.strip())
    assert folder.parent == tmp_path and not folder.exists()


MAKE = """
import os, sys
from dse_runner.simulation import scratch
folder = scratch.own_folder("dse-runner-test-")
print(folder, flush=True)
if sys.argv[1] == "os._exit":  # as an isolated FMU's child ends: no exit hook runs
    os._exit(0)
sys.stdin.readline()  # "wait": lives until told
"""


def make(tmp_path: Path, how: str) -> subprocess.Popen:
    """A process that makes its folder, then ends by ``os._exit`` or waits for a line on stdin."""
    return subprocess.Popen(
        [sys.executable, "-c", MAKE, how],
        stdout=subprocess.PIPE,
        stdin=subprocess.PIPE,
        text=True,
        env={**os.environ, "TMPDIR": str(tmp_path)},
    )


def test_a_folder_its_process_could_not_remove_goes_when_the_next_process_makes_one(tmp_path):
    gone = make(tmp_path, "os._exit")
    left = Path(gone.stdout.readline().strip())
    assert gone.wait(timeout=120) == 0 and left.is_dir()  # os._exit: its folder stays behind
    alive = make(tmp_path, "wait")
    older = tmp_path / "dse-runner-test-1"  # a folder without a lock file: being made, or from before locks
    older.mkdir()
    try:
        own = Path(alive.stdout.readline().strip())
        assert own.is_dir() and not left.exists()  # the next process of the kind removed the orphan
        later = make(tmp_path, "os._exit")
        assert later.wait(timeout=120) == 0
        assert (
            own.is_dir() and older.is_dir()
        )  # a live process's folder stays, and so does one without a lock
    finally:
        alive.communicate("\n", timeout=120)
    assert not own.exists()  # removed at its normal exit


FORK_MID_CLAIM = """
import os, threading, time
from dse_runner.simulation import scratch
def claim():
    with scratch._CLAIMING:
        time.sleep(1)
claiming = threading.Thread(target=claim)
claiming.start()
time.sleep(0.2)  # another thread is making a folder when the process forks
child = os.fork()
if child == 0:
    print(scratch.own_folder("dse-runner-test-"), flush=True)
    os._exit(0)
os.waitpid(child, 0)
claiming.join()
"""


def test_a_child_forked_while_another_thread_makes_a_folder_makes_its_own(tmp_path):
    done = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", FORK_MID_CLAIM],
        check=False,
        capture_output=True,
        text=True,
        env={**os.environ, "TMPDIR": str(tmp_path)},
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert Path(done.stdout.strip()).parent == tmp_path
