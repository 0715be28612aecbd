"""The contract of a term search: what a library supplies when discovery (discovery.py) looks beyond it.

Why a module of its own: discovery's procedure and its ranking of proposed terms on the residuals
(term_ranking.py) both work on what a search proposes, and neither should import the other for it. A case
reads this one file to know its duties, as an Optuna sampler reads ``BaseSampler``.

The lifecycle, as :func:`discovery.discover` runs it: :meth:`TermSearch.propose` on each parent fit (the
reference answer's, each fold's), every proposal ranked on the parents' residuals by the engine
(term_ranking.py: each term probed as :meth:`TermSearch.parameter` at the shapes :meth:`TermSearch.held`
holds), then :meth:`TermSearch.with_terms` (the engine's: each term freed as its parameter, its shapes
held) for every fit of the terms, which :meth:`TermSearch.is_term` tells apart from the library's
parameters; the extended BIC charges for :attr:`TermSearch.offered`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from ...sweeps.fit import FitProblem, FitResult, Parameter, Residuals
from .proof import extended_margin
from .sparse_regression import PRUNE_SE, pruned


class Proposal(Protocol):
    """What a search proposes for one parent fit: the terms to fit (name -> starting coefficient), every term
    it would offer best first (the slots pruning frees go to the next of them), the values of any shape the
    terms were made at, and how sure it is of each term it picked (a share; {} where it does not say). A
    dataclass: the ranking (term_ranking.py) gives it new ``terms`` and ``ranked`` by dataclasses.replace."""

    terms: Mapping[str, float]
    ranked: Sequence[tuple[str, float]]
    shapes: Mapping[str, float]
    inclusion: Mapping[str, float]

    @property
    def empty(self) -> bool: ...

    def readable(self) -> list[str]: ...


@dataclass(frozen=True)
class Parent:
    """A fit discovery proposes on top of: where it stands, on which scenarios, what was proposed there and
    its parameters' bounds (what a linearised ranking may move them by)."""

    fit: FitResult
    scenarios: tuple[str, ...]
    proposal: Proposal
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    def moves(self) -> tuple[np.ndarray, np.ndarray]:
        """How far each of the parent's parameters (``fit.names``) may move from its fitted value, down and
        up."""
        low = [self.bounds.get(n, (-math.inf, math.inf))[0] - self.fit.values[n] for n in self.fit.names]
        high = [self.bounds.get(n, (-math.inf, math.inf))[1] - self.fit.values[n] for n in self.fit.names]
        return np.minimum(low, 0.0), np.maximum(high, 0.0)


class TermSearch(ABC):
    """What a library supplies to search beyond itself; the engine runs the procedure (discovery.discover).

    Required: :meth:`propose` (terms from a parent fit and its residuals), :meth:`parameter` (the fit's
    parameter a term is: a term is absent at 0, its range symmetric about it; the ranking probes it by its
    step from its parent's value and bounds its coefficient by ± its upper end, and every fit of the terms
    frees it), :meth:`is_term` (which fitted parameters are terms) and :attr:`offered` (how many terms the
    search chooses among: the extended BIC charges for it). Optional: :meth:`held` (the shapes a term was made
    at, held wherever it is simulated; none by default) and :meth:`readable`. The engine's own:
    :meth:`with_terms` (a fit problem with terms freed, from those two)."""

    max_terms: int = 3  # terms a candidate holds at most

    @property
    @abstractmethod
    def offered(self) -> int: ...

    @abstractmethod
    def is_term(self, name: str) -> bool: ...

    @abstractmethod
    def propose(self, parent: FitResult, scenarios: Sequence[str], residuals: Residuals) -> Proposal:
        """Terms on top of ``parent`` from ``scenarios`` alone (``residuals``: every parent's, evaluated)."""

    @abstractmethod
    def parameter(self, variable: str) -> Parameter:
        """The fit's parameter for the term ``variable`` (its full name, range and finite-difference step)."""

    def held(self, shapes: Mapping[str, float], variables: Sequence[str]) -> dict[str, float]:
        """The fixed values a point needs for the terms ``variables`` made at ``shapes`` (shape -> value, as
        a proposal holds them): none when terms have no shape."""
        return {}

    def with_terms(
        self,
        problem: FitProblem,
        terms: Mapping[str, float],
        start: Mapping[str, float],
        shapes: Mapping[str, float],
    ) -> FitProblem:
        """``problem`` with ``terms`` (variable -> proposed value) freed as their :meth:`parameter`, each from
        ``start`` (a fitted point, by full name) where it has it, else from its proposed value, clipped into
        its range; a term the problem held fixed is freed, and the ``shapes`` the terms were made at are
        held (:meth:`held`)."""
        extra = tuple(started(self.parameter(variable), start, value) for variable, value in terms.items())
        names = {p.name for p in extra}
        return replace(
            problem,
            parameters=problem.parameters + extra,
            fixed={
                **{k: v for k, v in problem.fixed.items() if k not in names},
                **self.held(shapes, list(terms)),
            },
        )

    def terms_of(self, fit: FitResult) -> dict[str, float]:
        """The terms a fit moved, by local name (the part after the instance)."""
        return {n.rsplit(".", 1)[-1]: v for n, v in fit.values.items() if self.is_term(n)}

    def standing(self, fit: FitResult, factor: float = PRUNE_SE) -> dict[str, float]:
        """The fitted terms at least ``factor`` cluster-robust standard errors from zero (sparse_regression
        .pruned: an undetermined one goes), by local name."""
        kept = pruned(fit, [n for n in fit.values if self.is_term(n)], factor)
        return {name.rsplit(".", 1)[-1]: fit.values[name] for name in kept}

    def readable(self, values: Mapping[str, float]) -> list[str]:
        """The terms among ``values`` as a reader reads them (by default, name = value)."""
        return [f"{name} = {value:.4g}" for name, value in values.items() if self.is_term(name)]

    def charged(self, bic_margin: float, terms: int) -> float:
        """The BIC margin ``terms`` found terms must beat (proof.extended_margin)."""
        return extended_margin(bic_margin, self.offered, terms)


def started(parameter: Parameter, start: Mapping[str, float], value: float) -> Parameter:
    """``parameter`` starting from its value in ``start`` (a fitted point) if it has one, else from
    ``value``, clipped into its range: a fit never starts outside its bounds."""
    at = start.get(parameter.name, value)
    return replace(parameter, start=float(np.clip(at, parameter.lower, parameter.upper)))
