"""JSON that every parser accepts: what ``--json`` prints and the JSON files we write.

Python's ``json`` writes ``NaN`` and ``Infinity``, which are not JSON; a missing or
undefined number is written as ``null`` instead, so scripts never choke on our output.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd


def plain(value: Any) -> Any:
    """``value`` with numpy scalars made Python ones and every non-finite number made None."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, np.ndarray) and value.ndim == 0:
        return plain(value.item())
    if isinstance(value, (list, tuple, np.ndarray)):
        return [plain(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if value is pd.NA or value is pd.NaT:
        return None
    return value


def dumps(data: Any, indent: int | None = 2) -> str:
    """Strict JSON text; anything else JSON has no type for (paths, times) as its string."""
    return json.dumps(plain(data), indent=indent, allow_nan=False, default=str)
