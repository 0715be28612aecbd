"""Constraints as safe expressions: between parameters, e.g. ``vehicle.mass / 1000 < 2 * vehicle.mu + 1``,
or on objectives (a ranking's ``constraints``, e.g. ``level_max < 2.4``).

An expression is parsed once with :mod:`ast` and only a small grammar is
accepted: numbers, parameter names (``instance.variable``), arithmetic,
comparisons, ``and``/``or``/``not``, and the functions ``abs``, ``min``,
``max``. Anything else (calls, attributes of other things, subscripts) is
rejected when the spec is loaded, so nothing is ever ``eval``-ed.
"""

from __future__ import annotations

import ast
import operator
from collections.abc import Callable, Mapping

from ..errors import DseError

Values = Mapping[str, float]  # named numbers: a design point's (domain.Point), or a result's objectives
Evaluate = Callable[[Values], object]

_BINARY = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
    ast.Mod: operator.mod,
    ast.FloorDiv: operator.floordiv,
}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos, ast.Not: operator.not_}
_COMPARE = {
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
}
_FUNCTIONS = {"abs": abs, "min": min, "max": max}


def _dotted(node: ast.AST) -> str | None:
    """``vehicle.mass`` parses as Attribute(Name('vehicle'), 'mass'): give back the dotted name."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        head = _dotted(node.value)
        return f"{head}.{node.attr}" if head else None
    return None


def _compile(node: ast.AST, names: set[str], text: str, what: str = "parameter") -> Evaluate:
    def reject(what: str) -> DseError:
        return DseError(f"constraint {text!r}: {what} is not allowed")

    if isinstance(node, ast.Expression):
        return _compile(node.body, names, text, what)
    if (
        isinstance(node, ast.Constant)
        and isinstance(node.value, (int, float))
        and not isinstance(node.value, bool)
    ):
        value = node.value
        return lambda p: value
    if isinstance(node, (ast.Name, ast.Attribute)):
        name = _dotted(node)
        if name not in names:
            kind = "swept parameter" if what == "parameter" else what
            raise DseError(
                f"constraint {text!r}: {name or ast.unparse(node)!r} is not a {kind} "
                f"({what}s: {', '.join(sorted(names))})"
            )
        return lambda p: p[name]
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        op = _BINARY[type(node.op)]
        left, right = _compile(node.left, names, text, what), _compile(node.right, names, text, what)
        return lambda p: op(left(p), right(p))
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        op, operand = _UNARY[type(node.op)], _compile(node.operand, names, text, what)
        return lambda p: op(operand(p))
    if isinstance(node, ast.BoolOp):
        parts = [_compile(v, names, text, what) for v in node.values]
        if isinstance(node.op, ast.And):
            return lambda p: all(part(p) for part in parts)
        return lambda p: any(part(p) for part in parts)
    if isinstance(node, ast.Compare) and all(type(op) in _COMPARE for op in node.ops):
        terms = [_compile(node.left, names, text, what)] + [
            _compile(c, names, text, what) for c in node.comparators
        ]
        ops = [_COMPARE[type(op)] for op in node.ops]

        def compare(p: Values) -> bool:
            values = [term(p) for term in terms]
            return all(op(a, b) for op, a, b in zip(ops, values, values[1:]))

        return compare
    if (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id in _FUNCTIONS
        and not node.keywords
    ):
        function, args = _FUNCTIONS[node.func.id], [_compile(a, names, text, what) for a in node.args]
        return lambda p: function(*(arg(p) for arg in args))
    raise reject(f"{type(node).__name__} ({ast.unparse(node)!r})")


def compile_constraint(text: str, parameters: set[str], what: str = "parameter") -> Evaluate:
    """Check ``text`` against the grammar and the names it may use (``what`` they are, for the
    message); return its evaluator."""
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as e:
        raise DseError(f"constraint {text!r}: not an expression ({e.msg})") from None
    return _compile(tree, parameters, text, what)
