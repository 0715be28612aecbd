"""Optuna's samplers as strategies: tpe, gp (Bayesian optimisation), cmaes, nsga2 (multi-objective).

Each wraps an in-memory Optuna study driven by ``study.ask``/``study.tell``,
Optuna's own interface for optimisation loops it does not run itself. Trials
in flight are Optuna's "running" trials, which GP (batch acquisition) and TPE
(with ``constant_liar: true``, an option) take into account, so points can be asked
while others still simulate. A failed point is a failed trial. A point the constraints reject
is a complete trial with the worst value seen so far, marked infeasible with
Optuna's own ``Trial.set_constraint``, which TPE, GP and NSGA-II read, so the
sampler learns where the feasible region is instead of proposing the same
infeasible region again and again.

The strategy's options are the sampler's own keyword arguments, e.g.
``search: {strategy: tpe, n_startup_trials: 5}``; ``seed`` is the search's;
gp adds ``acquisition_samples`` and ``local_searches`` (GPSampler below).
"""

from __future__ import annotations

import inspect
import warnings
from collections import defaultdict, deque
from typing import Any, ClassVar

import optuna
from optuna.distributions import BaseDistribution, CategoricalDistribution, FloatDistribution, IntDistribution
from optuna.trial import TrialState
from pydantic import BaseModel

from ...errors import DseError
from ...schema import Extensible
from ..domain import Dimension, Point
from ..search import Evaluation, Problem, Strategy

NOT_OPTIONS = {
    "self",
    "seed",
    "constraints_func",
    "independent_sampler",
    "source_trials",
    "gamma",
    "weights",
    "mutation",
    "crossover",
    "elite_population_selection_strategy",
    "child_generation_strategy",
    "after_trial_strategy",
}  # set by us, or not expressible in YAML


class SamplerOptions(BaseModel):
    model_config = Extensible


def distribution(dimension: Dimension) -> BaseDistribution:
    d = dimension
    if d.choices is not None:
        return CategoricalDistribution(list(d.choices))
    if d.step is not None:
        return FloatDistribution(d.low, d.high, step=d.step)
    if d.integer:
        return IntDistribution(int(d.low), int(d.high), log=d.log)
    return FloatDistribution(d.low, d.high, log=d.log)


def keyword_options(kind: type) -> set[str]:
    """The keyword arguments a sampler class takes: its own, and its base's if it passes ``**options`` on."""
    parameters = inspect.signature(kind.__init__).parameters.values()
    names = {p.name for p in parameters if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)}
    if any(p.kind is p.VAR_KEYWORD for p in parameters) and kind.__base__ is not object:
        names |= keyword_options(kind.__base__)
    return names


VIOLATION = (
    "space.yaml constraints"  # the trial's constraint value: > 0 where the constraints reject the point
)


def _key(point: Point) -> tuple:
    return tuple(sorted(point.items()))


class OptunaStrategy(Strategy):
    """An Optuna sampler asked and told through an in-memory study."""

    sampler: ClassVar[type[optuna.samplers.BaseSampler]]
    reads_constraints: ClassVar[bool] = True  # the sampler uses Trial.set_constraint
    Options = SamplerOptions

    def __init__(self, problem: Problem):
        super().__init__(problem)
        accepted = keyword_options(self.sampler) - NOT_OPTIONS
        options = dict(self.options.model_extra or {})
        for name in options:
            if name not in accepted:
                raise DseError(
                    f"search.{name}: {self.sampler.__name__} has no option {name!r} "
                    f"(it takes {', '.join(sorted(accepted))})"
                )
        optuna.logging.set_verbosity(optuna.logging.WARNING)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            try:
                sampler = self.sampler(seed=problem.seed, **{**self.defaults(), **options})
            except (TypeError, ValueError) as e:  # a value of the wrong type or range, as Optuna says
                raise DseError(
                    f"search: {self.sampler.__name__} refuses the options "
                    f"{', '.join(f'{k}={v!r}' for k, v in options.items())}: {e}"
                ) from None
        self.goals = list(problem.pareto) if self.multi_objective else [problem.objective]
        self.study = optuna.create_study(
            sampler=sampler, directions=["minimize" if g == "min" else "maximize" for _, g in self.goals]
        )
        self.distributions = {d.name: distribution(d) for d in problem.dimensions}
        self.trials: defaultdict[tuple, deque[optuna.Trial]] = defaultdict(deque)
        self.worst: list[float] | None = (
            None  # the worst value of each objective so far: an infeasible point's
        )

    def defaults(self) -> dict[str, Any]:
        """Keyword arguments of ours that the user's options may override."""
        return {}

    def ask(self) -> Point | None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            try:
                trial = self.study.ask(self.distributions)
            except (TypeError, ValueError) as e:  # an option Optuna took but cannot use, e.g. a text sigma0
                options = ", ".join(f"{k}={v!r}" for k, v in (self.options.model_extra or {}).items())
                raise DseError(
                    f"search: {self.sampler.__name__} failed to propose a point with the options "
                    f"{options or '(none)'}: {type(e).__name__}: {e}"
                ) from None
        point = {
            name: float(v) if isinstance(v, int) and not isinstance(v, bool) else v
            for name, v in trial.params.items()
        }
        self.trials[_key(point)].append(trial)
        return point

    def tell(self, point: Point, evaluation: Evaluation) -> None:
        trial = self.trials[_key(point)].popleft()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            if evaluation.state == "ok":
                values = [evaluation.value(name) for name, _ in self.goals]
                self._remember(values)
                if evaluation.breaks and not self.reads_constraints:  # it learns only from a penalty
                    self.study.tell(trial, list(self.worst))
                else:
                    self._mark(trial, float(len(evaluation.breaks)))  # > 0: breaks ranking constraints
                    self.study.tell(trial, values)
            elif evaluation.state == "infeasible" and self.worst is not None:
                self._mark(trial, 1.0)
                self.study.tell(trial, list(self.worst))
            else:  # a failed simulation, or infeasible before any result to penalise it with
                self.study.tell(trial, state=TrialState.FAIL)

    def _mark(self, trial: optuna.Trial, violation: float) -> None:
        if self.reads_constraints:
            trial.set_constraint(VIOLATION, violation)

    def _remember(self, values: list[float]) -> None:
        worse = [max if goal == "min" else min for _, goal in self.goals]
        self.worst = values if self.worst is None else [w(a, b) for w, a, b in zip(worse, self.worst, values)]


class Tpe(OptunaStrategy):
    """Tree-structured Parzen estimator: Optuna's default Bayesian optimiser."""

    sampler = optuna.samplers.TPESampler

    def defaults(self) -> dict[str, Any]:
        return {"multivariate": True}  # models the parameters jointly: they interact in a calibration


class GPSampler(optuna.samplers.GPSampler):
    """Optuna's GPSampler, with the effort of its search for each next point as options: QMC points at which
    the acquisition function is first evaluated, then local searches from the best of them. Optuna sets both
    in its constructor (2048 and 10, for any number of parameters) and reads them in ``_optimize_acqf``,
    which its docstring leaves to advanced users."""

    def __init__(self, *, acquisition_samples: int = 2048, local_searches: int = 10, **options: Any):
        super().__init__(**options)
        if acquisition_samples < 1 or local_searches < 1:
            raise ValueError("acquisition_samples and local_searches must be positive")
        effort = {"_n_preliminary_samples": acquisition_samples, "_n_local_search": local_searches}
        for name, value in effort.items():
            if not hasattr(self, name):  # another Optuna: say so rather than set what it no longer reads
                raise ValueError(
                    f"this Optuna's GPSampler has no {name}: acquisition_samples and "
                    "local_searches do not apply"
                )
            setattr(self, name, value)


class GaussianProcess(OptunaStrategy):
    """Gaussian-process Bayesian optimisation (Optuna's GPSampler; needs PyTorch)."""

    sampler = GPSampler

    def __init__(self, problem: Problem):
        try:
            import torch  # noqa: F401  (only whether it is installed)
        except ImportError:
            raise DseError("search strategy 'gp' needs PyTorch: pip install 'dse-runner[gp]'") from None
        super().__init__(problem)

    def defaults(self) -> dict[str, Any]:
        """Cheaper asks, so that the client keeps up with the workers (its asks would otherwise keep them
        waiting: on the paper's calibration an ask cost about as much as a point's 12 simulations). A
        simulation gives the same numbers for the same point, so the model needs no noise term to fit; and a
        quarter of Optuna's acquisition samples and half its local searches found the same points to within
        1% and the same best on that calibration (docs/performance.md). Many parameters may want Optuna's."""
        return {"deterministic_objective": True, "acquisition_samples": 512, "local_searches": 5}

    def ask(self) -> Point | None:
        """With PyTorch on one thread throughout. An ask is many small tensor operations, which more threads
        slow down, and the client shares the cores with the workers (a local cluster starts one a core).
        Optuna's GPSampler limits its kernel fit and local searches so, but not the first evaluation of its
        acquisition samples, the largest part of an ask while points are in flight: left to PyTorch's
        default (a thread a core), asks took twice as long on 2 workers (docs/performance.md)."""
        import torch

        threads = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            return super().ask()
        finally:
            torch.set_num_threads(threads)


class CmaEs(OptunaStrategy):
    """CMA-ES (Optuna's CmaEsSampler over the cmaes package)."""

    sampler = optuna.samplers.CmaEsSampler
    reads_constraints = False  # it ranks an infeasible point by its penalty value alone

    def defaults(self) -> dict[str, Any]:
        return {"warn_independent_sampling": False}


class Nsga2(OptunaStrategy):
    """NSGA-II over the ranking's Pareto objectives."""

    sampler = optuna.samplers.NSGAIISampler
    multi_objective = True

    def defaults(self) -> dict[str, Any]:
        return {"population_size": 20}
