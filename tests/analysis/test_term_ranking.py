"""The engine's ranking of proposed terms on the residuals (analysis/diagnose/term_ranking.py), the
bounded least-squares step it shares with the linearised screen (analysis/diagnose/linear_step.py), and how
a fit frees the terms (analysis/diagnose/term_search.py, TermSearch.with_terms): what every case's term
search is ranked and fitted by, whatever its terms are."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pytest

from dse_runner.analysis.diagnose import term_ranking
from dse_runner.analysis.diagnose.linear_step import bounded_step
from dse_runner.analysis.diagnose.proof import extended_margin
from dse_runner.analysis.diagnose.term_search import Parent, TermSearch
from dse_runner.sweeps.fit import FitProblem, FitResult, Parameter

OFFERED = 150  # terms the search chooses among: the extended BIC charges for them


def margin(k: int) -> float:
    return extended_margin(10.0, OFFERED, k)


def test_terms_are_ranked_by_what_they_do_to_the_residuals():
    """Forward selection on the residuals, linearised: the two terms that are the residuals' shape win over
    a pair that only stands in for one of them (each alone barely moves the residuals), a term that
    explains nothing is left out however many slots remain, and on noise alone no term pays the BIC
    margin."""
    rng = np.random.default_rng(3)
    psi = np.linspace(0.0, 4 * np.pi, 2000)
    sin, cos = np.sin(psi), np.cos(psi)
    wobble = rng.normal(size=psi.size)
    columns = {
        "stand_in_a": cos + 3.0 * wobble,
        "stand_in_b": -3.0 * wobble,  # their sum is cos
        "sin": sin,
        "cos": cos,
        "unrelated": rng.normal(size=psi.size),
    }
    bounds = dict.fromkeys(columns, 10.0)
    base = np.ones((psi.size, 1))  # a calibrated parameter: an offset, refitted with every set
    noise = 0.02 * rng.normal(size=psi.size)
    r = -(0.15 * sin - 0.13 * cos) + 0.05 + noise  # the residuals the terms should cancel
    chosen, rest = term_ranking.forward_selection(r, base, columns, bounds, 3, margin)
    assert [v for v, _ in chosen] == ["sin", "cos"]
    assert dict(chosen)["sin"] == pytest.approx(0.15, abs=0.01)
    assert dict(chosen)["cos"] == pytest.approx(-0.13, abs=0.01)
    assert set(rest) == {"stand_in_a", "stand_in_b", "unrelated"}
    assert term_ranking.forward_selection(noise, base, columns, bounds, 3, margin)[0] == []


def test_a_bounded_step_stops_at_its_bounds_whatever_the_units():
    """The step that cancels the residuals when the bounds allow it; clipped to a bound otherwise, with the
    SSE it then leaves; a column's scale changes neither."""
    column = np.linspace(-1.0, 1.0, 50)
    jacobian = column[:, None]
    residuals = -0.5 * column
    for steps in (None, np.array([1.0]), np.array([1e-4])):
        step, sse = bounded_step(jacobian, residuals, np.array([-1.0]), np.array([1.0]), steps)
        assert step == pytest.approx([0.5]) and sse == pytest.approx(0.0, abs=1e-20)
        step, sse = bounded_step(jacobian, residuals, np.array([-1.0]), np.array([0.2]), steps)
        assert step == pytest.approx([0.2]) and sse == pytest.approx(0.09 * float(column @ column))


@dataclass(frozen=True)
class Proposed:
    terms: Mapping[str, float]
    ranked: tuple[tuple[str, float], ...]
    shapes: Mapping[str, float] = field(default_factory=dict)
    inclusion: Mapping[str, float] = field(default_factory=dict)

    @property
    def empty(self) -> bool:
        return not self.terms

    def readable(self) -> list[str]:
        return list(self.terms)


class Terms(TermSearch):
    """Terms ``m.<name>``; the term ``late`` is made at a shape, ``m.onset``, which its probe must hold."""

    offered = OFFERED

    def is_term(self, name: str) -> bool:
        return name.startswith("m.")

    def parameter(self, variable: str) -> Parameter:
        return Parameter(f"m.{variable}", 0.0, -1.0, 1.0, 1e-3)

    def held(self, shapes, variables):
        return {"m.onset": shapes["onset"]} if "late" in variables else {}

    def propose(self, parent, scenarios, residuals):  # the proposals are given
        raise NotImplementedError


class Linear:
    """A fitter whose residuals are linear in the terms: the recording is 0.3 of ``wanted``'s column, each
    term takes its column times its value off it; ``late``'s column is that only at the onset it was made
    at. Records every sweep it is asked for."""

    scenarios = ("run",)

    def __init__(self):
        t = np.linspace(0.0, 1.0, 400)
        self.columns = {"wanted": np.sin(7 * t), "other": np.cos(3 * t), "late": (t > 0.5) * 1.0}
        self.sweeps: list[list[dict]] = []

    def evaluate(self, points, scenarios=None):
        self.sweeps.append(list(points))

        def residuals(point, scenario):
            late = self.columns["late"] if point.get("m.onset") == 0.5 else np.zeros(400)
            columns = {**self.columns, "late": late}
            moved = sum(point.get(f"m.{v}", 0.0) * c for v, c in columns.items())
            return 0.3 * self.columns["wanted"] - moved

        return residuals


def test_every_proposal_is_ranked_again_on_its_parents_residuals_in_one_sweep():
    """The search's own order (an unrelated term first) gives way to the term the residuals want, sized as
    they want it; the terms that do not pay stay behind it in the order, for the slots pruning frees; a
    shaped term is probed at its shape; a parent that proposed nothing is left as it is; one sweep in all."""
    f = Linear()
    parent = FitResult("none", [], {}, 1.0, 400, 1, True, {}, [], {})
    proposal = Proposed({"other": 1.0}, (("other", 1.0), ("late", 0.1), ("wanted", 0.1)), {"onset": 0.5})
    nothing = Proposed({}, ())
    parents = {"full": Parent(parent, ("run",), proposal), "fold": Parent(parent, ("run",), nothing)}
    out = term_ranking.ranked(f, Terms(), parents, 10.0)
    assert list(out["full"].terms) == ["wanted"] and out["full"].terms["wanted"] == pytest.approx(0.3)
    order = [v for v, _ in out["full"].ranked]
    assert order[0] == "wanted" and set(order) == {"wanted", "other", "late"}
    assert out["full"].shapes == {"onset": 0.5}  # the rest of the proposal is kept
    assert out["fold"] is nothing
    [sweep] = f.sweeps
    assert {"m.late": 1e-3, "m.onset": 0.5} in sweep  # the shaped term's probe holds its shape


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
