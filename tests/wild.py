"""Other tools' FMUs (../shared/fmus-wild, beside the checkout) and fresh processes to check them against.

The references are independent of dse-runner's own lifecycle: FMPy's
``simulate_fmu``, and dse-runner runs each made in a process of its own, forked
from the standard library's fork server (which imports the modules once and
never loads an FMU), one task per process.
"""

from __future__ import annotations

import multiprocessing
import zipfile
from concurrent.futures import ProcessPoolExecutor
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
WILD = REPO.parent / "shared" / "fmus-wild"

# Every FMU there with a binary for Linux, with an experiment to run it alone on: (stop time, step). The
# stop times go past the 20-sim FMUs' DefaultExperiment stop times (16 s, 20 s); the Overture controllers
# step at a multiple of their thread period. The older one (0.1.7) also checks each step size exactly:
# at 0.1 s, FMPy's step from 0.3 to 0.4 is 0.09999999999999998 and it discards the step (FMPy then hangs).
ALONE = {
    "mass_spring_damper/FMUs/20-Sim/MassSpringDamper1.fmu": (10.0, 0.01),
    "mass_spring_damper/FMUs/20-Sim/MassSpringDamper2.fmu": (10.0, 0.01),
    "single_watertank/FMUs/watertankcontroller-c.fmu": (10.0, 0.1),
    "single_watertank/FMUs/singlewatertank-20sim.fmu": (30.0, 0.1),
    "single_watertank/FMUs/watertankController-Standalone.fmu": (10.0, 0.5),  # a step exact in binary (see below)
    "single_watertank/FMUs/watertankController_Standalone.fmu": (10.0, 0.1),
    "three_tank_watertank/FMUs/threewatertank1.fmu": (30.0, 0.05),
    "three_tank_watertank/FMUs/threewatertank2.fmu": (30.0, 0.05),
    "three_tank_watertank/FMUs/WaterTankController_Standalone.fmu": (10.0, 0.05),
}


def fmpy_ready(path: Path, folder: Path) -> Path:
    """``path`` as FMPy loads it: a copy with the binary renamed to the model identifier where the
    exporter named it otherwise (the shared README's advice)."""
    from fmpy import read_model_description

    identifier = read_model_description(str(path)).coSimulation.modelIdentifier
    expected = f"binaries/linux64/{identifier}.so"
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
        if expected in names:
            return path
        (binary,) = [n for n in names if n.startswith("binaries/linux64/") and n.endswith(".so")]
        copy = folder / path.name
        with zipfile.ZipFile(copy, "w") as out:
            for name in names:
                out.writestr(expected if name == binary else name, archive.read(name))
    return copy


def changed_parameters(path: Path, scale: float = 1.25) -> dict[str, float]:
    """Every Real parameter of the FMU scaled by ``scale`` (0 moves to scale - 1), by bare name."""
    from fmpy import read_model_description

    changed = {}
    for v in read_model_description(str(path)).modelVariables:
        if v.causality == "parameter" and v.type == "Real" and v.start is not None:
            start = float(v.start)
            changed[v.name] = start * scale if start else scale - 1.0
    return changed


# ---- fresh processes ---------------------------------------------------------------------------------

@cache
def pool() -> ProcessPoolExecutor:
    """Two processes at a time, each used for one task only."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["numpy", "fmpy", "dse_runner.simulation.run", "wild"])
    return ProcessPoolExecutor(max_workers=2, mp_context=context, max_tasks_per_child=1)


def fresh(function, *args) -> Any:
    """``function(*args)`` in a process of its own."""
    return pool().submit(function, *args).result(timeout=300)


def fresh_all(function, calls: list[tuple]) -> list[Any]:
    """Each call in a process of its own, two at a time."""
    futures = [pool().submit(function, *args) for args in calls]
    return [f.result(timeout=600) for f in futures]


def fmpy_outputs(path: str, stop: float, step: float, values: dict[str, float]) -> dict[str, np.ndarray]:
    """FMPy's simulate_fmu as a user calls it: every output, by name, with time."""
    from fmpy import simulate_fmu

    result = simulate_fmu(path, stop_time=stop, output_interval=step, start_values=values,
                          fmi_type="CoSimulation")
    return {name: np.asarray(result[name], dtype=float) for name in result.dtype.names}


def ours(model: str, stop: float, step: float, values: dict[str, Any]) -> dict[str, np.ndarray]:
    """dse-runner's simulate: every output by name (instance prefix dropped for one FMU), with time."""
    from dse_runner.simulation.run import simulate

    result = simulate(model, stop_time=stop, step=step, values=values)
    single = str(model).endswith(".fmu")
    outputs = {(name.partition(".")[2] if single else name): np.asarray(v, dtype=float)
               for name, v in result.outputs.items()}
    return {"time": np.asarray(result.time), **outputs}


def run_here() -> None:
    """In a fresh process of the pool: run the FMUs here, whatever their lifecycle, since this process is
    the reference a fresh process per run stands for."""
    from dse_runner.simulation import isolation

    isolation._IN_CHILD = True


def ours_here(model: str, stop: float, step: float, values: dict[str, Any]) -> dict[str, np.ndarray]:
    """:func:`ours`, in this (fresh) process."""
    run_here()
    return ours(model, stop, step, values)


def default_step(path: Path) -> float:
    """The FMU's DefaultExperiment step: a 20-sim FMU's internal step."""
    from fmpy import read_model_description

    return float(read_model_description(str(path)).defaultExperiment.stepSize)


def point_objectives(dse: str, coe: str, point: dict[str, Any]) -> dict[str, Any]:
    """One point of an INTO-CPS DSE config, scored as a sweep scores it, in this (fresh) process."""
    from dse_runner.interfaces.intocps import load_space
    from dse_runner.simulation.run import simulate

    run_here()
    space = load_space(dse, coe=coe)
    result = simulate(space.plan, space.scenarios[0], point, objectives=space.objectives, experiment=space.experiment)
    return result.objectives
