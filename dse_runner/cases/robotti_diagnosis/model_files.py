"""The files a diagnosis reads and writes: the calibration space, the effects multi-model every fit runs, and
the augmented model a user can run."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import yaml

from ... import bundled
from ...analysis.diagnose import discovery
from ...analysis.diagnose.calibration import parameters_at
from ...errors import DseError
from ...simulation.multimodel import MultiModel, split_ref
from ...sweeps.domain import Range
from ...sweeps.fit import Parameter
from ...sweeps.spec import Space, SpaceSpec, resolve_space
from .. import fielddata
from . import correction
from .correction import variables as correction_variables
from .hypotheses import EFFECTS_FMU, effect_variables, hypothesis
from .outcome import Diagnosis

FITS = "diagnosis-fits"  # the sweep every fit's rounds go to
STEP = 0.01  # a calibrated parameter's finite-difference step, as a share of its range


def vehicle_of(calibration: Space) -> str:
    """The instance whose outputs are the position compared with GPS: where the effects act."""
    if not calibration.scenarios or calibration.scenarios[0].kind != fielddata.KIND:
        raise DseError("diagnosis needs recorded runs in the field-data format (GPS fixes)")
    x, _ = fielddata.position_of(calibration.plan.recorded, calibration.scenarios[0])
    return split_ref(x)[0]


def at_antenna(entries: list[Any], vehicle: str) -> list[dict[str, Any]]:
    """Scenario entries whose runs are compared with GPS at the antenna's outputs (gps_x, gps_y)."""
    position = {"x": f"{vehicle}.gps_x", "y": f"{vehicle}.gps_y"}
    return [
        {"path": e, "position": position} if isinstance(e, str) else {**e, "position": position}
        for e in entries
    ]


def effects_multimodel(multimodel: MultiModel, vehicle: str, folder: Path) -> dict[str, Any]:
    """The multi-model with ``vehicle`` replaced by the effects variant, to be written into ``folder``
    (FMU paths relative to it, bundled ones as ``bundled:``)."""
    bundled.bundled_path(EFFECTS_FMU)  # it ships with the package; an error names it if not
    data = multimodel.model_dump(mode="json")
    data["fmus"] = {
        name: ref if bundled.is_bundled(ref) else _relative(multimodel.fmu_path(name), folder)
        for name, ref in multimodel.fmus.items()
    }
    data["fmus"][vehicle] = EFFECTS_FMU
    return data


def _relative(path: Path, folder: Path) -> str:
    """``path`` relative to ``folder`` where that is possible, so written
    files can move with the repository."""
    try:
        return os.path.relpath(path, folder)
    except ValueError:  # another drive
        return str(path)


def _write_yaml(path: Path, data: dict[str, Any], header: str = "") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(header + yaml.safe_dump(data, sort_keys=False))
    return path


def base_parameters(calibration: Space, best: dict[str, Any]) -> tuple[Parameter, ...]:
    """The calibration's parameters with a range (calibration.parameters_at), starting from the grid's
    best point, with a finite-difference step of a hundredth of each range; none is an error."""
    params = parameters_at(calibration, best, STEP)
    if not params:
        raise DseError(f"{calibration.path}: no numeric parameter with a range to calibrate")
    return params


def fits_space(calibration: Space, vehicle: str, out: Path) -> Space:
    """A space over the effects multi-model whose rounds are given points (fit.py)."""
    mm_path = _write_yaml(
        out / "effects-multimodel.yaml",
        effects_multimodel(calibration.multimodel, vehicle, out),
        "# The multi-model diagnosis fits: the vehicle replaced by its effects variant.\n",
    )
    parameters = {name: values for name, values in calibration.parameters.items()}
    parameters.update({f"{vehicle}.{v}": [0.0] for v in effect_variables()})
    parameters.update(
        {f"{vehicle}.{v}": [0.0] for v in correction_variables()}
    )  # off until discovery frees them
    parameters.update(
        {f"{vehicle}.{s.variable}": [s.default] for s in correction.SHAPES.values()}
    )  # held by discovery
    entries = [e if isinstance(e, str) else e.model_dump() for e in calibration.spec.scenarios]
    spec = SpaceSpec(
        name=FITS,
        multimodel=str(mm_path),
        scenarios=at_antenna(entries, vehicle),
        parameters=parameters,
        objectives=["cross_track_error", "fix_residuals"],
        output=str(out),
        cluster=calibration.spec.cluster,
        keep_trajectories=0,
        timeout=calibration.spec.timeout,
        chunk_seconds=calibration.spec.chunk_seconds,
    )
    return resolve_space(spec, out / f"{FITS}.yaml")


def write_model(diagnosis: Diagnosis, calibration: Space) -> dict[str, Path]:
    """The chosen effects as a multi-model and a space.yaml that re-calibrates with them."""
    if not diagnosis.chosen.ids:
        return {}
    out, vehicle = diagnosis.out, diagnosis.calibration["vehicle"]
    names = ", ".join(diagnosis.chosen.ids)
    mm_path = _write_yaml(
        out / "augmented-multimodel.yaml",
        effects_multimodel(calibration.multimodel, vehicle, out),
        f"# Written by dse-runner diagnose: the vehicle's effects variant, for {names}.\n",
    )
    spec = calibration.spec.model_dump(
        mode="json", exclude={"output", "keep_trajectories"}, exclude_defaults=True
    )
    parameters = dict(spec["parameters"])
    fit = diagnosis.chosen.full
    interval = fit.interval()
    for name in fit.names:  # the discovered terms over their intervals, as the effects' below
        if correction.is_correction(name):
            low, high = sorted(interval[name])
            if not (math.isfinite(low) and math.isfinite(high)) or high <= low:
                low, high = sorted((0.0, 2.0 * fit.values[name]))
            parameters[name] = Range(start=round(low, 9), stop=round(high, 9), num=3).model_dump(
                exclude_none=True
            )
            shape = correction.shape_of(correction.term(name))
            if shape is not None:  # what shapes the term (when it switches on, ...), as the fits held it
                parameters[f"{vehicle}.{shape.variable}"] = [fit.point[f"{vehicle}.{shape.variable}"]]
    for hid in discovery.library_ids(diagnosis.chosen.ids):
        for p in hypothesis(hid).parameters:
            ref = f"{vehicle}.{p.variable}"
            low, high = (max(p.lower, interval[ref][0]), min(p.upper, interval[ref][1]))
            if not (math.isfinite(low) and math.isfinite(high)) or high <= low:
                low, high = p.lower, p.upper
            parameters[ref] = Range(start=round(low, 6), stop=round(high, 6), num=3).model_dump(
                exclude_none=True
            )
    scenarios = at_antenna(
        [_relative(Path(s), out) if isinstance(s, str) else s for s in spec["scenarios"]], vehicle
    )
    spec.update(
        name=f"{calibration.name}-with-{'-'.join(diagnosis.chosen.ids)}",
        multimodel=mm_path.name,
        scenarios=scenarios,
        parameters=parameters,
        output="recalibration",
    )
    space_path = _write_yaml(
        out / "space.yaml",
        spec,
        f"# Written by dse-runner diagnose: the calibration with {names} added,\n"
        "# each effect parameter over its fitted ~95 % interval. Run: dse-runner submit space.yaml\n",
    )
    return {"multimodel": mm_path, "space": space_path}


def steering_source(multimodel: MultiModel, vehicle: str) -> str:
    """The output that drives the vehicle's steering input, as recorded in trajectories."""
    for source, targets in multimodel.connections.items():
        if f"{vehicle}.delta_f" in targets:
            return source
    raise DseError(f"diagnosis needs a connection into {vehicle}.delta_f (the steering command)")
