"""What every file format's pydantic model shares: how strictly a file is read.

Why one place: a space, a multi-model, a scenario, a cluster kind's block and an INTO-CPS file are
each read by pydantic models (beside the code that uses them) held to one rule: an unknown key is a
typo, and NaN or infinity is not a number a file means. Written once, the rule cannot drift.
"""

from __future__ import annotations

from pydantic import ConfigDict

Strict = ConfigDict(extra="forbid", allow_inf_nan=False)  # unknown keys, NaN and infinity are errors
Extensible = ConfigDict(
    extra="allow", allow_inf_nan=False
)  # keys besides the model's go to a plug-in's own model
