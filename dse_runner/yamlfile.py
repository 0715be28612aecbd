"""Our YAML files read into their pydantic models, every error one line naming the file.

The models are the formats (space.yaml, scenario.yaml, values and variants files); this is the one
way they are read, so a missing file, bad YAML and a bad value are worded alike everywhere.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, TypeAdapter, ValidationError

from .errors import DseError, format_syntax_error, format_validation_error

T = TypeVar("T")


def load_yaml(path: Path, what: str = "file") -> Any:
    """The file's YAML data (None for an empty file); ``what`` names it in
    the error for an unreadable file."""
    try:
        return yaml.safe_load(Path(path).read_text())
    except OSError as e:
        raise DseError(f"cannot read {what} {path}: {e.strerror}") from None
    except UnicodeDecodeError:
        hint = _binary_hint(Path(path))
        raise DseError(f"{path}: not a {what}: it is not text ({hint}a {what} is YAML)") from None
    except yaml.YAMLError as e:
        raise DseError(format_syntax_error(str(path), "YAML", e)) from None


def shape(value: Any) -> str:
    """A value's shape as a file gives it: "mapping" (or a model), "list", or "scalar" (a name, a number, a
    Boolean). Our formats' unions are told apart by it (pydantic's ``Discriminator``), so a wrong value gets
    the messages of the member its shape picks, not one per member."""
    if isinstance(value, (Mapping, BaseModel)):
        return "mapping"
    return "list" if isinstance(value, (list, tuple)) else "scalar"


@cache
def _adapter(shape: Any) -> TypeAdapter:
    return TypeAdapter(shape)


def validated(data: Any, shape: type[T], source: str) -> T:
    """``data`` as ``shape`` (a pydantic model or any type pydantic validates), errors naming ``source``."""
    try:
        return _adapter(shape).validate_python(data)
    except ValidationError as e:
        raise DseError(format_validation_error(source, e)) from None


def _binary_hint(path: Path) -> str:
    return "an FMU archive; " if path.suffix.lower() == ".fmu" else ""


def read_yaml(path: Path, shape: type[T], what: str = "file", empty: Any = None) -> T:
    """A YAML file validated as ``shape``; an empty file counts as ``empty``."""
    return as_format(load_yaml(path, what), shape, path, what, empty)


def as_format(data: Any, shape: type[T], path: Path, what: str = "file", empty: Any = None) -> T:
    """The data of the YAML file ``path`` validated as ``shape``. A file that is not a YAML mapping where one
    is expected (a CSV, a list) is one line saying so, not a validation error."""
    if data is not None and not isinstance(data, Mapping) and _wants_mapping(shape):
        found = (
            "a list"
            if isinstance(data, list)
            else "text that is not a YAML mapping (a CSV file?)"
            if (isinstance(data, str))
            else f"the single value {data!r:.40}"
        )
        raise DseError(
            f"{path}: not a {what}: a {what} is a YAML mapping of keys to values, this file holds {found}"
        )
    return validated(empty if data is None else data, shape, str(path))


def _wants_mapping(shape: Any) -> bool:
    """Whether ``shape`` reads a mapping: a pydantic model, or a root model of a dict."""
    if not (isinstance(shape, type) and issubclass(shape, BaseModel)):
        return False
    root = shape.model_fields.get("root")
    return root is None or getattr(root.annotation, "__origin__", None) is dict
