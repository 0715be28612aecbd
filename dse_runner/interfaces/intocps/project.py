"""Where an INTO-CPS DSE's files are: the project, its multi-model and its co-simulation config.

A dse.json names neither its mm.json nor its coe.json: the INTO-CPS
application lets the user pick a coe.json among every file under
``Multi-models/`` whose name ends in ``coe.json``, and takes the multi-model
two folders up (``<mm>/<config>/coe.json`` -> ``<mm>/mm.json``, else the one
file there ending in ``mm.json``), else the coe's ``multimodel_path``
(docs/research/intocps-formats.md, section 4). :func:`locate` does the same
without a user to ask: the candidates whose multi-model defines every
``{fmu}.instance`` the DSE names and whose FMUs are in the project; one is
taken, several are listed, none is an error naming what is missing and the
multi-models looked at. Configs that fit but whose FMUs are absent (a project
published without them) are set aside with one line saying so.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

from ...errors import DseError
from ...simulation.multimodel import from_into_cps, into_cps_instances, portable, split_into_cps_id
from .formats import CoeConfig, DseConfig, IntoCpsWarning, read, read_json

PROJECT_FILE = ".project.json"
MULTI_MODEL_FOLDERS = ("Multi-models", "Multi-Models", "Multimodels")  # all three occur in real projects
FMUS_FOLDER = "FMUs"
SCRIPTS_FOLDER = "userMetricScripts"


@dataclass(frozen=True)
class Located:
    """A DSE config with the project around it and the multi-model and co-simulation config it runs."""

    root: Path
    dse: Path
    multimodel: Path
    coe: Path

    @property
    def fmus(self) -> Path:
        return self.root / FMUS_FOLDER

    @property
    def scripts(self) -> Path:
        return self.root / SCRIPTS_FOLDER


def project_root(dse: Path) -> Path:
    """The folder holding ``.project.json`` above the DSE, else the one holding its ``DSEs`` folder."""
    for folder in dse.resolve().parents:
        if (folder / PROJECT_FILE).is_file():
            return folder
    for folder in dse.resolve().parents:
        if folder.name == "DSEs":
            return folder.parent
    raise DseError(
        f"{dse}: not inside an INTO-CPS project (no {PROJECT_FILE} above it, and it is not under "
        "a DSEs folder)"
    )


def _is_result_copy(path: Path, root: Path) -> bool:
    """Co-simulation results (``R_<date>/``) hold copies of the coe.json they ran."""
    return any(part.startswith("R_") for part in path.relative_to(root).parts[:-1])


def coe_candidates(root: Path) -> list[Path]:
    """Every co-simulation config of the project, as the application lists them."""
    found = [
        path
        for name in MULTI_MODEL_FOLDERS
        for path in (root / name).rglob("*coe.json")
        if path.is_file() and not _is_result_copy(path, root)
    ]
    return sorted(set(found))


def multimodel_of(coe: Path, root: Path) -> Path:
    """The multi-model a coe.json runs: the application's rule, then the coe's ``multimodel_path``."""
    folder = coe.parent.parent
    if (folder / "mm.json").is_file():
        return folder / "mm.json"
    named = sorted(folder.glob("*mm.json"))
    if len(named) == 1:
        return named[0]
    given = read(coe, CoeConfig).multimodel_path
    if given is not None and (root / given).is_file():
        return root / given
    raise DseError(
        f"{coe}: no multi-model found for it: no mm.json in {folder}"
        + (
            f" and its multimodel_path {given!r} is not a file"
            if given
            else " and it has no multimodel_path; give --multimodel"
        )
    )


def instances_used(dse: DseConfig) -> set[str]:
    """The ``{fmu}.instance`` of every id the DSE config names (an id of another shape is named by
    convert.py's checks, later)."""
    ids = [
        *dse.parameters,
        *(f.columnID for f in dse.objectiveDefinitions.internalFunctions.values()),
        *(v for s in dse.objectiveDefinitions.externalScripts.values() for v in s.scriptParameters.values()),
    ]
    return {f"{key}.{instance}" for key, instance, _ in filter(None, map(_split, ids))}


def _split(ref: str) -> tuple[str, str, str] | None:
    try:
        return split_into_cps_id(ref)
    except DseError:
        return None


def instances_defined(multimodel: Path) -> set[str]:
    """The ``{fmu}.instance`` an mm.json defines: INTO-CPS's instances are those its connections and
    parameters name, under an FMU key of ``fmus``."""
    data = read_json(multimodel)
    if not isinstance(data, dict) or not isinstance(data.get("fmus"), dict):
        return set()  # not an mm.json: it defines nothing the DSE can run
    try:
        return {f"{key}.{instance}" for instance, key in into_cps_instances(data).items()}
    except DseError as e:
        raise DseError(f"{multimodel}: {str(e).removeprefix('mm.json: ')}") from None


def locate(dse_path: Path, multimodel: Path | None = None, coe: Path | None = None) -> Located:
    """The files a DSE runs with: those given, the others found as the application finds them."""
    root = project_root(dse_path)
    if coe is None:
        coe = _pick_coe(root, read(dse_path, DseConfig), multimodel)
    if multimodel is None:
        multimodel = multimodel_of(coe, root)
    for path in (coe, multimodel):
        if not path.is_file():
            raise DseError(f"file not found: {path}")
    return Located(root, dse_path.resolve(), multimodel.resolve(), coe.resolve())


def _pick_coe(root: Path, dse: DseConfig, multimodel: Path | None) -> Path:
    """One candidate whose multi-model defines every instance the DSE names, or an error saying why not."""
    candidates = coe_candidates(root)
    if multimodel is not None:
        candidates = [c for c in candidates if _multimodel_or_none(c, root) == multimodel.resolve()]
    where = f"{root}/{'|'.join(MULTI_MODEL_FOLDERS)}"
    if not candidates:
        raise DseError(
            f"no co-simulation config (*coe.json) under {where}"
            + (f" runs {multimodel}" if multimodel else "")
            + "; give --coe"
        )
    used = instances_used(dse)
    lacking = {c: _lacking(c, root, used) for c in candidates}
    fitting = [c for c in candidates if not lacking[c]]
    if not fitting:
        raise DseError(_none_fits(root, lacking))
    absent = {c: absent_fmus(c, root) for c in fitting} if len(fitting) > 1 else {}
    if absent and any(absent.values()):
        runnable = [c for c in fitting if not absent[c]]
        if not runnable:
            raise DseError(
                "every co-simulation config that could run this DSE lacks FMUs: "
                + "; ".join(f"{_shown(c, root)} needs {', '.join(missing)}" for c, missing in absent.items())
            )
        warnings.warn(
            IntoCpsWarning(
                "set aside, their FMUs absent from the project: "
                + "; ".join(
                    f"{_shown(c, root)} (needs {', '.join(missing)})"
                    for c, missing in absent.items()
                    if missing
                )
            ),
            stacklevel=3,
        )
        fitting = runnable
    if len(fitting) == 1:
        return fitting[0]
    names = ", ".join(str(c.relative_to(root)) for c in fitting)
    raise DseError(f"several co-simulation configs could run this DSE ({names}); choose one with --coe")


def _multimodel_or_none(coe: Path, root: Path) -> Path | None:
    try:
        return multimodel_of(coe, root).resolve()
    except DseError:
        return None


def _lacking(coe: Path, root: Path, used: set[str]) -> list[str]:
    """What of ``used`` the coe.json's multi-model does not define (all of it when it has none)."""
    multimodel = _multimodel_or_none(coe, root)
    return sorted(used - (instances_defined(multimodel) if multimodel is not None else set()))


def absent_fmus(coe: Path, root: Path) -> list[str]:
    """The FMU files the coe.json's multi-model names that the project does not hold (found as the run finds
    them: in its FMUs folder, also under a name written otherwise)."""
    multimodel = _multimodel_or_none(coe, root)
    if multimodel is None:
        return []
    data = read_json(multimodel)
    with warnings.catch_warnings():  # a renamed FMU is said when the chosen config loads, not per candidate
        warnings.simplefilter("ignore")
        found = from_into_cps(data, multimodel.parent)["fmus"]
    named = {instance: data["fmus"][key] for instance, key in into_cps_instances(data).items()}
    return sorted(
        {
            portable(named[instance])
            for instance, path in found.items()
            if not (Path(path).is_absolute() and Path(path).exists())
        }
    )  # one not found stays relative


def _shown(path: Path, root: Path) -> str:
    return str(path.relative_to(root)) if path.is_relative_to(root) else str(path)


def _none_fits(root: Path, lacking: dict[Path, list[str]]) -> str:
    """What the DSE names that no candidate's multi-model defines, and the multi-models looked at."""
    looked: dict[str, list[str]] = {}
    for coe, missing in lacking.items():
        multimodel = _multimodel_or_none(coe, root)
        name = _shown(multimodel, root) if multimodel else f"{_shown(coe, root)} (no multi-model)"
        looked.setdefault(name, missing)
    if len({tuple(m) for m in looked.values()}) == 1:
        missing = ", ".join(next(iter(looked.values())))
        return (
            f"this DSE names {missing}, which no multi-model of the project defines (looked at "
            f"{', '.join(looked)}; a multi-model defines the {{fmu}}.instance its connections and "
            "parameters name)"
        )
    return "no multi-model of the project defines every {fmu}.instance this DSE names: " + "; ".join(
        f"{name} lacks {', '.join(missing)}" for name, missing in looked.items()
    )
