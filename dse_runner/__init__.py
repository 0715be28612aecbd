"""dse-runner: design-space exploration for FMI co-simulation, from one machine to a cluster.

The Python API mirrors the CLI; ``dse-runner simulate`` is :func:`simulate`.
"""

from .errors import DseError

__version__ = "0.1.0"

__all__ = ["DseError", "__version__"]
