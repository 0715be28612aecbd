"""Where an INTO-CPS DSE's files are: the project, its multi-model and its co-simulation config.

A dse.json names neither its mm.json nor its coe.json: the INTO-CPS
application lets the user pick a coe.json among every file under
``Multi-models/`` whose name ends in ``coe.json``, and takes the multi-model
two folders up (``<mm>/<config>/coe.json`` -> ``<mm>/mm.json``, else the one
file there ending in ``mm.json``), else the coe's ``multimodel_path``
(docs/research/intocps-formats.md, section 4). :func:`locate` does the same
without a user to ask: one candidate is taken; among several, the one whose
multi-model has every FMU the DSE names; otherwise the error lists them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ...errors import DseError
from .formats import CoeConfig, DseConfig, read, read_json

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
    raise DseError(f"{dse}: not inside an INTO-CPS project (no {PROJECT_FILE} above it, and it is not under "
                   "a DSEs folder)")


def _is_result_copy(path: Path, root: Path) -> bool:
    """Co-simulation results (``R_<date>/``) hold copies of the coe.json they ran."""
    return any(part.startswith("R_") for part in path.relative_to(root).parts[:-1])


def coe_candidates(root: Path) -> list[Path]:
    """Every co-simulation config of the project, as the application lists them."""
    found = [path for name in MULTI_MODEL_FOLDERS for path in (root / name).rglob("*coe.json")
             if path.is_file() and not _is_result_copy(path, root)]
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
    if given is not None and (root / given.replace("\\", "/")).is_file():
        return root / given.replace("\\", "/")
    raise DseError(f"{coe}: no multi-model found for it: no mm.json in {folder}"
                   + (f" and its multimodel_path {given!r} is not a file" if given else
                      " and it has no multimodel_path; give --multimodel"))


def fmu_keys_used(dse: DseConfig) -> set[str]:
    """The ``{fmu}`` keys of every id the DSE config names."""
    ids = [*dse.parameters, *(f.columnID for f in dse.objectiveDefinitions.internalFunctions.values()),
           *(v for s in dse.objectiveDefinitions.externalScripts.values() for v in s.scriptParameters.values())]
    return {i.partition("}")[0] + "}" for i in ids if i.startswith("{") and "}" in i}


def _defines(multimodel: Path, keys: set[str]) -> bool:
    data = read_json(multimodel)
    return isinstance(data, dict) and keys <= set(data.get("fmus", {}))


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
    candidates = coe_candidates(root)
    if multimodel is not None:
        candidates = [c for c in candidates if _multimodel_or_none(c, root) == multimodel.resolve()]
    if len(candidates) > 1:
        keys = fmu_keys_used(dse)
        fitting = [c for c in candidates if _fits(c, root, keys)]
        candidates = fitting or candidates
    if len(candidates) == 1:
        return candidates[0]
    where = f"{root}/{'|'.join(MULTI_MODEL_FOLDERS)}"
    if not candidates:
        raise DseError(f"no co-simulation config (*coe.json) under {where}"
                       + (f" runs {multimodel}" if multimodel else "") + "; give --coe")
    names = ", ".join(str(c.relative_to(root)) for c in candidates)
    raise DseError(f"several co-simulation configs could run this DSE ({names}); choose one with --coe")


def _multimodel_or_none(coe: Path, root: Path) -> Path | None:
    try:
        return multimodel_of(coe, root).resolve()
    except DseError:
        return None


def _fits(coe: Path, root: Path, keys: set[str]) -> bool:
    multimodel = _multimodel_or_none(coe, root)
    return multimodel is not None and _defines(multimodel, keys)
