"""A genetic algorithm (pymoo's GA) that reads INTO-CPS's genetic options.

INTO-CPS's DSE offers a genetic search configured in the DSE file's
``algorithm`` (the INTO-CPS application: ``initialPopulation``,
``initialPopulationDistribution``, ``mutationProbability``,
``parentSelectionStrategy``, ``maxGenerationsWithoutImprovement``) or in
``geneticArguments`` (the Python 3 dse_scripts: ``popSize``,
``maxGenerations``, ``mutationChance``, ``crossingFunction``). Both spellings
are accepted under ``search:``, beside our own snake_case names.

A GA needs whole generations: it asks a population's points, waits until all
are told, then breeds the next. Genes live in the unit cube (domain.py), so
intervals, grids and choices mix. Points the constraints reject and points
that fail to simulate are infeasible to pymoo (constraint violation 1), so
selection avoids them without their ever being simulated.
"""

from __future__ import annotations

from collections import defaultdict, deque
from typing import Literal

import numpy as np
from pydantic import AliasChoices, Field, PositiveInt
from pymoo.algorithms.soo.nonconvex.ga import GA
from pymoo.core.evaluator import Evaluator
from pymoo.core.problem import Problem as PymooProblem
from pymoo.operators.crossover.pntx import TwoPointCrossover
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.crossover.ux import UniformCrossover
from pymoo.operators.mutation.pm import PM
from pymoo.operators.sampling.lhs import LHS
from pymoo.operators.sampling.rnd import FloatRandomSampling
from pymoo.operators.selection.rnd import RandomSelection
from pymoo.operators.selection.tournament import TournamentSelection, compare
from pymoo.problems.static import StaticProblem

from ..domain import Point, from_units
from ..search import Evaluation, Options, Problem, Strategy


class GeneticOptions(Options):
    population: PositiveInt = Field(
        20, validation_alias=AliasChoices("population", "initialPopulation", "popSize")
    )
    distribution: Literal["random", "uniform"] = (
        Field(  # uniform: a Latin hypercube spreads the first generation
            "random", validation_alias=AliasChoices("distribution", "initialPopulationDistribution")
        )
    )
    mutation_probability: float | None = Field(  # per gene; default 1 / number of parameters
        None,
        ge=0,
        le=1,
        validation_alias=AliasChoices("mutation_probability", "mutationProbability", "mutationChance"),
    )
    parent_selection: Literal["algorithmObjectiveSpace", "tournament", "random"] = Field(
        "tournament", validation_alias=AliasChoices("parent_selection", "parentSelectionStrategy")
    )
    crossover: Literal["SBX", "UniformCrossing", "NPointCrossing"] = Field(
        "SBX", validation_alias=AliasChoices("crossover", "crossingFunction")
    )
    max_generations: PositiveInt | None = Field(
        None, validation_alias=AliasChoices("max_generations", "maxGenerations")
    )
    max_generations_without_improvement: PositiveInt | None = Field(
        None,
        validation_alias=AliasChoices(
            "max_generations_without_improvement", "maxGenerationsWithoutImprovement"
        ),
    )


def _binary_tournament(pop, P, **kwargs):
    """The fitter of two (feasible first, then by objective): pymoo's comparison, our wiring."""
    winners = np.empty(len(P), dtype=int)
    for i, (a, b) in enumerate(P):
        cv_a, cv_b = pop[a].CV[0], pop[b].CV[0]
        if cv_a > 0 or cv_b > 0:
            winners[i] = compare(a, cv_a, b, cv_b, method="smaller_is_better", return_random_if_equal=True)
        else:
            winners[i] = compare(
                a, pop[a].F[0], b, pop[b].F[0], method="smaller_is_better", return_random_if_equal=True
            )
    return winners[:, None]


class Genetic(Strategy):
    """pymoo's GA, generation by generation."""

    Options = GeneticOptions

    def __init__(self, problem: Problem):
        super().__init__(problem)
        o: GeneticOptions = self.options
        self.dimensions = list(problem.dimensions)
        self.sign = 1.0 if problem.objective[1] == "min" else -1.0
        self.pymoo_problem = PymooProblem(n_var=len(self.dimensions), n_obj=1, n_ieq_constr=1, xl=0.0, xu=1.0)
        crossover = {
            "SBX": SBX(),
            "UniformCrossing": UniformCrossover(),
            "NPointCrossing": TwoPointCrossover(),
        }
        self.algorithm = GA(
            pop_size=o.population,
            sampling=LHS() if o.distribution == "uniform" else FloatRandomSampling(),
            selection=RandomSelection()
            if o.parent_selection == "random"
            else TournamentSelection(func_comp=_binary_tournament),
            crossover=crossover[o.crossover],
            mutation=PM(prob_var=o.mutation_probability) if o.mutation_probability is not None else PM(),
            eliminate_duplicates=True,
        )
        self.algorithm.setup(
            self.pymoo_problem, termination=("n_gen", 10**9), seed=problem.seed, verbose=False
        )
        self.generation = 0
        self.best = np.inf
        self.stale = 0  # generations without improvement
        self._breed()

    def _breed(self) -> None:
        self.population = self.algorithm.ask()
        self.points = [from_units(self.dimensions, x) for x in self.population.get("X")]
        self.unasked = deque(range(len(self.points)))
        self.waiting: defaultdict[tuple, deque[int]] = defaultdict(deque)
        self.F = np.zeros((len(self.points), 1))
        self.G = np.zeros((len(self.points), 1))
        self.told = 0

    def ask(self) -> Point | None:
        if not self.unasked or self._finished():
            return None  # the rest of the generation is still simulating, or the GA has stopped
        index = self.unasked.popleft()
        point = self.points[index]
        self.waiting[tuple(sorted(point.items()))].append(index)
        return point

    def tell(self, point: Point, evaluation: Evaluation) -> None:
        index = self.waiting[tuple(sorted(point.items()))].popleft()
        if evaluation.state == "ok":
            self.F[index, 0] = self.sign * evaluation.value(self.problem.objective[0])
            self.G[index, 0] = float(
                len(evaluation.breaks)
            )  # ranking constraints broken: not selected over one that keeps them
        else:
            self.G[index, 0] = 1.0  # infeasible or failed: never selected over a feasible point
        self.told += 1
        if self.told == len(self.points):
            Evaluator().eval(StaticProblem(self.pymoo_problem, F=self.F, G=self.G), self.population)
            self.algorithm.tell(infills=self.population)
            self._generation_done()
            self._breed()

    def _generation_done(self) -> None:
        self.generation += 1
        feasible = self.F[self.G[:, 0] <= 0, 0]
        best = float(feasible.min()) if feasible.size else np.inf
        if best < self.best:
            self.best, self.stale = best, 0
        else:
            self.stale += 1

    def _finished(self) -> bool:
        o: GeneticOptions = self.options
        return (o.max_generations is not None and self.generation >= o.max_generations) or (
            o.max_generations_without_improvement is not None
            and self.stale >= o.max_generations_without_improvement
        )
