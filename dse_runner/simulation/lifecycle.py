"""How an FMU lives across the runs of one process: one instance reset between
runs, or a fresh process each run.

The reference is a fresh process per run: that is how FMPy's ``simulate_fmu``
and INTO-CPS's engine meet an FMU. A sweep runs thousands of simulations per
worker process, so reusing one instance through ``fmi2Reset`` (fmu.py) saves
loading and instantiating the FMU every time, but only where it gives the
same numbers. Exported FMUs differ here: some keep their old outputs after a
reset, some crash on a second run, some say in their model description that
they can be instantiated only once per process.

So each FMU gets a :class:`Verdict`, decided in this order (docs/multimodel.md):

1. the multi-model asks for ``lifecycle: process``: a fresh process;
2. the FMU declares ``canBeInstantiatedOnlyOncePerProcess``: a fresh process;
3. otherwise it is *measured*: :func:`probe` runs the FMU alone (at most
   PROBE_STEPS steps of its default experiment, its inputs driven) a few times in
   one process, with its defaults and with changed parameters, and compares every
   output bit for bit with runs in fresh processes. Identical: ``reset``. Different,
   crashed or not runnable alone: a fresh process.

Measured verdicts are kept per FMU content in the cache folder, so each FMU is
probed once per machine.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..errors import DseError
from . import fmu as fmus
from . import isolation
from .cosim import Runner, prepare
from .multimodel import single_fmu
from .plan import Plan, make_plan
from .trajectory import Series

Mode = Literal["reset", "process"]
PROBE_VERSION = 1  # bump when the probe changes: verdicts kept on disk are then measured again
PROBE_STEPS = 200  # the longest probe run, in communication steps (a stale reset shows in the first ones)
PROBE_SECONDS = 60.0  # a probe run that takes longer than this is stopped (the FMU then runs the safe way)


@dataclass(frozen=True)
class Verdict:
    """How one FMU is run across the runs of a process, and why."""

    mode: Mode
    reason: str


def plan_verdicts(runner: Runner, values: Mapping[str, Any]) -> dict[str, Verdict]:
    """Every instance's verdict. An FMU that cannot run alone (one that needs a file, say) is measured in
    this multi-model with these values, where every other instance can be reused; where another needs a
    fresh process anyway, so does the whole run, and it is not measured."""
    plan = runner.plan
    if isolation.in_child():  # a fresh process measures nothing: it is what the measures compare with
        return dict.fromkeys(plan.fmu_paths, Verdict("process", "run in a fresh process of its own"))
    verdicts: dict[str, Verdict | str] = {}
    for name, path in plan.fmu_paths.items():
        interface, asked = plan.interfaces[name], plan.multimodel.settings(name).lifecycle
        verdicts[name] = (
            declared(path, interface, asked) or _known(path, interface) or _measured_alone(path, interface)
        )
    alone = {name: why for name, why in verdicts.items() if isinstance(why, str)}
    decided = {name: v for name, v in verdicts.items() if isinstance(v, Verdict)}
    if not alone:
        return decided
    others = [name for name, v in decided.items() if v.mode == "process"]
    if others:
        return {
            **decided,
            **{
                name: Verdict(
                    "process", f"not measured ({why}); the run needs a fresh process for {others[0]} anyway"
                )
                for name, why in alone.items()
            },
        }
    together = probe(runner, dict(values), [plan.fmu_paths[name] for name in alone])
    if isinstance(together, str):  # this run fails in a fresh process too: nothing measured, nothing kept
        return {
            **decided,
            **dict.fromkeys(alone, Verdict("process", f"not measured ({together}), so run the safe way")),
        }
    if len(plan.fmu_paths) > 1:
        together = Verdict(
            together.mode,
            f"{together.reason}, in this multi-model (it cannot run alone: {next(iter(alone.values()))})",
        )
    for name in alone:
        _keep(plan.fmu_paths[name], plan.interfaces[name], together)
    return {**decided, **dict.fromkeys(alone, together)}


def needs_process(verdicts: dict[str, Verdict]) -> bool:
    """A run with any instance that must run in a fresh process runs whole in one."""
    return any(v.mode == "process" for v in verdicts.values())


def declared(path: Path, interface: str, asked: str = "auto") -> Verdict | None:
    """The verdict the multi-model or the FMU itself gives, if any."""
    if asked == "process":
        return Verdict("process", "the multi-model asks for a fresh process per run (lifecycle: process)")
    description = fmus.describe(path)
    part = description.coSimulation if interface == "cs" else description.modelExchange
    if part is not None and part.canBeInstantiatedOnlyOncePerProcess:
        return Verdict("process", "the FMU declares canBeInstantiatedOnlyOncePerProcess")
    return None


_KNOWN: dict[tuple[str, str], Verdict] = {}


def _known(path: Path, interface: str) -> Verdict | None:
    """A verdict measured before, in this process or on this machine."""
    key = (fmus.content_hash(path), interface)
    found = _KNOWN.get(key) or _read_kept(*key)
    if found is not None:
        _KNOWN[key] = found
    return found


def _measured_alone(path: Path, interface: str) -> Verdict | str:
    """The probe's verdict on the FMU alone, kept; or why it could not run alone."""
    plan = make_plan(single_fmu(path), interface)
    runner, fresh = _alone(plan)
    if runner is None:
        return fresh
    found = probe(runner, {}, [path], fresh)
    _keep(path, interface, found)
    return found


# ---- measuring -----------------------------------------------------------------------------------


def probe(
    runner: Runner, values: dict[str, Any], changing: list[Path], fresh: list[tuple] | None = None
) -> Verdict | str:
    """Run ``runner`` in fresh processes and several times in one, and compare every output bit for bit:
    first with the parameters of the FMUs at ``changing`` changed, then with ``values`` twice. What a
    reset forgets to reset shows. ``fresh``: the run with ``values`` in a fresh process, if made already.
    Why not, where even that run fails."""
    fresh = fresh or _fresh_runs(runner, [values])
    if isinstance(fresh, str):
        return fresh
    changed = {**values, **_changed_parameters(runner.plan, changing, values)}
    fresh_changed = _fresh_runs(runner, [changed]) if changed != values else "no parameters to change"
    sequence = [changed, values, values] if not isinstance(fresh_changed, str) else [values, values]
    expected = ([fresh_changed[0]] if not isinstance(fresh_changed, str) else []) + [fresh[0], fresh[0]]
    reused = _fresh_runs(runner, sequence)
    if isinstance(reused, str):
        return Verdict("process", f"measured: runs after the first in one process failed ({reused})")
    for k, (got, want) in enumerate(zip(reused, expected)):
        difference = _difference(runner, got, want)
        if difference:
            return Verdict(
                "process",
                f"measured: run {k + 1} of {len(sequence)} in one process differed from a "
                f"fresh process's ({difference})",
            )
    return Verdict(
        "reset",
        f"measured: {len(sequence)} runs in one process (reset between them) were "
        "bit-identical to runs in fresh processes",
    )


def _alone(plan: Plan) -> tuple[Runner | None, list[tuple] | str]:
    """The FMU alone on the probe's experiment and its run in a fresh process: with its inputs driven,
    else at their start values; otherwise (None, why not)."""
    start, stop, step = _probe_times(plan)
    why = "no experiment"
    for inputs in (_excitation(plan, start, stop), {}):
        try:
            runner = prepare(plan, start, stop, step, inputs)
        except DseError as e:
            why = str(e)
            continue
        fresh = _fresh_runs(runner, [{}])
        if not isinstance(fresh, str):
            return runner, fresh
        why = fresh
    return None, why


def _excitation(plan: Plan, start: float, stop: float) -> dict[str, Series]:
    """Every number input driven from 0 up to 1 and back (held steps for integers and Booleans)."""
    middle, third = (start + stop) / 2, (stop - start) / 3
    driven = {}
    for variables in plan.variables.values():
        for v in variables.values():
            if v.causality != "input" or v.family not in ("float", "integer", "boolean"):
                continue
            if v.family == "float":
                driven[v.ref] = Series(np.array([start, middle, stop]), np.array([0.0, 1.0, 0.0]))
            else:
                driven[v.ref] = Series(
                    np.array([start, start + third, start + 2 * third]), np.array([0.0, 1.0, 0.0]), "hold"
                )
    return driven


def _probe_times(plan: Plan) -> tuple[float, float, float]:
    """The FMU's default experiment, at most PROBE_STEPS steps of it; 1 s in 100 steps where it gives none."""
    start, stop, step = plan.defaults
    start = start or 0.0
    stop = stop if stop is not None and stop > start else start + 1.0
    step = step if step is not None and step > 0 else (stop - start) / 100
    return start, min(stop, start + PROBE_STEPS * step), step


def _fresh_runs(runner: Runner, values: list[dict[str, Any]]) -> list[tuple] | str:
    """The runs in one fresh process, each as (values, texts); a message if any failed or the process died."""
    try:
        return isolation.run(
            _runs_here,
            runner,
            values,
            preload=[(p, runner.plan.interfaces[n]) for n, p in runner.plan.fmu_paths.items()],
            kill_after=len(values) * PROBE_SECONDS + isolation.KILL_GRACE,
        )
    except DseError as e:
        return str(e)


def _runs_here(runner: Runner, values: list[dict[str, Any]]) -> list[tuple]:
    """In the fresh process: every run, one after another, with the instance reset between them."""
    runs = []
    for v in values:
        trajectory = runner.run(v, timeout=PROBE_SECONDS)
        runs.append((trajectory.values, trajectory.texts))
    return runs


def _changed_parameters(plan: Plan, changing: list[Path], values: Mapping[str, Any]) -> dict[str, float]:
    """Every real parameter of the FMUs at ``changing`` that ``values`` leaves alone, a quarter off its
    start value and within its declared bounds. Parameters that start at 0 stay: 0 often means "off"
    (a delay, a pause), and no scale says what else it could be."""
    changed = {}
    for name, path in plan.fmu_paths.items():
        if path not in changing:
            continue
        for v in fmus.describe(path).modelVariables:
            variable = plan.variables[name].get(v.name)
            if (
                variable is None
                or v.causality != "parameter"
                or variable.family != "float"
                or v.start is None
                or variable.ref in values
            ):
                continue
            try:
                start = float(v.start)
            except (TypeError, ValueError):
                continue
            if not start:
                continue
            value = min(
                max(start * 1.25, variable.low if variable.low is not None else -math.inf),
                variable.high if variable.high is not None else math.inf,
            )
            if value != start and math.isfinite(value):
                changed[variable.ref] = value
    return changed


def _difference(runner: Runner, got: tuple, want: tuple) -> str | None:
    """Where two runs part, in words; None if they are bit-identical."""
    (values, texts), (expected, expected_texts) = got, want
    same = (values == expected) | (np.isnan(values) & np.isnan(expected))
    if not same.all():
        row, column = np.argwhere(~same)[0]
        return (
            f"{runner.plan.recorded[column]} at t={runner.times[row]:.6g}: "
            f"{float(values[row, column])!r} against {float(expected[row, column])!r}"
        )
    for name, series in texts.items():
        if series != expected_texts.get(name):
            return f"{name} differs"
    return None


# ---- keeping verdicts ----------------------------------------------------------------------------


def _kept_path(sha: str, interface: str) -> Path:
    from .build import default_cache_dir

    return default_cache_dir().parent / "lifecycle" / f"{sha}-{interface}.json"


def _read_kept(sha: str, interface: str) -> Verdict | None:
    try:
        kept = json.loads(_kept_path(sha, interface).read_text())
    except (OSError, ValueError):
        return None
    if kept.get("probe") != PROBE_VERSION or kept.get("mode") not in ("reset", "process"):
        return None
    return Verdict(kept["mode"], kept["reason"])


def _keep(fmu: Path, interface: str, found: Verdict) -> None:
    """Kept for this process and machine; written whole or not at all (a cache that cannot be written
    only costs a probe next time)."""
    sha = fmus.content_hash(fmu)
    _KNOWN[(sha, interface)] = found
    path = _kept_path(sha, interface)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f".{path.name}-{os.getpid()}")
        partial.write_text(json.dumps({**asdict(found), "probe": PROBE_VERSION}))
        os.replace(partial, path)
    except OSError:
        pass
