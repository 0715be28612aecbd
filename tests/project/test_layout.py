"""The map holds: the core knows no case. Field data, GPS, cross-track and the Robotti's diagnosis live in
cases/; the core reaches them only as plug-ins (entry points), and the layers import only downwards."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import dse_runner

PACKAGE = Path(dse_runner.__file__).parent
CASES = PACKAGE / "cases"  # the Robotti's field-data kind, GPS objectives and diagnosis; the path kind


def core_modules():
    """Every module outside cases/: the layers and the package's own top-level modules."""
    return [p for p in PACKAGE.rglob("*.py") if CASES not in p.parents]


def imported_modules(path: Path) -> set[str]:
    """Every module a file imports, as an absolute dotted name (relative imports resolved from the file's
    package; ``from a import b`` counts as ``a`` and ``a.b``, b being a module or a name in a)."""
    package = ".".join(("dse_runner", *path.relative_to(PACKAGE).parent.parts))
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
            module = node.module or "" if node.level == 0 else ".".join(filter(None, (base, node.module)))
            names.add(module)
            names.update(f"{module}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return names


def test_no_core_module_imports_a_case():
    offenders = [
        f"{path.relative_to(PACKAGE)}: {name}"
        for path in core_modules()
        for name in sorted(imported_modules(path))
        if name == "dse_runner.cases" or name.startswith("dse_runner.cases.")
    ]
    assert offenders == []


def test_gps_words_stay_in_the_case():
    """No core module names GPS or cross-track in its code (comments and docstrings may explain them)."""
    offenders = []
    for path in core_modules():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Name, ast.Attribute, ast.FunctionDef, ast.arg)):
                word = (
                    getattr(node, "id", None)
                    or getattr(node, "attr", None)
                    or getattr(node, "name", None)
                    or getattr(node, "arg", "")
                )
                words = [w.lower() for w in re.findall(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+", word)]
                if "gps" in words or "cross_track" in word.lower():  # Optuna's GPSampler is GP + Sampler
                    offenders.append(f"{path.relative_to(PACKAGE)}: {word}")
    assert offenders == []


def test_a_plain_fmu_study_runs_without_loading_the_case(tmp_path):
    """Simulating a plain multi-model, scored by its default objectives, never loads a case's module."""
    from conftest import REPO

    script = f"""
import sys
from dse_runner.simulation.run import simulate
result = simulate({str(REPO / "jobs" / "watertank" / "multimodel.yaml")!r}, stop_time=5, step=0.1)
print(sorted(m for m in sys.modules if m.startswith("dse_runner")))
"""
    done = subprocess.run(
        [sys.executable, "-c", script], check=False, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert "fielddata" not in done.stdout and "cases.paths" not in done.stdout


LAYERS = ["simulation", "sweeps", "analysis", "interfaces"]


def test_each_layer_imports_only_the_layers_before_it():
    offenders = []
    for position, layer in enumerate(LAYERS):
        later = set(LAYERS[position + 1 :]) | {"cases"}
        for path in (PACKAGE / layer).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ImportFrom) and node.level and node.module:
                    target = node.module.split(".")[0]
                    if target in later:
                        offenders.append(f"{path.relative_to(PACKAGE)} imports {node.module}")
    assert offenders == []


def test_the_import_graph_in_architecture_md_is_the_codes():
    """docs/architecture.md draws the package's imports; a change of imports must redraw it, and no modules
    may import one another round a loop (the check fails on a circle, deferred imports included)."""
    from conftest import REPO

    done = subprocess.run(
        [sys.executable, str(REPO / "docs" / "import_graph.py"), "--check"],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stdout + done.stderr


def test_the_graph_check_finds_a_circle_however_its_imports_are_deferred():
    """What --check calls a circle: modules that import one another round a loop, a deferred import (inside a
    function, under TYPE_CHECKING) counted like any other; a chain that never comes back is none."""
    import importlib.util

    from conftest import REPO

    loaded = importlib.util.spec_from_file_location("import_graph", REPO / "docs" / "import_graph.py")
    graph = importlib.util.module_from_spec(loaded)
    loaded.loader.exec_module(graph)
    deferred = {
        ("sweeps.spec", "sweeps.makers"): True,
        ("sweeps.makers", "sweeps.uncertainty"): True,
        ("sweeps.uncertainty", "sweeps.spec"): False,
        ("sweeps.rank", "sweeps.spec"): True,
    }
    assert graph.circles(deferred) == [["sweeps.makers", "sweeps.spec", "sweeps.uncertainty"]]
    assert graph.circles({k: v for k, v in deferred.items() if k[0] != "sweeps.uncertainty"}) == []


def test_the_wheel_lists_every_package_and_takes_the_fmu_sources_from_the_top_level():
    """pyproject.toml lists the packages one by one (the FMU sources are mapped in from the top-level fmus/,
    which a search of dse_runner/ cannot find): a package folder left off the list would be missing from the
    wheel, and the FMU sources are kept once, at the top level."""
    import tomllib

    from conftest import REPO

    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    folders = {".".join(p.parent.relative_to(REPO).parts) for p in (REPO / "dse_runner").rglob("__init__.py")}
    assert set(setuptools["packages"]) == folders | {"dse_runner.bundled.fmus"}
    assert setuptools["package-dir"] == {"dse_runner.bundled.fmus": "fmus"}
    assert (REPO / "fmus" / "common" / "slave.c").is_file() and not (PACKAGE / "bundled" / "fmus").exists()
