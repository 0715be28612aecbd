"""An independent FMI master to check ours against: libcosim (Open Simulation Platform).

libcosim runs the same plan (FMUs, connections, values) with its own FMU
loading (FMI Library) and its own fixed-step algorithm. Agreement between the
two is evidence that our master transfers values and steps FMUs as FMI means
it to. Requires the optional ``libcosimpy`` package (and Debian's libtbb12).
"""

from __future__ import annotations

import numpy as np

from ..errors import DseError
from .plan import Plan
from .trajectory import Trajectory
from .variables import Value


def _libcosim():
    try:
        from libcosimpy import CosimLogging
        from libcosimpy.CosimEnums import CosimVariableType
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimObserver import CosimObserver
        from libcosimpy.CosimSlave import CosimLocalSlave
    except (ImportError, OSError) as e:
        raise DseError(
            f"libcosim is not available ({e}): pip install libcosimpy; apt-get install libtbb12"
        ) from None
    CosimLogging.log_output_level(CosimLogging.CosimLogLevel.ERROR)
    return CosimExecution, CosimLocalSlave, CosimObserver, CosimVariableType


def run_libcosim(plan: Plan, values: dict[str, Value], stop: float, step: float) -> Trajectory:
    """Co-simulate ``plan`` with libcosim from 0 to the last whole step before ``stop``.

    libcosim counts time in whole nanoseconds and steps of one size, so the
    trajectory ends at the last whole step; it starts at the first step
    (libcosimpy's sample reader cannot return step 0 together with the rest).
    """
    execution_type, slave_type, observer_type, variable_type = _libcosim()
    step_ns = round(step * 1e9)
    n_steps = int(np.floor(stop / step + 1e-9))
    execution = execution_type.from_step_size(step_ns)
    index = {
        name: execution.add_local_slave(slave_type(fmu_path=str(path), instance_name=name))
        for name, path in plan.fmu_paths.items()
    }
    for ref, value in values.items():
        variable = plan.variable(ref, "setting")
        slave = index[variable.instance]
        ok = (
            execution.string_initial_value(slave, variable.vr, str(value))
            if variable.type == "String"
            else execution.real_initial_value(slave, variable.vr, float(value))
        )
        if not ok:
            raise DseError(f"libcosim refused the initial value {ref}={value!r}")
    for source, target in plan.connections:
        execution.connect_real_variables(index[source.instance], source.vr, index[target.instance], target.vr)
    observer = observer_type.create_time_series()
    execution.add_observer(observer)
    recorded = [v for vs in plan.outputs.values() for v in vs]
    for v in recorded:
        observer.start_time_series(index[v.instance], v.vr, variable_type.REAL)
    if not execution.simulate_until(n_steps * step_ns):
        raise DseError("libcosim's simulation failed")
    columns, time = [], None
    for v in recorded:
        time_ns, _, samples = observer.time_series_real_samples(index[v.instance], v.vr, 1, n_steps)
        columns.append(samples)
        time = np.asarray(time_ns, dtype=float) * 1e-9
    return Trajectory(time, plan.recorded, np.column_stack(columns))
