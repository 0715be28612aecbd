"""Discovery, stage 3: the Robotti's term search as the engine runs it (analysis/diagnose/discovery.py):
terms proposed from each parent fit's equation error (propose.py), ranked on positions (rank_terms.py) and
freed as the correction block's ``corr_*`` parameters of the effects FMU (correction.py).

The engine then proposes on every fold's own runs, settles, proves and accepts them with the library's
rule and the search charged; this module says only what a term of this vehicle is."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from ....analysis.diagnose.discovery import Parent, Proposal, TermSearch
from ....analysis.diagnose.fitter import Fitter
from ....sweeps.fit import FitProblem, FitResult, Residuals
from .. import correction
from .observe import Observed, vehicle_values
from .propose import CorrectionProposal, propose, regressions
from .rank_terms import held_shapes, screened, searched_count


@dataclass
class CorrectionSearch(TermSearch):
    """The correction block's terms on ``vehicle``, proposed from the recorded ``runs`` (observe.py) at each
    parent fit's values (the multi-model's ``fixed`` ones under them), ranked at ``fits``."""

    fits: Fitter | None = None
    vehicle: str = "vehicle"
    runs: Sequence[Observed] = ()
    fixed: Mapping[str, Any] = field(default_factory=dict)
    max_terms: int = 3
    bic_margin: float = 10.0
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

    def ranked(self, parents: Mapping[str, Parent]) -> dict[str, Proposal]:
        assert self.fits is not None, "ranking on positions simulates: the search needs the fits"
        return screened(self.fits, self.vehicle, parents, self.rms, self.max_terms, self.bic_margin)

    def with_terms(
        self,
        problem: FitProblem,
        terms: Mapping[str, float],
        start: Mapping[str, float],
        shapes: Mapping[str, float],
    ) -> FitProblem:
        """Each term bounded by correction.bound over the runs' feature RMS; the shapes the terms depend on
        held at their values in ``shapes``."""
        extra = tuple(
            correction.parameter(
                correction.term(variable),
                self.vehicle,
                self.rms.get(variable),
                start.get(f"{self.vehicle}.{variable}", value),
            )
            for variable, value in terms.items()
        )
        names = {p.name for p in extra}
        held = held_shapes(shapes, self.vehicle, list(terms))
        return replace(
            problem,
            parameters=problem.parameters + extra,
            fixed={**{k: v for k, v in problem.fixed.items() if k not in names}, **held},
        )
