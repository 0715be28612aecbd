"""One run of a space's model: ``dse-runner simulate SPACE.yaml`` runs what a sweep
of the space runs, at one point.

Why: a study's model is often written only in its space (an inline multi-model, instances named as the user
chose), so the values a sweep, a fit or a diagnosis writes (``rank --best-values``, ``diagnosed-values.yaml``)
name its variables as the space does. Replaying them needs the space's own model, experiment, scenarios and
objectives, not a model made anew from the FMU file under another instance name.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from ..errors import DseError, did_you_mean
from ..simulation import objectives as objs
from ..simulation.run import SimulationResult, simulate
from .search import Search
from .spec import read_spec, resolve_space


def is_space_file(path: Path) -> bool:
    """Whether ``path`` is a space.yaml (a YAML mapping with a ``multimodel`` key), not a model."""
    if path.suffix.lower() not in (".yaml", ".yml") or not path.is_file():
        return False
    try:
        data = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError):
        return False
    return isinstance(data, dict) and "multimodel" in data


def simulate_space(
    path: Path,
    scenario: str | Path | None,
    values: Mapping[str, Any],
    objectives: Mapping[str, objs.ObjectiveSpec] | None = None,
    start_time: float | None = None,
    stop_time: float | None = None,
    step: float | None = None,
    best: bool = False,
) -> SimulationResult:
    """The space's model run once on one of its scenarios (its only one, or the one named; a scenario folder
    also serves), with its single-valued parameters, then its sweep's best point if ``best``, then
    ``values``, scored by its objectives unless others are given. Its search strategy plays no part:
    intervals need no grid here."""
    spec = read_spec(path.resolve())
    space = resolve_space(spec.model_copy(update={"search": Search(strategy="given")}), path.resolve())
    if best:
        values = {**best_point(space.output, space.name), **values}
    by_name = {s.name: s for s in space.scenarios}
    if scenario is None:
        if len(by_name) != 1:
            raise DseError(
                f"{path}: the space has {len(by_name)} scenarios ({', '.join(by_name)}): name one with "
                "--scenario"
            )
        chosen: Any = next(iter(by_name.values()))
    elif str(scenario) in by_name:
        chosen = by_name[str(scenario)]
    elif Path(scenario).is_dir():
        chosen = Path(scenario)
    else:
        raise DseError(
            f"--scenario {scenario}: neither a scenario of {path} ({', '.join(by_name)}) nor a folder"
            f"{did_you_mean(str(scenario), by_name)}"
        )
    fixed = {name: points[0] for name, points in space.parameters.items() if len(points) == 1}
    return simulate(
        space.plan,
        chosen,
        {**fixed, **values},
        start_time,
        stop_time,
        step,
        objectives=dict(objectives) if objectives else space.objectives,
        experiment=space.experiment,
    )


def best_point(output: Any, sweep: str) -> dict[str, Any]:
    """The best point of ``sweep`` in the store ``output``, as ``dse-runner rank`` ranks it."""
    from .rank import rank  # pandas and the store: only when a best point is asked for

    try:
        return dict(rank(output, sweep).best)
    except DseError as e:
        raise DseError(f"--best: {e} (submit the space first, or give --values)") from None
