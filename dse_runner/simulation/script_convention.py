"""Which command line a user's script expects: with the scenario's data folder as its third argument or not.

INTO-CPS's DSE scripts call an external script as ``python SCRIPT FOLDER NAME DATA ARG...`` in every version
of theirs one can read (``processObjectiveExternalScripts`` in ``scripts/libs/Common.py``, Python 2 and 3
alike). Yet the scripts published with INTO-CPS's single- and three-tank examples read their first parameter
at ``sys.argv[3]``: they were written for a command line without ``DATA``, and under those DSE scripts
they read a folder's path where they expect a column name. No field of a DSE config tells the two apart
(both kinds of project write ``"scenarios": []``); the script itself does. A script whose fixed
``sys.argv`` indices end at ``2 + len(args)`` takes no data folder; one whose indices end at
``3 + len(args)`` takes it. Anything else (no fixed index, ``sys.argv[3:]``, indices that fit neither) cannot
be read: the data folder is passed, as INTO-CPS's DSE scripts pass it, and one line says so.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass


@dataclass(frozen=True)
class Convention:
    """Whether to pass the data folder, and, when the script could not tell, the line that says so."""

    data_folder: bool
    note: str | None = None


def highest_index(tree: ast.Module) -> int | None:
    """The highest ``sys.argv`` position the script reads at a fixed index or within a fixed slice; None when
    it reads none, or reads one it computes (``sys.argv[i]``, ``sys.argv[3:]``)."""
    found: list[int] = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Subscript) and _is_argv(node.value)):
            continue
        index = node.slice
        if isinstance(index, ast.Constant) and isinstance(index.value, int) and index.value >= 0:
            found.append(index.value)
        elif (
            isinstance(index, ast.Slice)
            and isinstance(index.upper, ast.Constant)
            and isinstance(index.upper.value, int)
            and index.step is None
        ):
            found.append(index.upper.value - 1)
        else:
            return None
    return max(found) if found else None


def _is_argv(node: ast.expr) -> bool:
    """``sys.argv``, or ``argv`` imported from sys."""
    if isinstance(node, ast.Attribute):
        return node.attr == "argv" and isinstance(node.value, ast.Name) and node.value.id == "sys"
    return isinstance(node, ast.Name) and node.id == "argv"


def convention(code: str, arguments: int, name: str) -> Convention:
    """What ``code`` (Python 3) expects, given the ``arguments`` it is passed after the fixed ones."""
    try:
        highest = highest_index(ast.parse(code))
    except SyntaxError:
        highest = None
    if highest == 3 + arguments:
        return Convention(True)
    if highest == 2 + arguments:
        return Convention(arguments == 0)  # with no parameters the data folder is harmless, and INTO-CPS's
    read = "reads no fixed sys.argv index" if highest is None else f"reads sys.argv up to [{highest}]"
    return Convention(
        True,
        f"{name} {read}, which fits neither command line for its {arguments} parameters: "
        "passing the scenario's data folder as its third argument, as INTO-CPS's DSE "
        "scripts do (data_folder: false leaves it out)",
    )
