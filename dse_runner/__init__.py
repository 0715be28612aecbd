"""dse-runner: design-space exploration for FMI co-simulation, from one machine to a cluster.

The Python API mirrors the CLI; ``dse-runner simulate`` is :func:`simulate`::

    from dse_runner import simulate
    result = simulate("tank.fmu", stop_time=50, values={"area": 2.0})
    result.time, result.outputs["tank.level"], result.objectives
"""

from typing import Any

from .errors import DseError

__version__ = "0.1.0"

__all__ = ["DseError", "__version__", "simulate"]


def __getattr__(name: str) -> Any:
    """``simulate`` is imported on first use: the CLI's start-up need not load FMPy."""
    if name == "simulate":
        from .simulation.run import simulate

        return simulate
    raise AttributeError(f"module 'dse_runner' has no attribute {name!r}")
