"""A user's script checked for Python 2 before anything runs, and ported when it is.

INTO-CPS's published user scripts (its DSE ``externalScripts``) are Python 2:
``print x``, ``unicode(...)``, ``except IOError, e``. dse-runner runs scripts
with Python 3, where such a script fails every task with a traceback that
does not say why. :func:`check` reads the script when the spec loads and
names the first line that is Python 2, or the line Python 3 cannot compile.
:func:`as_python3` then ports a Python 2 script with fissix (the maintained
fork of lib2to3, 2to3's engine) and our fixers for what fissix leaves
(python2_fixers.py: ``open(f, 'rU')``, csv on binary files, the ``string``
module's functions, Python 2's integer division, ...), so that it runs as
Python 2 ran it: the run uses the ported text, line for line the user's, the
user's file is never changed, and only a script that still is not Python 3
once ported is refused, naming its line, so that no task runs. A Python 3
script gets only what Python 3.11 refuses of earlier Python 3 (``'rU'``,
``time.clock()``).
"""

from __future__ import annotations

import ast
import re
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import DseError

if TYPE_CHECKING:
    from .python2_fixers import Fix

PORT = "dse-runner runs scripts with Python 3 (docs/intocps.md)"

# Why Python 3 could not compile a line: its message, then the line itself; each with what it is.
MESSAGES = [
    (re.compile(r"Missing parentheses in call to 'print'"), "print statement"),
    (re.compile(r"Missing parentheses in call to 'exec'"), "exec statement"),
]
LINES = [
    (re.compile(r"^\s*print\b\s*(>>|[^\s(=.,)\]}:;])"), "print statement"),
    (re.compile(r"^\s*exec\b\s+[\"'\w]"), "exec statement"),
    (re.compile(r"\bexcept\s+[^:]+,\s*\w+\s*:"), "except X, e"),
    (re.compile(r"\braise\s+[\w.]+\s*,"), "raise X, message"),
    (re.compile(r"<>"), "the <> operator"),
    (re.compile(r"\b\d+[lL]\b"), "a long literal such as 10L"),
    (re.compile(r"(?<![\w.])0\d+\b"), "an octal literal such as 0777"),
    (re.compile(r"`"), "backquotes for repr"),
    (re.compile(r"\bur['\"]"), "a ur'...' string"),
]
# Builtins and modules Python 3 no longer has: such a script compiles, then fails when it gets there.
BUILTINS = {
    "unicode",
    "xrange",
    "basestring",
    "raw_input",
    "unichr",
    "long",
    "execfile",
    "reduce",
    "cmp",
    "reload",
    "apply",
    "buffer",
    "intern",
    "coerce",
    "file",
}
# Attributes Python 3 does not have, of a module the script imports as itself, which fissix ports (the string
# module's, which ours port, are python2_fixers.STRING_REMOVED)
ATTRIBUTES = {("sys", "maxint"), ("os", "getcwdu")}
METHODS = {"has_key", "iteritems", "iterkeys", "itervalues"}
MODULES = {
    "urllib2",
    "urlparse",
    "ConfigParser",
    "StringIO",
    "cStringIO",
    "cPickle",
    "Queue",
    "Tkinter",
    "__builtin__",
    "httplib",
    "HTMLParser",
    "SocketServer",
    "commands",
    "exceptions",
}


def as_python3(code: str, path: Path) -> tuple[str, str | None]:
    """The text to run, and, if it was ported, what made it need porting and what the port did, as the line
    that tells the user (None: it runs as written)."""
    try:
        check(code, path)
    except DseError as refused:
        ported = _ported(code, path, python2=True)
        if ported is None:
            raise
        text, fixes = ported
        try:
            check(text, path)
        except DseError as still:
            raise DseError(
                f"{refused}; ported by fissix it is still not Python 3: {str(still).removeprefix(f'{path} ')}"
            ) from None
        because = str(refused).removeprefix(f"{path} ").split(";")[0]
        also = f" (and {_listed(fixes)})" if fixes else ""
        return text, f"{because}; ported to Python 3 with fissix for this run{also}, the file unchanged"
    ported = _ported(code, path, python2=False)
    if ported is None or not ported[1] or _fails(ported[0], path):  # what fissix cannot parse runs as written
        return code, None
    return ported[0], f"{_listed(ported[1])}; ported for this run, the file unchanged"


def _fails(code: str, path: Path) -> bool:
    """Whether :func:`check` refuses ``code`` (a port of a Python 3 script must not break it)."""
    try:
        check(code, path)
    except DseError:
        return True
    return False


def _ported(code: str, path: Path, python2: bool) -> tuple[str, list[Fix]] | None:
    """``code`` through fissix's fixers and ours (python2_fixers.py), or None if fissix cannot parse it.
    fissix is loaded here, on first use: a space without a script objective never loads it."""
    import logging

    from fissix.pgen2.parse import ParseError
    from fissix.pgen2.tokenize import TokenError

    from . import python2_fixers

    logging.getLogger("RefactoringTool").setLevel(logging.ERROR)  # it logs each fixer it loads
    try:
        return python2_fixers.port(code, str(path), python2)
    except (ParseError, TokenError, SyntaxError, IndentationError):
        return None


LISTED = 3  # kinds of change a port's line names, each by its first change


def _listed(fixes: list[Fix]) -> str:
    """What the port changed: the first change of each kind (fixer), and how many more there are."""
    first: dict[str, Fix] = {}
    for fix in fixes:
        first.setdefault(fix.fixer, fix)
    shown = list(first.values())[:LISTED]
    more = len(fixes) - len(shown)
    return "; ".join(f"line {f.line}: {f.what}" for f in shown) + (f"; {more} more" if more else "")


def check(code: str, path: Path) -> None:
    """Raise a one-line DseError if ``code`` is Python 2, or is not Python 3 that compiles."""
    try:
        with warnings.catch_warnings():  # invalid escapes and the like are the script's own business
            warnings.simplefilter("ignore")
            tree = compile(code, str(path), "exec", ast.PyCF_ONLY_AST, dont_inherit=True)
            compile(tree, str(path), "exec", dont_inherit=True)  # what only the compiler finds
    except (SyntaxError, ValueError) as e:  # ValueError: a null byte, before Python 3.12
        raise DseError(_syntax_message(e, code, path)) from None
    found = python2_names(tree)
    if found:
        line, what = found
        raise DseError(f"{path} line {line}: a Python 2 script ({what}); {PORT}")


def _syntax_message(error: SyntaxError | ValueError, code: str, path: Path) -> str:
    """A Python 2 construct where Python 3 stopped, named; any other syntax error as Python says it."""
    line = getattr(error, "lineno", None) or 1
    lines = code.splitlines()
    text = lines[line - 1] if 0 < line <= len(lines) else ""
    message = getattr(error, "msg", str(error))
    found = [what for pattern, what in MESSAGES if pattern.search(message)]
    found += [what for pattern, what in LINES if pattern.search(text)]
    if found:
        return f"{path} line {line}: a Python 2 script ({found[0]}); {PORT}"
    return f"{path} line {line}: not valid Python 3: {message}"


def python2_names(tree: ast.Module) -> tuple[int, str] | None:
    """The first line (and what it uses) that calls on what only Python 2 has: a builtin the script
    does not define itself, a dict method, a module, or ``print`` alone on a line. Code under a
    ``try`` that catches its absence (``except ImportError``) is a script made for both."""
    from .python2_fixers import STRING_REMOVED

    attributes = ATTRIBUTES | {("string", name) for name in STRING_REMOVED}
    bound, guarded, modules = _bound(tree), _guarded(tree), _modules(tree)
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if id(node) in guarded:
            continue
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load) and node.id in BUILTINS - bound:
            found.append((node.lineno, f"{node.id}(), which Python 3 does not have"))
        elif isinstance(node, ast.Attribute) and node.attr in METHODS - bound:
            found.append((node.lineno, f".{node.attr}(), a dict method Python 3 does not have"))
        elif (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and (node.value.id, node.attr) in attributes
            and node.value.id in modules
        ):
            found.append((node.lineno, f"{node.value.id}.{node.attr}, which Python 3 does not have"))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            found += [
                (node.lineno, f"module {n}, which Python 3 renamed or removed")
                for n in names
                if n.split(".")[0] in MODULES
            ]
        elif isinstance(node, ast.Expr) and _is_print_statement(node.value):
            found.append((node.lineno, "print statement"))
    return min(found) if found else None


def _is_print_statement(value: ast.expr) -> bool:
    """``print`` or ``print >>f, x``: Python 3 compiles both as expressions that print nothing."""
    if isinstance(value, ast.Tuple) and value.elts:
        value = value.elts[0]
    if isinstance(value, ast.BinOp) and isinstance(value.op, ast.RShift):
        value = value.left
    return isinstance(value, ast.Name) and value.id == "print"


def _bound(tree: ast.Module) -> set[str]:
    """Every name the script defines: a compatibility shim (``unicode = str``) is not Python 2."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and not isinstance(node.ctx, ast.Load):
            names.add(node.id)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
        elif isinstance(node, ast.alias):
            names.add((node.asname or node.name).split(".")[0])
    return names


def _modules(tree: ast.Module) -> set[str]:
    """The modules the script imports under their own names (``import os, string``)."""
    return {
        alias.name.split(".")[0]
        for node in ast.walk(tree)
        if isinstance(node, ast.Import)
        for alias in node.names
        if alias.asname is None
    }


GUARDS = {"ImportError", "ModuleNotFoundError", "NameError", "AttributeError"}


def _guarded(tree: ast.Module) -> set[int]:
    """The nodes inside a ``try`` whose handlers catch a missing module, name or attribute."""
    guarded: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Try) and any(_catches(h.type) & GUARDS for h in node.handlers):
            guarded |= {id(inner) for statement in node.body for inner in ast.walk(statement)}
    return guarded


def _catches(kind: ast.expr | None) -> set[str]:
    if isinstance(kind, ast.Tuple):
        return set().union(*map(_catches, kind.elts))
    return {kind.id} if isinstance(kind, ast.Name) else set()
