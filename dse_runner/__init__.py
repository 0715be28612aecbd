"""dse-runner: design-space exploration for FMI co-simulation, from one machine to a cluster.

The Python API mirrors the CLI, a function per command (docs/python.md)::

    from dse_runner import simulate, submit
    result = simulate("tank.fmu", stop_time=50, values={"area": 2.0})
    result.time, result.outputs["tank.level"], result.objectives

    study = submit("space.yaml")          # a Study: results(), rank(), best, report(path)
    study.results(), study.best

and ``rank``, ``report``, ``sensitivity`` and ``diagnose`` likewise (interfaces/api.py).
"""

from typing import Any

from .errors import DseError

__version__ = "0.1.0"

# Imported on first use: the CLI's start-up need not load FMPy, Dask or pandas. Name -> its module.
_LAZY = {
    "simulate": ".simulation.run",
    "submit": ".interfaces.api",
    "Study": ".interfaces.api",
    "rank": ".interfaces.api",
    "report": ".interfaces.api",
    "sensitivity": ".interfaces.api",
    "diagnose": ".interfaces.api",
    "Diagnosis": ".interfaces.api",
    "Interrupted": ".interfaces.api",
}

__all__ = [
    "Diagnosis",
    "DseError",
    "Interrupted",
    "Study",
    "__version__",
    "diagnose",
    "rank",
    "report",
    "sensitivity",
    "simulate",
    "submit",
]


def __getattr__(name: str) -> Any:
    """The API's functions are imported on first use (``_LAZY``)."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module 'dse_runner' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])
