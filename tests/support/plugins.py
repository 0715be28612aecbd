"""Plug-ins registered for one test the way an installed package registers them: a module and a
``*.dist-info`` folder with its ``entry_points.txt``, on sys.path, which importlib.metadata reads like
any installed distribution's. Nothing is installed into the environment."""

from __future__ import annotations

import functools
import sys
import textwrap
from pathlib import Path

import pytest

from dse_runner import plugins


def register(
    monkeypatch: pytest.MonkeyPatch,
    folder: Path,
    module: str,
    source: str,
    entries: dict[str, dict[str, str]],
) -> None:
    """Write ``module`` (its ``source``) into ``folder`` with a distribution declaring ``entries``
    (group -> name -> ``module:attribute``), and put the folder first on sys.path for this test."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{module}.py").write_text(textwrap.dedent(source))
    info = folder / f"{module}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "".join(
            f"[{group}]\n" + "".join(f"{name} = {target}\n" for name, target in names.items()) + "\n"
            for group, names in entries.items()
        )
    )
    monkeypatch.syspath_prepend(str(folder))  # also invalidates the import system's caches
    monkeypatch.delitem(sys.modules, module, raising=False)
    # the registry reads the entry points once per process: this test reads them afresh, and the tests after
    # it get the registry as it was, without this plug-in
    monkeypatch.setattr(plugins, "entries", functools.cache(plugins.entries.__wrapped__))
