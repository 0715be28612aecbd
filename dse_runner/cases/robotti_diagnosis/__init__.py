"""The Robotti's diagnosis: calibrate, locate the mismatch, explain it, model it, show the fit improve.

The field robot's hypothesis library, registered with ``diagnose`` as the plug-in ``robotti``
(library.py; the core's contract is dse_runner/analysis/diagnose/library.py). :func:`diagnose` runs
the whole chain on a folder of runs in the field-data format. Every simulation is a task of a sweep
on the Dask cluster, with rows in the Parquet store under ``out``: the calibration grid is an ordinary
sweep, and each fit (fit.py) runs its rounds as sweeps of the *effects* multi-model, the user's
multi-model with the vehicle replaced by its effects variant, in which every hypothesis of the
library is a parameter that is zero when absent.

The package reads in the order data flows: ``workflow`` (the steps, :func:`diagnose`) over
``chain`` (fits as sweeps) and ``model_files`` (what it reads and writes), with the results in
``outcome``; the steps' own modules are noise, locate, segments, lookalike, discover/ and report, with
the combination screen (linearised unless the settings name another) and the choice among candidates in
the core (analysis/diagnose/screens/, explain.py). This module re-exports what users import.
"""

from .chain import Chain, DiagnosisMessages
from .library import RobottiLibrary
from .outcome import Diagnosis, DiagnosisSettings
from .workflow import DEFAULT_SPACE, diagnose, diagnose_calibration

__all__ = [
    "DEFAULT_SPACE",
    "Chain",
    "Diagnosis",
    "DiagnosisMessages",
    "DiagnosisSettings",
    "RobottiLibrary",
    "diagnose",
    "diagnose_calibration",
]
