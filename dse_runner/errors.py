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


def close_names(name: str, options: Iterable[str], n: int = 3) -> list[str]:
    """The options closest to ``name``, those that differ from it only in case first: difflib alone finds
    ``UA`` no match for ``Ua`` (half their letters differ), though it is the likeliest meant."""
    options = [o for o in dict.fromkeys(options) if o != name]
    same = [o for o in options if o.casefold() == name.casefold()]
    folded: dict[str, list[str]] = {}
    for option in options:
        folded.setdefault(option.casefold(), []).append(option)
    near = difflib.get_close_matches(name.casefold(), list(folded), n=n)
    return list(dict.fromkeys([*same, *(o for f in near for o in folded[f])]))[:n]


def did_you_mean(name: str, options: Iterable[str]) -> str:
    """`` (did you mean a, b?)`` with the options closest to ``name``, or nothing if none is close."""
    close = close_names(name, options)
    return f" (did you mean {', '.join(close)}?)" if close else ""
