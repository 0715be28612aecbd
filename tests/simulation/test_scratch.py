"""A process's own temporary folders (simulation/scratch.py: its extracted FMUs, its unpacked shipments) go
when it exits, and only the process that made one removes it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

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
    done = subprocess.run([sys.executable, "-c", FORK_THEN_EXIT], capture_output=True, text=True,
                          env={**os.environ, "TMPDIR": str(tmp_path)}, timeout=120)
    assert done.returncode == 0, done.stderr
    folder, after_child = done.stdout.split()
    assert Path(folder).parent == tmp_path and after_child == "True"
    assert not Path(folder).exists()
