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

REPO = Path(__file__).resolve().parents[2]
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
    "single_watertank/FMUs/watertankController-Standalone.fmu": (
        10.0,
        0.5,
    ),  # a step exact in binary (see below)
    "single_watertank/FMUs/watertankController_Standalone.fmu": (10.0, 0.1),
    "three_tank_watertank/FMUs/threewatertank1.fmu": (30.0, 0.05),
    "three_tank_watertank/FMUs/threewatertank2.fmu": (30.0, 0.05),
    "three_tank_watertank/FMUs/WaterTankController_Standalone.fmu": (10.0, 0.05),
}


def fmpy_ready(path: Path, folder: Path) -> Path:
    """``path`` as FMPy loads it: a copy with the binary renamed to the model identifier where the
    exporter named it otherwise (FMPy looks for the binary under the model identifier only)."""
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


def driven_inputs(path: Path, stop: float) -> dict[str, tuple[np.ndarray, np.ndarray, str]]:
    """Every Real input of the FMU driven from 0 up to 2 and back (crossing the water-tank controllers'
    levels), by bare name: (times, values, interpolation). Continuous inputs are interpolated, discrete
    ones held, as FMPy's Input does."""
    from fmpy import read_model_description

    times = np.array([0.0, stop / 2, stop])  # on the communication grid: FMPy would step to an input event
    return {
        v.name: (times, np.array([0.0, 2.0, 0.0]), "linear" if v.variability == "continuous" else "hold")
        for v in read_model_description(str(path)).modelVariables
        if v.causality == "input" and v.type == "Real"
    }


# ---- fresh processes ---------------------------------------------------------------------------------


@cache
def pool() -> ProcessPoolExecutor:
    """Two processes at a time, each used for one task only."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["numpy", "fmpy", "dse_runner.simulation.run", "wild"])
    return ProcessPoolExecutor(max_workers=2, mp_context=context, max_tasks_per_child=1)


def fresh(function, *args) -> Any:
    """``function(*args)`` in a process of its own."""
    return pool().submit(function, *args).result(timeout=120)


def fresh_all(function, calls: list[tuple]) -> list[Any]:
    """Each call in a process of its own, two at a time."""
    futures = [pool().submit(function, *args) for args in calls]
    return [f.result(timeout=600) for f in futures]


def fmpy_outputs(
    path: str, stop: float, step: float, values: dict[str, float], driven: bool = False
) -> dict[str, np.ndarray]:
    """FMPy's simulate_fmu as a user calls it: every output, by name, with time; ``driven``: with
    :func:`driven_inputs`."""
    from fmpy import simulate_fmu

    inputs = driven_inputs(Path(path), stop) if driven else {}
    signals = None
    if inputs:
        times = next(iter(inputs.values()))[0]
        signals = np.array(
            list(zip(times, *(v for _, v, _ in inputs.values()))),
            dtype=[("time", float), *((name, float) for name in inputs)],
        )
    result = simulate_fmu(
        path,
        stop_time=stop,
        output_interval=step,
        start_values=values,
        fmi_type="CoSimulation",
        input=signals,
    )
    return {name: np.asarray(result[name], dtype=float) for name in result.dtype.names}


def ours(
    model: str, stop: float, step: float, values: dict[str, Any], driven: bool = False
) -> dict[str, np.ndarray]:
    """dse-runner's simulate: every output by name (instance prefix dropped for one FMU), with time;
    ``driven``: a single FMU's inputs as :func:`driven_inputs` drives them."""
    from dse_runner.simulation.multimodel import single_fmu
    from dse_runner.simulation.run import simulate
    from dse_runner.simulation.scenario import Scenario
    from dse_runner.simulation.trajectory import Series

    scenario = None
    if driven:
        instance = next(iter(single_fmu(model).fmus))
        scenario = Scenario(
            "driven",
            inputs={
                f"{instance}.{name}": Series(t, v, how)
                for name, (t, v, how) in driven_inputs(Path(model), stop).items()
            },
        )
    result = simulate(model, scenario, stop_time=stop, step=step, values=values)
    single = str(model).endswith(".fmu")
    outputs = {
        (name.partition(".")[2] if single else name): np.asarray(v, dtype=float)
        for name, v in result.outputs.items()
    }
    return {"time": np.asarray(result.time), **outputs}


def run_here() -> None:
    """In a fresh process of the pool: run the FMUs here, whatever their lifecycle, since this process is
    the reference a fresh process per run stands for."""
    from dse_runner.simulation import isolation

    isolation._IN_CHILD = True


def ours_here(
    model: str, stop: float, step: float, values: dict[str, Any], driven: bool = False
) -> dict[str, np.ndarray]:
    """:func:`ours`, in this (fresh) process."""
    run_here()
    return ours(model, stop, step, values, driven)


def default_step(path: Path) -> float:
    """The FMU's DefaultExperiment step (a 20-sim FMU's internal step); 0 where it gives none."""
    from fmpy import read_model_description

    experiment = read_model_description(str(path)).defaultExperiment
    return float(experiment.stepSize) if experiment is not None and experiment.stepSize else 0.0


def point_objectives(dse: str, coe: str, point: dict[str, Any]) -> dict[str, Any]:
    """One point of an INTO-CPS DSE config, scored as a sweep scores it, in this (fresh) process."""
    from dse_runner.interfaces.intocps import load_space
    from dse_runner.simulation.run import simulate

    run_here()
    space = load_space(dse, coe=coe)
    result = simulate(
        space.plan, space.scenarios[0], point, objectives=space.objectives, experiment=space.experiment
    )
    return result.objectives


def as_intocps_scripts_compute(
    dse: str, coe: str | None, point: dict[str, Any], level: str, target: float, valve: str
) -> tuple[dict[str, Any], dict[str, float]]:
    """One point of a DSE, scored as a sweep scores it, beside what INTO-CPS's published scripts compute from
    the run's own trajectory read as INTO-CPS writes results.csv: ``cumulativeDeviation`` sums
    |level - target| times the step-size column (0 on the first row, then time[i] - time[i-1]); ``vCount``
    counts the valve's changes between rows."""
    from dse_runner.interfaces.intocps import load_space
    from dse_runner.simulation.run import simulate

    run_here()
    space = load_space(dse, coe=coe)
    result = simulate(
        space.plan, space.scenarios[0], point, objectives=space.objectives, experiment=space.experiment
    )
    time = result.trajectory.time
    steps = np.concatenate([[0.0], time[1:] - time[:-1]])
    levels, valves = result.trajectory.column(level), result.trajectory.column(valve)
    return result.objectives, {
        "cumulativeDeviation": float(np.sum(np.abs(levels - target) * steps)),
        "vCount": float(np.count_nonzero(valves[1:] != valves[:-1])),
    }
