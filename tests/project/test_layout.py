"""The map holds: the core knows no case. Field data, GPS and cross-track live in their own module,
which only its own case's analysis (diagnose) imports; everything else reaches it as a plug-in."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import dse_runner

PACKAGE = Path(dse_runner.__file__).parent
CASE_MODULES = {"fielddata", "paths", "runinfo"}  # the Robotti field-data kind and GPS objectives; the path kind; their shared header
MAY_IMPORT_CASES = {"diagnose"}  # the Robotti diagnosis: a case's own analysis


def imported_modules(path: Path) -> set[str]:
    """The last dotted part of every module a file imports (relative or absolute, at any depth)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.module:
                names.add(node.module.rsplit(".", 1)[-1])
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.Import):
            names.update(alias.name.rsplit(".", 1)[-1] for alias in node.names)
    return names


def test_no_core_module_imports_the_field_data_case():
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        if path.stem in CASE_MODULES or MAY_IMPORT_CASES & set(path.relative_to(PACKAGE).parts):
            continue
        if imported_modules(path) & CASE_MODULES:
            offenders.append(str(path.relative_to(PACKAGE)))
    assert offenders == []


def _outside_diagnose(tree: ast.AST):
    """Every node, except inside the CLI's ``diagnose`` command (the diagnosis case's own interface)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.FunctionDef) and node.name == "diagnose":
            continue
        yield node
        stack.extend(ast.iter_child_nodes(node))


def test_gps_words_stay_in_the_case():
    """No core module names GPS or cross-track in its code (comments and docstrings may explain them)."""
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        if path.stem in CASE_MODULES or MAY_IMPORT_CASES & set(path.relative_to(PACKAGE).parts):
            continue
        for node in _outside_diagnose(ast.parse(path.read_text())):
            if isinstance(node, (ast.Name, ast.Attribute, ast.FunctionDef, ast.arg)):
                word = getattr(node, "id", None) or getattr(node, "attr", None) or getattr(node, "name", None) \
                    or getattr(node, "arg", "")
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
result = simulate({str(REPO / 'jobs' / 'watertank' / 'multimodel.yaml')!r}, stop_time=5, step=0.1)
print(sorted(m for m in sys.modules if m.startswith("dse_runner")))
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "fielddata" not in done.stdout and "cases.paths" not in done.stdout


LAYERS = ["simulation", "sweeps", "analysis", "interfaces"]


def test_each_layer_imports_only_the_layers_before_it():
    offenders = []
    for position, layer in enumerate(LAYERS):
        later = set(LAYERS[position + 1:]) | {"cases"}
        for path in (PACKAGE / layer).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ImportFrom) and node.level and node.module:
                    target = node.module.split(".")[0]
                    case_analysis = target == "cases" and MAY_IMPORT_CASES & set(path.parts)
                    if target in later and not case_analysis:
                        offenders.append(f"{path.relative_to(PACKAGE)} imports {node.module}")
    assert offenders == []


def test_the_import_graph_in_architecture_md_is_the_codes():
    """docs/architecture.md draws the package's imports; a change of imports must redraw it."""
    from conftest import REPO

    done = subprocess.run([sys.executable, str(REPO / "docs" / "import_graph.py"), "--check"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
