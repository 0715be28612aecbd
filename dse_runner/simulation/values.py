"""A values file: ``instance.variable: value`` lines (one FMU alone: ``variable: value``), one design point.

What a tuning hands on: ``dse-runner rank OUT --best-values tuned.yaml`` writes the best point
of a sweep, ``dse-runner simulate MODEL --values tuned.yaml`` runs it again. The model below is
the file format; names are checked against the FMUs when the values are used.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TypeVar

import yaml
from pydantic import RootModel

from ..errors import DseError
from ..yamlfile import as_format, load_yaml
from .variables import FiniteValue, Value

K = TypeVar("K")


class ValuesFile(RootModel[dict[str, FiniteValue]]):
    """``{instance.variable: value}``: numbers, booleans or strings, every number finite."""


def split_named(
    values: Mapping[str, object],
    parse: Callable[[str], K | None],
    what: str,
    allow: Callable[[K, float], bool] = lambda key, value: False,
) -> tuple[dict[str, object], dict[K, float]]:
    """A run's values split by name: those ``parse`` reads as master-side parameters (signal effects,
    derivative terms, state limits), each a finite number or one ``allow`` admits (``what`` names the kind
    in errors), and all the others."""
    plain: dict[str, object] = {}
    parsed: dict[K, float] = {}
    for name, value in values.items():
        key = parse(name)
        if key is None:
            plain[name] = value
        elif (
            not isinstance(value, (int, float))
            or isinstance(value, bool)
            or not (math.isfinite(value) or allow(key, float(value)))
        ):
            raise DseError(f"{name}: {what} is a finite number, not {value!r}")
        else:
            parsed[key] = float(value)
    return plain, parsed


def read_values(path: str | Path) -> dict[str, Value]:
    """The values of a values file; errors name the file and the key."""
    data = load_yaml(Path(path), "values file")
    if isinstance(data, dict) and "multimodel" in data:
        raise DseError(
            f"{path}: a space.yaml, not a values file: a values file holds instance.variable: "
            "value lines (rank --best-values and diagnose write them); run a space with "
            "simulate SPACE.yaml"
        )
    return as_format(data, ValuesFile, Path(path), "values file").root


def write_values(path: str | Path, values: Mapping[str, Value], header: str = "") -> Path:
    """``values`` as a values file, in the given order, after an optional comment ``header``."""
    path = Path(path)
    plain = ValuesFile.model_validate(dict(values)).root  # what read_values will accept, checked now
    path.parent.mkdir(parents=True, exist_ok=True)
    comment = "".join(f"# {line}\n" for line in header.splitlines())
    path.write_text(comment + yaml.safe_dump(plain, sort_keys=False, default_flow_style=False))
    return path.resolve()
