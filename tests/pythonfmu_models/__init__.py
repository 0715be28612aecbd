"""Test models written with PythonFMU (pip install pythonfmu), a third-party FMI 2.0 exporter.

The folder is not called ``pythonfmu``: tests/ is on sys.path and would shadow the package.
PythonFMU's FMUs embed the Python that loads them, so they run in-process only in a Python built
with a shared libpython (sysconfig's Py_ENABLE_SHARED = 1, as pyenv's here and Debian's are).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
TYPES_SLAVE = HERE / "types_slave.py"


def build_pythonfmu(tmp_dir: str | Path, script: Path = TYPES_SLAVE) -> Path:
    """Build ``script``'s Fmi2Slave into ``tmp_dir`` with PythonFMU's command line; return the .fmu.

    A subprocess, because the builder imports the script and edits sys.path in the process it runs in.
    """
    target = Path(tmp_dir) / f"{script.stem}.fmu"
    target.parent.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(
        [sys.executable, "-m", "pythonfmu", "build", "-f", str(script), "-d", str(target)],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0 or not target.is_file():
        raise RuntimeError(f"pythonfmu build of {script.name} failed:\n{done.stdout}{done.stderr}")
    return target
