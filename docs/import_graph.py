"""Draws dse_runner's import graph from its code, as a Mermaid diagram grouped by layer.

    python docs/import_graph.py            # rewrites the diagram in docs/architecture.md
    python docs/import_graph.py --print    # prints it instead
    python docs/import_graph.py --check    # exit code 1 if docs/architecture.md's diagram is not the code's,
                                           # or if any modules import one another round a loop

Every ``import`` and ``from … import`` in every module of the package is read with ``ast`` (nothing is
imported, so no dependency needs to be installed). A node is a module; a subpackage below a layer
(``sweeps/strategies``, ``analysis/diagnose``, ``interfaces/dashboard``, ``interfaces/intocps``,
``cases/robotti_diagnosis``) is one node. An arrow A --> B says A
imports B at the top of the module; a dotted arrow, only inside a function or under ``TYPE_CHECKING`` (on
first use, so that starting the CLI does not load what a command does not need). ``errors``,
``plugins``, ``schema``, ``strict_json`` and ``yamlfile``, which every layer may import, are drawn without
their arrows. ``--check`` also fails on an import circle: modules that import one another round a loop,
deferred imports counted (deferring an import does not untie two modules).
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "dse_runner"
TARGET = ROOT / "docs" / "architecture.md"
START, END = "<!-- import-graph: start (docs/import_graph.py) -->", "<!-- import-graph: end -->"

LAYERS = ("simulation", "sweeps", "analysis", "interfaces", "cases")  # in the order they may import
COLLAPSED = (
    "sweeps.strategies",
    "analysis.diagnose",
    "interfaces.dashboard",
    "interfaces.intocps",
    "cases.robotti_diagnosis",
)
SHARED = (
    "errors",
    "plugins",
    "schema",
    "strict_json",
    "yamlfile",
)  # imported from everywhere: drawn without arrows
LEFT_OUT = ("__main__", "bundled")  # the entry point (imports cli) and the data package (imports nothing)


def module_name(path: Path) -> str:
    """``dse_runner/sweeps/rank.py`` -> ``sweeps.rank``; a package's ``__init__.py`` is the package."""
    parts = path.relative_to(PACKAGE).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def node_of(module: str) -> str:
    """The drawn node a module belongs to: itself, or the subpackage it is collapsed into."""
    return next((c for c in COLLAPSED if module == c or module.startswith(c + ".")), module)


def deferred_nodes(tree: ast.Module) -> set[int]:
    """ids of the import statements inside a function or an ``if TYPE_CHECKING:`` block."""
    found = set()
    for node in ast.walk(tree):
        inside = isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) or (
            isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
        )
        if inside:
            found.update(id(n) for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom)))
    return found


def targets(
    statement: ast.Import | ast.ImportFrom, importer: str, is_package: bool, modules: set[str]
) -> set[str]:
    """The package's modules one import statement names (``from . import x`` names module ``x``)."""
    if isinstance(statement, ast.Import):
        names = [
            a.name.removeprefix("dse_runner.") for a in statement.names if a.name.startswith("dse_runner.")
        ]
        return {n for n in names if n in modules}
    if statement.level:
        base = importer.split(".") if is_package else importer.split(".")[:-1]
        base = base[: len(base) - (statement.level - 1)] if statement.level > 1 else base
        module = ".".join(base + ([statement.module] if statement.module else []))
    elif statement.module and statement.module.startswith("dse_runner"):
        module = statement.module.removeprefix("dse_runner").removeprefix(".")
    else:
        return set()
    found = set()
    for alias in statement.names:
        submodule = f"{module}.{alias.name}" if module else alias.name
        found.add(submodule if submodule in modules else module)
    return {m for m in found if m in modules}


def package_files() -> dict[str, Path]:
    """Module name -> file, for every module of the package."""
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py")) if "__pycache__" not in p.parts}


def drawn(module: str) -> bool:
    """Whether a module is a node: not the root, not a layer's __init__.py (they hold no code worth an arrow;
    the root's is lazy), not the entry point or the data package."""
    return bool(module) and module.split(".")[0] not in LEFT_OUT and module not in LAYERS


def module_edges() -> dict[tuple[str, str], bool]:
    """Every import between two of the package's modules: (importer, imported) -> whether some import of it
    is at the top of the module (False: only inside a function or under ``TYPE_CHECKING``)."""
    files = package_files()
    modules = set(files) - {""}
    graph: dict[tuple[str, str], bool] = {}
    for module, path in files.items():
        if not drawn(module):
            continue
        tree = ast.parse(path.read_text())
        deferred = deferred_nodes(tree)
        for statement in ast.walk(tree):
            if not isinstance(statement, (ast.Import, ast.ImportFrom)):
                continue
            for target in targets(statement, module, path.name == "__init__.py", modules):
                if target == module or target in LAYERS or target.split(".")[0] in LEFT_OUT:
                    continue
                graph[(module, target)] = graph.get((module, target), False) or id(statement) not in deferred
    return graph


def edges() -> tuple[set[str], dict[tuple[str, str], bool]]:
    """The drawn nodes, and every edge (importer node, imported node) -> whether some import of it is at the
    top."""
    modules = module_edges()
    nodes = {node_of(module) for module in package_files() if drawn(module)}
    graph: dict[tuple[str, str], bool] = {}
    for (module, target), top in modules.items():
        a, b = node_of(module), node_of(target)
        if a == b or b in SHARED:
            continue
        graph[(a, b)] = graph.get((a, b), False) or top
    return nodes, graph


def circles(graph: dict[tuple[str, str], bool]) -> list[list[str]]:
    """The import circles: each set of modules that import one another round a loop (a strongly connected
    component of more than one module), by whatever import, deferred or not. Deferring an import does not
    untie two modules: each still needs the other."""
    following: dict[str, list[str]] = {}
    for a, b in graph:
        following.setdefault(a, []).append(b)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:  # Tarjan's algorithm
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in following.get(node, ()):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(following):
        if node not in index:
            visit(node)
    return sorted(found)


def node_id(name: str) -> str:
    return name.replace(".", "_")


def label(name: str) -> str:
    """What a node shows: its name inside its layer, a collapsed subpackage with a slash."""
    short = name.split(".", 1)[1] if "." in name else name
    return short + "/" if name in COLLAPSED else short


def layer_of(node: str) -> str:
    return node.split(".")[0]


def layers_mermaid(graph: dict[tuple[str, str], bool]) -> str:
    """The layers and how many module-to-module imports go from one to another."""
    counts: dict[tuple[str, str], list[bool]] = {}
    for (a, b), top in graph.items():
        if layer_of(a) != layer_of(b) and layer_of(b) in LAYERS:
            counts.setdefault((layer_of(a), layer_of(b)), []).append(top)
    lines = ["```mermaid", "flowchart LR"]
    lines.extend(f'  {layer}["{layer}/"]' for layer in LAYERS)
    for (a, b), tops in sorted(counts.items(), key=lambda e: (LAYERS.index(e[0][0]), LAYERS.index(e[0][1]))):
        arrow = "-->" if any(tops) else "-.->"
        lines.append(f"  {a} {arrow}|{len(tops)}| {b}")
    lines.append("```")
    return "\n".join(lines) + "\n"


def modules_mermaid(nodes: set[str], graph: dict[tuple[str, str], bool]) -> str:
    lines = ["```mermaid", "flowchart TB"]
    for layer in LAYERS:
        members = sorted(n for n in nodes if n.split(".")[0] == layer)
        lines.append(f'  subgraph {layer}["{layer}/"]')
        lines.extend(f'    {node_id(n)}["{label(n)}"]' for n in members)
        lines.append("  end")
    shared = [n for n in sorted(nodes) if n in SHARED]
    lines.append('  subgraph shared["imported from every layer"]')
    lines.extend(f'    {node_id(n)}["{n}"]' for n in shared)
    lines.append("  end")
    for (a, b), top in sorted(graph.items()):
        lines.append(f"  {node_id(a)} {'-->' if top else '-.->'} {node_id(b)}")
    lines.append("```")
    return "\n".join(lines) + "\n"


def mermaid() -> str:
    """What goes between the markers: the layers, then every module (folded, as it is large)."""
    nodes, graph = edges()
    return (
        f"{layers_mermaid(graph)}\n<details><summary>Every module ({len(nodes)} nodes, {len(graph)} "
        f"imports)</summary>\n\n{modules_mermaid(nodes, graph)}\n</details>\n"
    )


def replaced(text: str, diagram: str) -> str:
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    return f"{head}{START}\n{diagram}{END}{tail}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    action = parser.add_mutually_exclusive_group()
    action.add_argument("--print", action="store_true", help="print the diagram instead of writing it")
    action.add_argument(
        "--check",
        action="store_true",
        help="exit code 1 if architecture.md's diagram is stale or the package has an import circle",
    )
    args = parser.parse_args()
    tied = circles(module_edges())
    for circle in tied:
        print(f"import circle: {' -> '.join(circle)} (each imports another round a loop)", file=sys.stderr)
    diagram = mermaid()
    if args.print:
        sys.stdout.write(diagram)
        return 0
    text = TARGET.read_text()
    new = replaced(text, diagram)
    if args.check:
        if new != text:
            print(
                f"{TARGET}: the import graph is not the code's; run python docs/import_graph.py",
                file=sys.stderr,
            )
            return 1
        return 1 if tied else 0
    TARGET.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
