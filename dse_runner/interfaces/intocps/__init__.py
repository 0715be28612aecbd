"""INTO-CPS projects run unchanged (docs/intocps.md).

* formats.py: the dse.json and coe.json as pydantic models (the mm.json is
  read by simulation/multimodel.py);
* project.py: where a DSE's multi-model and co-simulation config are, found
  the way the INTO-CPS application associates them;
* convert.py: a DSE config, its mm.json and coe.json made one of our
  space specs, which the rest of the tool runs like any space.yaml;
* results.py: INTO-CPS's result files (dseResults.csv, results.html,
  ranking.json, graphs/pareto.png) written from our ranking.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from ...errors import DseError
from ...sweeps.spec import Space, SpaceSpec, resolve_space
from .convert import IntoCpsWarning, to_spec
from .project import locate

if TYPE_CHECKING:  # the ranking's pandas only for result files: `submit` names a bad spec without it
    from ...sweeps import store

__all__ = ["IntoCpsWarning", "convert", "is_dse_config", "load_space", "write_result_files"]


def is_dse_config(path: str | Path) -> bool:
    """INTO-CPS names its DSE configs ``<name>.dse.json``."""
    return str(path).lower().endswith(".dse.json")


def load_space(dse: str | Path, multimodel: str | Path | None = None, coe: str | Path | None = None) -> Space:
    """An INTO-CPS DSE config as a checked space, ready to submit; paths relative to its folder."""
    located = locate(Path(dse), _path(multimodel), _path(coe))
    return resolve_space(to_spec(located, located.dse.parent), located.dse)


def convert(
    dse: str | Path, output: str | Path, multimodel: str | Path | None = None, coe: str | Path | None = None
) -> Path:
    """Write the space.yaml equivalent to an INTO-CPS DSE config; it is loaded once to check it."""
    output = Path(output).resolve()
    output.parent.mkdir(parents=True, exist_ok=True)
    located = locate(Path(dse), _path(multimodel), _path(coe))
    spec = to_spec(located, output.parent)
    resolve_space(spec, output)
    data = spec.model_dump(mode="json", exclude_none=True, exclude_defaults=True)
    header = (
        f"# Converted from the INTO-CPS DSE config {located.dse.name} by dse-runner convert-intocps\n"
        f"# (multi-model {located.multimodel.name}, co-simulation config {located.coe.name}).\n"
    )
    output.write_text(header + yaml.safe_dump(data, sort_keys=False, width=110))
    return output


def _path(value: str | Path | None) -> Path | None:
    return Path(value) if value is not None else None


def write_result_files(output: store.Root, folder: Path, sweep: str | None = None) -> dict[str, Path]:
    """INTO-CPS's result files (results.py) of a sweep converted from a DSE config, into ``folder``."""
    from ...sweeps.rank import current_rows, load_sweep_spec, pick_sweep, rank, scalar_objectives
    from .results import write_results

    sweep = pick_sweep(output, sweep)
    spec = load_sweep_spec(output, sweep)
    if spec.origin is None or spec.origin.format != "intocps":
        raise DseError(
            f"sweep {sweep!r} was not converted from an INTO-CPS DSE config: no INTO-CPS result files"
        )
    ranking = rank(output, sweep)
    ids = _ids(spec)
    objectives = scalar_objectives(spec, output, sweep)
    rows = current_rows(output, sweep, ["status", *spec.parameters])
    failed = rows.loc[rows["status"] != "ok", list(spec.parameters)].drop_duplicates()
    fixed = {
        ids(ref): value for ref, value in _multimodel_parameters(spec).items() if ref not in spec.parameters
    }
    return write_results(
        Path(folder),
        ranking.totals,
        {ref: ids(ref) for ref in spec.parameters},
        objectives,
        spec.ranking.pareto_goals() or [(ranking.objective, ranking.goal)],
        fixed,
        failed,
    )


def _ids(spec: SpaceSpec):
    """``instance.variable`` -> INTO-CPS's ``{fmu}.instance.variable``."""
    keys = spec.origin.fmu_keys if spec.origin else {}
    return lambda ref: f"{keys.get(ref.split('.')[0], '{' + ref.split('.')[0] + '}')}.{ref}"


def _multimodel_parameters(spec: SpaceSpec) -> dict:
    return dict(spec.multimodel.get("parameters", {})) if isinstance(spec.multimodel, dict) else {}
