"""The one exception type users catch: every message names its culprit."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

from pydantic import ValidationError


class DseError(Exception):
    """A problem with the user's input or model, with a message meant for them."""


def format_validation_error(source: str, error: ValidationError) -> str:
    """One line: the file, then each problem's key path and reason."""
    problems = []
    for problem in error.errors():
        where = ".".join(str(p) for p in problem["loc"])
        reason = problem["msg"].removeprefix("Value error, ")
        problems.append(f"{where}: {reason}" if where else reason)  # at the top: the file's own problem
    return f"{source}: " + "; ".join(problems)


def format_syntax_error(source: str, kind: str, error: Exception) -> str:
    """A YAML or JSON parser's complaint as one line: file, line, column, problem."""
    mark = getattr(error, "problem_mark", None)  # PyYAML
    if mark is not None:
        return f"{source} line {mark.line + 1}, column {mark.column + 1}: not valid {kind}: {error.problem}"
    if hasattr(error, "lineno"):  # json.JSONDecodeError
        return f"{source} line {error.lineno}, column {error.colno}: not valid {kind}: {error.msg}"
    return f"{source}: not valid {kind}: {' '.join(str(error).split())}"


def did_you_mean(name: str, options: Iterable[str]) -> str:
    """`` (did you mean a, b?)`` with the options closest to ``name``, or nothing if none is close."""
    close = difflib.get_close_matches(name, list(options), n=3)
    return f" (did you mean {', '.join(close)}?)" if close else ""
