"""What fissix leaves of a Python 2 script that Python 3.11 refuses, or runs otherwise: fixers of our own,
run in fissix's pass beside its own (python2.py), so that a ported script runs as Python 2 ran it.

fissix (2to3's engine) ports the syntax and the renamed builtins, modules and methods. It leaves:

- file modes with ``U`` (``open(f, 'rU')``, ``io.open``, ``codecs.open``, ``fileinput``), which Python 3.11
  refuses (``ValueError: invalid mode: 'rU'``); every text file has universal newlines since Python 3.0;
- a file opened in binary for ``csv`` (the csv module's own advice in Python 2) or written by ``json.dump``:
  Python 3's csv reads and writes text, and ``json.dump`` writes text;
- the ``string`` module's functions and constants that Python 3 dropped (``string.join``, ``string.split``,
  ``string.atof``, ``string.letters``, ...), ``file()``, ``cmp()`` and ``time.clock()``;
- ``/``, which floored between integers in Python 2 and does not in Python 3 (unless the script imports
  ``division`` from ``__future__``).

Each fixer records what it changed (:class:`Fix`). ``/`` and ``cmp`` call helpers bound at the top of the
ported text (PRELUDE); :func:`keep_lines` then puts every statement a fixer added (ours, and fissix's
imports such as ``from functools import reduce``) on a line of its own neighbours, so that line N of the
ported text is line N of the user's file, as tracebacks and failed rows name it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from fissix import pygram, pytree
from fissix.fixer_base import BaseFix
from fissix.fixer_util import Call, Comma, KeywordArg, Name, String, find_binding, find_root
from fissix.pgen2 import driver, token
from fissix.refactor import RefactoringTool, get_fixers_from_package

syms = pygram.python_symbols


@dataclass(frozen=True)
class Fix:
    """One change a fixer of ours made: its line in the user's file, and what it did (the fixer's name: its
    kind of change)."""

    line: int
    what: str
    fixer: str


# Helpers the ported text calls, each bound in one statement (a lambda, not a def: it can share a line)
PRELUDE = {
    "_py2_div": (
        "_py2_div = lambda a, b: a // b if all(isinstance(v, __import__('numbers').Integral) or "
        "getattr(getattr(v, 'dtype', None), 'kind', '') in ('i', 'u') for v in (a, b)) "
        "else __import__('operator').truediv(a, b)"
    ),
    "_py2_cmp": "_py2_cmp = lambda a, b: (a > b) - (a < b)",
}


def port(code: str, filename: str, python2: bool) -> tuple[str, list[Fix]]:
    """``code`` through fissix's fixers and ours (``python2``), or through only those of ours that a Python 3
    script may need (Python 3.11 refuses what earlier Python 3 accepted); what ours changed. Raises fissix's
    ParseError (or SyntaxError) if fissix cannot parse it."""
    fixes: list[Fix] = []
    tool = _Tool(
        get_fixers_from_package("fissix.fixes") if python2 else [],
        OURS if python2 else PYTHON3,
        {"print_function": not python2, "fixes": fixes},
    )
    tree = tool.refactor_string(code if code.endswith("\n") else code + "\n", filename)
    keep_lines(tree)
    return str(tree), sorted(fixes, key=lambda f: f.line)


class _Tool(RefactoringTool):
    """fissix's refactoring tool with our fixer classes beside the fixers it loads by module name."""

    def __init__(self, names: list[str], ours: list[type[BaseFix]], options: dict) -> None:
        self.ours = ours
        super().__init__(names, options)

    def get_fixers(self):
        pre, post = super().get_fixers()
        for kind in self.ours:
            fixer = kind(self.options, self.fixer_log)
            (pre if fixer.order == "pre" else post).append(fixer)
        return sorted(pre, key=lambda f: f.run_order), sorted(post, key=lambda f: f.run_order)


class _Fixer(BaseFix):
    """A fixer of ours: records each change with the line it was on."""

    def record(self, node: pytree.Base, what: str) -> None:
        self.options["fixes"].append(Fix(_line(node), what, type(self).__name__))

    def helper(self, node: pytree.Base, name: str) -> None:
        """Bind helper ``name`` (PRELUDE) before the script's first statement that runs, once."""
        root = find_root(node)
        if any(_binds(child, name) for child in root.children):
            return
        statement = driver.Driver(pygram.python_grammar, convert=pytree.convert).parse_string(
            PRELUDE[name] + "\n"
        )
        added = statement.children[0]
        for leaf in added.leaves():
            leaf.lineno = 0  # added: keep_lines puts it on a neighbour's line
        added.remove()
        root.insert_child(_first_run(root), added)


def imports(root: pytree.Node, module: str) -> bool:
    """Whether the script imports ``module`` under its own name anywhere (``import os, string``)."""
    for node in root.pre_order():
        if node.type == syms.import_name:
            for name in str(node.children[1]).split(","):
                words = name.split()
                if words and (words[-1] if "as" in words else words[0].split(".")[0]) == module:
                    return True
    return False


def _binds(statement: pytree.Base, name: str) -> bool:
    return (
        statement.type == syms.simple_stmt
        and statement.children[0].type == syms.expr_stmt
        and statement.children[0].children[0].type == token.NAME
        and statement.children[0].children[0].value == name
    )


def _line(node: pytree.Base) -> int:
    return next((leaf.lineno for leaf in node.leaves() if leaf.lineno), 0)


def _first_run(root: pytree.Node) -> int:
    """Where a helper goes: before the first statement that runs when the module does, past the docstring,
    the ``from __future__`` imports and the functions defined before it (their bodies run later, when called;
    not one with default values, which run now), so that keep_lines can put it on that statement's line."""
    for index, child in enumerate(root.children):
        first = child.children[0] if child.type == syms.simple_stmt else None
        docstring = first is not None and first.type == token.STRING and index == 0
        header = docstring or (first is not None and _future(first))
        defined = child.type == syms.funcdef and "=" not in str(child.children[2])
        if not (header or defined):
            return index
    return len(root.children)


def _future(node: pytree.Base) -> bool:
    return node.type == syms.import_from and str(node.children[1]).strip() == "__future__"


def _arguments(trailer: pytree.Node) -> tuple[list[pytree.Base], dict[str, pytree.Base]]:
    """A call's positional arguments and its keyword arguments' values, from its ``( ... )`` trailer."""
    inner = trailer.children[1:-1]
    if not inner:
        return [], {}
    items = (
        [c for c in inner[0].children if c.type != token.COMMA]
        if inner[0].type == syms.arglist
        else [inner[0]]
    )
    positional, keywords = [], {}
    for item in items:
        if item.type == syms.argument and len(item.children) == 3 and item.children[1].type == token.EQUAL:
            keywords[item.children[0].value] = item.children[2]
        elif item.type == syms.argument or (item.type == token.STAR or item.type == token.DOUBLESTAR):
            return [], {}  # *args, **kwargs or a generator: nothing to read
        else:
            positional.append(item)
    return positional, keywords


def _mode(trailer: pytree.Node, position: int | None) -> pytree.Leaf | None:
    """The string literal a call (its ``( ... )``) gives as its mode, at ``position`` or as ``mode=``."""
    positional, keywords = _arguments(trailer)
    mode = keywords.get("mode")
    if mode is None and position is not None and len(positional) > position:
        mode = positional[position]
    literal = isinstance(mode, pytree.Leaf) and mode.type == token.STRING and _literal(mode) is not None
    return mode if literal else None


LITERAL = re.compile(r"([uUrR]?)('|\")([^'\"\\]*)\2$")


def _literal(leaf: pytree.Leaf) -> str | None:
    """The text of a plain one-quote string literal (a mode, ``'rU'``), else None."""
    match = LITERAL.match(leaf.value)
    return match[3] if match else None


def _set_literal(leaf: pytree.Leaf, text: str) -> None:
    match = LITERAL.match(leaf.value)
    leaf.value = f"{match[1]}{match[2]}{text}{match[2]}"
    leaf.changed()


def _without_u(mode: str) -> str:
    """A mode without ``U``: reading, unless the mode says otherwise (``'U'`` alone read in Python 2)."""
    kept = mode.replace("U", "")
    return kept if any(c in kept for c in "rwax") else "r" + kept


class FixFileModes(_Fixer):
    """``open(f, 'rU')``, ``'Ur'``, ``'U'``, ``'rbU'``; ``io.open``, ``codecs.open``, ``file`` likewise, and
    ``fileinput``'s ``mode=``: the mode without its ``U``."""

    PATTERN = """
    power< ('open' | 'file') call=trailer< '(' [any] ')' > any* >
    | power< ('io' | 'codecs') trailer< '.' 'open' > call=trailer< '(' [any] ')' > any* >
    | power< 'fileinput' trailer< '.' ('input' | 'FileInput') > call=trailer< '(' [any] ')' > any* >
    """

    def transform(self, node, results):
        fileinput = node.children[0].value == "fileinput"
        mode = _mode(results["call"], None if fileinput else 1)
        if mode is None or "U" not in _literal(mode):
            return
        old = _literal(mode)
        _set_literal(mode, _without_u(old))
        self.record(mode, f"open mode {old!r} -> {_literal(mode)!r} (Python 3.11 refuses 'U')")


def _opened(node: pytree.Base) -> pytree.Node | None:
    """``node`` if it is a call of open (or file, io.open) and nothing more, else None."""
    if node.type != syms.power or node.children[-1].type != syms.trailer:
        return None
    head = [str(c).strip() for c in node.children[:-1]]
    called = node.children[-1].children[0].value == "("
    return node if called and head in (["open"], ["file"], ["io", ".open"]) else None


def _bound_opens(root: pytree.Node, name: str) -> list[pytree.Node]:
    """The open calls anywhere in the script whose file ``name`` is: ``with open(...) as name`` and
    ``name = open(...)``."""
    found = []
    for node in root.pre_order():
        if node.type == syms.with_item and len(node.children) == 3 and str(node.children[2]).strip() == name:
            found.append(_opened(node.children[0]))
        elif (
            node.type == syms.expr_stmt
            and len(node.children) == 3
            and node.children[1].type == token.EQUAL
            and str(node.children[0]).strip() == name
        ):
            found.append(_opened(node.children[2]))
    return [call for call in found if call is not None]


class FixTextFiles(_Fixer):
    """A file opened in binary that ``csv.reader``, ``csv.writer``, ``csv.DictReader``, ``csv.DictWriter``
    or ``json.dump`` is given: opened as text, for csv with ``newline=''`` as Python 3's csv asks (Python 2's
    binary mode kept its ``\\r\\n`` too). The file is the call itself, or a name the script binds to one
    with ``with ... as name`` or ``name = ...``."""

    PATTERN = """
    power< module='csv' trailer< '.' ('reader' | 'writer' | 'DictReader' | 'DictWriter') >
           call=trailer< '(' any ')' > any* >
    | power< module='json' trailer< '.' 'dump' > call=trailer< '(' any ')' > any* >
    """

    def transform(self, node, results):
        positional, keywords = _arguments(results["call"])
        consumer = results["module"].value
        where = 0 if consumer == "csv" else 1  # csv's file comes first, json.dump's second (or fp=)
        handle = keywords.get("fp", positional[where] if len(positional) > where else None)
        if handle is None:
            return
        opens = [_opened(handle)] if _opened(handle) else []
        if not opens and handle.type == token.NAME:
            opens = _bound_opens(find_root(node), handle.value)
        for call in opens:
            mode = _mode(call.children[-1], 1)
            if mode is None or "b" not in _literal(mode):
                continue
            old = _literal(mode)
            _set_literal(mode, _without_u(old).replace("b", ""))
            if consumer == "csv" and "newline" not in _arguments(call.children[-1])[1]:
                _add_keyword(call.children[-1], "newline", String("''"))
            what = "csv" if consumer == "csv" else "json.dump"
            self.record(
                mode, f"open mode {old!r} -> {_literal(mode)!r} for {what} (Python 3's {what} is text)"
            )


def _add_keyword(trailer: pytree.Node, name: str, value: pytree.Base) -> None:
    """Append ``name=value`` to a call's arguments."""
    argument = KeywordArg(Name(name), value)
    argument.prefix = " "
    inner = trailer.children[1]
    if inner.type == syms.arglist:
        inner.append_child(Comma())
        inner.append_child(argument)
    else:
        inner.replace(pytree.Node(syms.arglist, [inner.clone(), Comma(), argument]))


STRING_NAMES = {"letters": "ascii_letters", "lowercase": "ascii_lowercase", "uppercase": "ascii_uppercase"}
STRING_NUMBERS = {"atof": "float", "atoi": "int", "atol": "int"}
STRING_METHODS = {
    **{m: m for m in ("split", "rsplit", "strip", "lstrip", "rstrip", "lower", "upper", "swapcase")},
    **{m: m for m in ("capitalize", "replace", "find", "rfind", "index", "rindex", "count", "expandtabs")},
    **{m: m for m in ("ljust", "rjust", "center", "zfill")},
    "splitfields": "split",
}
STRING_REMOVED = {*STRING_NAMES, *STRING_NUMBERS, *STRING_METHODS, "join", "joinfields", "maketrans"}


class FixStringModule(_Fixer):
    """The ``string`` module's functions and constants that Python 3 dropped, as Python 3 spells them:
    ``string.join(words, sep)`` as ``sep.join(words)``, ``string.split(s, ...)`` as ``s.split(...)``,
    ``string.atof(s)`` as ``float(s)``, ``string.letters`` as ``string.ascii_letters``,
    ``string.maketrans`` as ``str.maketrans``. Only in a script that imports ``string``."""

    PATTERN = "power< 'string' trailer< '.' name=NAME > rest=any* >"

    def transform(self, node, results):
        name = results["name"].value
        if name not in STRING_REMOVED or not imports(find_root(node), "string"):
            return
        rest = [r.clone() for r in results["rest"]]
        call = rest[0] if rest and rest[0].children[0].value == "(" else None
        if name in STRING_NAMES:
            results["name"].replace(Name(STRING_NAMES[name]))
            self.record(node, f"string.{name} -> string.{STRING_NAMES[name]}")
            return
        if name == "maketrans":
            node.children[0].replace(Name("str", prefix=node.children[0].prefix))
            self.record(node, "string.maketrans -> str.maketrans")
            return
        if call is None:
            return
        positional, keywords = _arguments(call)
        if keywords or not positional:
            return
        if name in STRING_NUMBERS:
            new = [Name(STRING_NUMBERS[name]), *rest]
            what = f"string.{name}(...) -> {STRING_NUMBERS[name]}(...)"
        elif name in ("join", "joinfields"):
            words, separator = positional[0], positional[1] if len(positional) > 1 else String('" "')
            method = [pytree.Node(syms.trailer, [pytree.Leaf(token.DOT, "."), Name("join")])]
            new = [_receiver(separator), *method, _call([words]), *rest[1:]]
            what = f"string.{name}(words, sep) -> sep.join(words)"
        else:
            method = [pytree.Node(syms.trailer, [pytree.Leaf(token.DOT, "."), Name(STRING_METHODS[name])])]
            new = [_receiver(positional[0]), *method, _call(positional[1:]), *rest[1:]]
            what = f"string.{name}(s, ...) -> s.{STRING_METHODS[name]}(...)"
        replacement = pytree.Node(syms.power, new)
        replacement.prefix = node.prefix
        node.replace(replacement)
        self.record(replacement, what)


def _receiver(node: pytree.Base) -> pytree.Base:
    """``node`` to put before ``.method(...)``: in parentheses unless a name, a literal or a call chain."""
    node = node.clone()
    node.prefix = ""
    plain = node.type in (token.NAME, token.STRING, syms.atom) or (
        node.type == syms.power and not any(c.type == token.DOUBLESTAR for c in node.children)
    )
    return (
        node
        if plain
        else pytree.Node(syms.atom, [pytree.Leaf(token.LPAR, "("), node, pytree.Leaf(token.RPAR, ")")])
    )


def _call(arguments: list[pytree.Base]) -> pytree.Node:
    """A ``( ... )`` trailer of ``arguments`` (cloned, comma-separated)."""
    items: list[pytree.Base] = []
    for i, argument in enumerate(arguments):
        argument = argument.clone()
        argument.prefix = " " if i else ""
        items += [Comma(), argument] if i else [argument]
    inner = [pytree.Node(syms.arglist, items)] if len(items) > 1 else items
    return pytree.Node(syms.trailer, [pytree.Leaf(token.LPAR, "("), *inner, pytree.Leaf(token.RPAR, ")")])


class FixBuiltins(_Fixer):
    """``file(...)`` as ``open(...)``; ``cmp(a, b)`` as Python 2's (a helper): unless the script binds the
    name itself."""

    PATTERN = "power< name=NAME trailer< '(' [any] ')' > any* >"

    def transform(self, node, results):
        name = results["name"]
        if name.value not in ("file", "cmp") or find_binding(name.value, find_root(node)):
            return
        if name.value == "file":
            name.replace(Name("open", prefix=name.prefix))
            self.record(node, "file(...) -> open(...)")
        else:
            name.replace(Name("_py2_cmp", prefix=name.prefix))
            self.helper(node, "_py2_cmp")
            self.record(node, "cmp(a, b) -> Python 2's cmp")


class FixTimeClock(_Fixer):
    """``time.clock()``, which Python 3.8 removed, as ``time.perf_counter()``: the clock to time a span by."""

    PATTERN = "power< 'time' trailer< '.' name='clock' > trailer< '(' ')' > any* >"

    def transform(self, node, results):
        if not imports(find_root(node), "time"):
            return
        results["name"].replace(Name("perf_counter"))
        self.record(node, "time.clock() -> time.perf_counter() (Python 3.8 removed time.clock)")


class FixOldDivision(_Fixer):
    """``a / b`` and ``a /= b`` as Python 2 divided: floored when both are integers (numbers.Integral, or
    NumPy integer arrays), true division otherwise; a helper decides at run time, as only then are the
    operands' types known. Not in a script that imports ``division`` from ``__future__``."""

    PATTERN = "term< any+ > | expr_stmt< any '/=' any >"

    def start_tree(self, tree, filename):
        super().start_tree(tree, filename)
        self.future = any(
            _future(node) and "division" in re.findall(r"\w+", str(node)) for node in tree.pre_order()
        )

    def transform(self, node, results):
        if self.future or (node.type == syms.term and not any(c.type == token.SLASH for c in node.children)):
            return
        if not _line(node):  # what a fixer added (a helper)
            return
        self.helper(node, "_py2_div")
        self.record(node, "/ -> Python 2's division (floored between integers)")
        if node.type == syms.expr_stmt:
            target, operator, value = node.children
            divided = Call(Name("_py2_div"), [_bare(target), Comma(), _spaced(value)], prefix=value.prefix)
            assign = pytree.Leaf(token.EQUAL, "=", prefix=operator.prefix)
            node.replace(pytree.Node(syms.expr_stmt, [target.clone(), assign, divided]))
        else:
            first, *rest = node.children
            done: list[pytree.Base] = [first.clone()]
            for operator, operand in zip(rest[::2], rest[1::2], strict=True):
                if operator.type == token.SLASH:
                    left = done[0] if len(done) == 1 else pytree.Node(syms.term, done)
                    done = [Call(Name("_py2_div"), [_bare(left), Comma(), _spaced(operand)])]
                else:
                    done += [operator.clone(), operand.clone()]
            new = done[0] if len(done) == 1 else pytree.Node(syms.term, done)
            new.prefix = node.prefix
            node.replace(new)


def _bare(node: pytree.Base) -> pytree.Base:
    node = node.clone()
    node.prefix = ""
    return node


def _spaced(node: pytree.Base) -> pytree.Base:
    node = node.clone()
    node.prefix = " "
    return node


OURS: list[type[BaseFix]] = [
    FixFileModes,
    FixTextFiles,
    FixStringModule,
    FixBuiltins,
    FixTimeClock,
    FixOldDivision,
]
PYTHON3: list[type[BaseFix]] = [FixFileModes, FixTimeClock]  # what a Python 3 script may need on Python 3.11


def keep_lines(root: pytree.Node) -> None:
    """Put each statement a fixer added at the top level (its leaves have no line) on the line of the
    statement before it (``import sys; from functools import reduce``), or of the one after it: the ported
    text then has the user's lines where the user has them. One with no simple statement beside it keeps a
    line of its own."""
    merged = True
    while merged:  # each merge changes the children: look again from the start
        merged = False
        for statement in root.children:
            if _added(statement) and _merge(statement):
                merged = True
                break


def _added(statement: pytree.Base) -> bool:
    return statement.type == syms.simple_stmt and not any(leaf.lineno for leaf in statement.leaves())


def _merge(statement: pytree.Node) -> bool:
    """Move ``statement`` onto a neighbouring simple statement's line; whether it could."""
    body = [c.clone() for c in statement.children[:-1]]  # without its newline
    before, after = statement.prev_sibling, statement.next_sibling
    if before is not None and before.type == syms.simple_stmt:
        at = len(before.children) - (before.children[-1].type == token.NEWLINE)  # before its newline
        if all(c.type == token.NEWLINE and not c.value for c in before.children[:at]):
            # a line a fixer emptied (fissix's of a __future__ import): the statement takes it
            body[0].prefix = before.children[0].prefix
            for child in before.children[:at]:
                child.remove()
            at, joined = 0, body
        else:
            body[0].prefix = " "
            ended = before.children[at - 1].type == token.SEMI  # ``import sys;`` has its semicolon
            joined = body if ended else [pytree.Leaf(token.SEMI, ";"), *body]
        for i, child in enumerate(joined):
            before.insert_child(at + i, child)
        statement.remove()
        return True
    if after is not None and after.type == syms.simple_stmt and after.children:
        body[0].prefix = after.prefix
        after.prefix = " "
        for i, child in enumerate([*body, pytree.Leaf(token.SEMI, ";")]):
            after.insert_child(i, child)
        statement.remove()
        return True
    return False
