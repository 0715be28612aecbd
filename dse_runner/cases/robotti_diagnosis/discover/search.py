"""Discovery, stage 2: the Robotti's term search as the engine runs it (analysis/diagnose/discovery.py):
terms proposed from each parent fit's equation error (propose.py), each the correction block's ``corr_*``
parameter of the effects FMU (correction.py) and the shapes it holds; the engine frees them
(TermSearch.with_terms).

The engine then ranks the proposals on the fix residuals (analysis/diagnose/term_ranking.py), proposes on
every fold's own runs, settles, proves and accepts them with the library's rule and the search charged;
this module says only what a term of this vehicle is."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ....analysis.diagnose.fitter import Fitter
from ....analysis.diagnose.term_search import TermSearch
from ....sweeps.fit import FitResult, Parameter, Residuals
from .. import correction
from .observe import Observed, vehicle_values
from .propose import CorrectionProposal, propose, regressions, searched_count


@dataclass
class CorrectionSearch(TermSearch):
    """The correction block's terms on ``vehicle``, proposed from the recorded ``runs`` (observe.py) at each
    parent fit's values (the multi-model's ``fixed`` ones under them); ``fits``: the whole diagnosis' (a
    proposal on all its scenarios sizes the terms)."""

    fits: Fitter | None = None
    vehicle: str = "vehicle"
    runs: Sequence[Observed] = ()
    fixed: Mapping[str, Any] = field(default_factory=dict)
    max_terms: int = 3
    rms: dict[str, float] = field(default_factory=dict)  # each term's feature RMS over the runs: its bound

    @property
    def offered(self) -> int:
        return searched_count()

    def is_term(self, name: str) -> bool:
        return correction.is_correction(name)

    def propose(
        self, parent: FitResult, scenarios: Sequence[str], residuals: Residuals
    ) -> CorrectionProposal:
        by_name = {r.name: r for r in self.runs}
        mine = [by_name[n] for n in scenarios if n in by_name]
        values = vehicle_values(parent.point, self.vehicle, self.fixed)
        found = propose(
            regressions(mine, values, {r.name: residuals(parent.point, r.name) for r in mine}), self.max_terms
        )
        # every run's features size the terms; a fold's fill in only what every run's left out
        whole = self.fits is None or tuple(scenarios) == self.fits.scenarios
        self.rms.update(found.rms if whole else {v: x for v, x in found.rms.items() if v not in self.rms})
        return found

    def parameter(self, variable: str) -> Parameter:
        """The term bounded by correction.bound over the runs' feature RMS."""
        return correction.parameter(correction.term(variable), self.vehicle, self.rms.get(variable))

    def held(self, shapes: Mapping[str, float], variables: Sequence[str]) -> dict[str, float]:
        """The shapes the terms ``variables`` depend on, as the vehicle's parameters at their found values (a
        shape no term uses changes nothing, and leaving it at its default keeps the points the store has)."""
        out = {}
        for v in variables:
            shape = correction.shape_of(correction.term(v))
            if shape is not None and shape.variable in shapes:
                out[f"{self.vehicle}.{shape.variable}"] = shapes[shape.variable]
        return out
