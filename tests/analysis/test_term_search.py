"""The engine's side of the term-search contract (analysis/diagnose/term_search.py): how any case's terms
are freed in a fit, from nothing but the parameter each term is and the shapes it holds."""

from __future__ import annotations

from dse_runner.analysis.diagnose.term_search import TermSearch
from dse_runner.sweeps.fit import FitProblem, Parameter


class Terms(TermSearch):
    """Terms ``m.<name>`` within ±1; the term ``late`` is made at a shape, ``m.onset``."""

    offered = 10

    def is_term(self, name: str) -> bool:
        return name.startswith("m.")

    def parameter(self, variable: str) -> Parameter:
        return Parameter(f"m.{variable}", 0.0, -1.0, 1.0, 1e-3)

    def held(self, shapes, variables):
        return {"m.onset": shapes["onset"]} if "late" in variables else {}

    def propose(self, parent, scenarios, residuals):  # not used here
        raise NotImplementedError


def test_terms_are_freed_from_the_fitted_point_else_their_proposed_value_within_their_range():
    """A term starts where a fitted point has it, else at its proposed value, clipped into its range (a fit
    never starts outside its bounds); a term the problem held fixed is freed rather than both fixed and
    fitted; the shape a term was made at is held; everything else of the problem stays."""
    mass = Parameter("m.mass", 2.0, 1.0, 3.0, 1e-3)
    problem = FitProblem("base", (mass,), {"m.late": 0.0, "m.gear": 4.0}, ("run",))
    freed = Terms().with_terms(
        problem, {"late": 0.2, "wanted": 5.0}, {"m.late": -0.4, "m.mass": 2.5}, {"onset": 0.5}
    )
    assert freed.parameters == (
        mass,
        Parameter("m.late", -0.4, -1.0, 1.0, 1e-3),
        Parameter("m.wanted", 1.0, -1.0, 1.0, 1e-3),
    )
    assert freed.fixed == {"m.gear": 4.0, "m.onset": 0.5}
    assert (freed.label, freed.scenarios) == (problem.label, problem.scenarios)


def test_terms_without_a_shape_hold_nothing_more():
    """A term made at no shape adds no fixed value: the points the store already has stay the same."""
    problem = FitProblem("base", (), {"m.gear": 4.0}, ("run",))
    freed = Terms().with_terms(problem, {"wanted": 0.1}, {}, {"onset": 0.5})
    assert freed.parameters == (Parameter("m.wanted", 0.1, -1.0, 1.0, 1e-3),)
    assert freed.fixed == {"m.gear": 4.0}
