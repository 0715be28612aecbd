"""A values file: ``instance.variable: value`` lines (one FMU alone: ``variable: value``), one design point.

What a tuning hands on: ``dse-runner rank OUT --best-values tuned.yaml`` writes the best point
of a sweep, ``dse-runner simulate MODEL --values tuned.yaml`` runs it again. The model below is
the file format; names are checked against the FMUs when the values are used.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import yaml
from pydantic import RootModel

from ..yamlfile import read_yaml
from .variables import FiniteValue, Value


class ValuesFile(RootModel[dict[str, FiniteValue]]):
    """``{instance.variable: value}``: numbers, booleans or strings, every number finite."""


def read_values(path: str | Path) -> dict[str, Value]:
    """The values of a values file; errors name the file and the key."""
    return read_yaml(Path(path), ValuesFile, "values file").root


def write_values(path: str | Path, values: Mapping[str, Value], header: str = "") -> Path:
    """``values`` as a values file, in the given order, after an optional comment ``header``."""
    path = Path(path)
    plain = ValuesFile.model_validate(dict(values)).root  # what read_values will accept, checked now
    path.parent.mkdir(parents=True, exist_ok=True)
    comment = "".join(f"# {line}\n" for line in header.splitlines())
    path.write_text(comment + yaml.safe_dump(plain, sort_keys=False, default_flow_style=False))
    return path.resolve()
