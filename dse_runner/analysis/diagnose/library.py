"""Hypothesis libraries: the plug-in contract of ``diagnose``, and how a space
finds the library that serves it.

A library knows a family of effects a model may miss, and the diagnosis that fits them to recordings.
One is built in: the signal effects (signal_library.py), late, sluggish, scaled or biased inputs and
outputs, which serve any space whose objectives compare signals with recordings. A package adds
its own, as the Robotti case adds the field robot's (wheel slip, actuator lags, antenna lever arm,
…), through an entry point::

    [project.entry-points."dse_runner.hypotheses"]
    mine = "my_package.diagnosis:MyLibrary"   # a subclass of HypothesisLibrary

Installed libraries are asked before the built-in one, so a case's own physics comes first where it
applies and the generic library serves everything else.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Protocol

from ... import bundled, plugins
from ...errors import DseError
from ...sweeps.domain import Interval
from ...sweeps.search import Search
from ...sweeps.spec import Space, SpaceSpec, read_spec, resolve_space
from . import report, screens
from .answer import Answer
from .explain import NOISE_FACTOR, floors
from .hypotheses import Hypothesis
from .one_thread import one_thread
from .report import Section

GROUP = "dse_runner.hypotheses"

Messages = Callable[[str], None]  # progress lines, as the CLI prints them to stderr


@dataclass(frozen=True)
class Request:
    """What a user asks of any diagnosis: the command's options."""

    out: Path = Path("out/diagnosis")
    folds: int = 3  # cross-validation folds across scenarios
    noise_factor: float = NOISE_FACTOR  # held-out error above this many noise floors is unexplained
    hypotheses: tuple[str, ...] = ()  # the library's ids to try; () tries them all
    discovery: bool = True  # seek what is missing inside the model too (terms in its derivatives)
    screen: str = ""  # the combination screen by name (screens/registry.py); "": the library's own

    def __post_init__(self) -> None:
        if self.screen:
            screens.known(self.screen)
        if not (isinstance(self.folds, int) and self.folds >= 2):
            raise DseError(f"--folds {self.folds!r}: cross-validation needs 2 folds or more")
        floors(self.noise_factor, "--noise-factor", NOISE_FACTOR)


class Result(Protocol):
    """What every diagnosis answers: a verdict, strict JSON, and lines for the terminal."""

    @property
    def verdict(self) -> str: ...

    def to_json(self) -> dict[str, Any]: ...

    def summary(self) -> list[str]: ...


class HypothesisLibrary(ABC):
    """A library of hypotheses and the diagnosis that fits them: the contract of the entry-point group
    ``dse_runner.hypotheses``, whose entries name a subclass (built with no arguments).

    Lifecycle (:func:`diagnose`). The space to diagnose is read once: the user's, with ``--scenarios``
    runs in place of its scenarios and ``--out`` as its output. Each installed library, the general ones
    (``general``, such as the built-in signal effects) last, is asked :meth:`serves`; the first that
    says yes gets :meth:`diagnose` once, with that space, the request and a function for progress lines,
    and returns a :class:`Result`. It starts (or reaches, by ``space.spec.cluster``) its own cluster, and
    keeps every simulation in the space's Parquet store, so that running it again resumes.

    Its report is the engine's (report.py), drawn from the answer's JSON: the library writes it with
    ``report.write(answer, self.sections)`` once its answer and figures are made.

    Optional parts, with defaults: ``calibration`` (None: ``--scenarios`` alone cannot choose this
    library; a library whose case has a standard calibration names it, e.g. ``bundled:…``),
    ``screen`` (the combination screen it runs unless ``--screen`` names another: ``mixed``),
    :meth:`hypotheses` (none listed), :meth:`sections` (none: the report is the engine's skeleton alone).
    """

    name: ClassVar[str]
    calibration: ClassVar[str | None] = None  # the space ``--scenarios DIR`` fills when no --space is given
    general: ClassVar[bool] = False  # serves any model: asked after the libraries of a model
    screen: ClassVar[str] = "mixed"  # its combination screen by name (screens/registry.py), unless asked

    def screen_for(self, request: Request) -> str:
        """The combination screen ``request`` names, else this library's own."""
        return request.screen or self.screen

    @abstractmethod
    def serves(self, space: Space) -> bool:
        """Whether this library can diagnose ``space`` (its scenarios, multi-model and objectives)."""

    @abstractmethod
    def diagnose(self, space: Space, request: Request, say: Messages) -> Result:
        """Calibrate, fit the hypotheses, choose what the recordings support, write the report."""

    def hypotheses(self, space: Space) -> list[Hypothesis]:
        """The hypotheses it would try on ``space``: ``--hypothesis`` may name
        only these (none listed: any)."""
        return []

    def sections(self, answer: Answer) -> list[Section]:
        """Its own parts of the report, each placed after a part of the engine's (report.PARTS): what only
        it has, drawn from ``answer`` alone (its ``case``, its figures in ``files``), so the whole report can
        be drawn again from ``diagnosis.json`` (:func:`report_again`)."""
        return []


def report_again(summary: Path) -> dict[str, Path]:
    """A diagnosis' report, page and JSON written again from its ``diagnosis.json`` alone, with the sections
    of the installed library that diagnosed: what a change to the report's layout needs, not a new fit."""
    answer = report.read(summary)
    library = next((lib for lib in libraries() if lib.name == answer.library), None)
    if library is None:
        raise DseError(f"{summary}: diagnosed by the {answer.library} library, which is not installed")
    return report.write(answer, library.sections)


def checked(library: HypothesisLibrary, space: Space, request: Request) -> HypothesisLibrary:
    """The library, once every ``--hypothesis`` is one it has: an unknown one
    is named before anything runs."""
    if not request.hypotheses:  # nothing to check: listing them (reading the recordings) would be wasted
        return library
    known = [h.id for h in library.hypotheses(space)]
    unknown = [h for h in request.hypotheses if known and h not in known]
    if unknown:
        raise DseError(
            f"--hypothesis {', '.join(unknown)}: the {library.name} library has no such hypothesis "
            f"(it has {', '.join(known)})"
        )
    return library


def libraries() -> list[HypothesisLibrary]:
    """Installed libraries (entry-point group ``dse_runner.hypotheses``) in the order they are asked: those of
    a model in name order, then the general ones (the built-in signal effects, which serve any model)."""
    found = [
        plugins.instance_of_subclass(entry, HypothesisLibrary, f"hypothesis library {name!r}")
        for name, entry in sorted(plugins.entries(GROUP).items())
    ]
    return sorted(found, key=lambda library: library.general)  # stable: name order within each


def runs_folder(scenarios: str | Path) -> Path:
    """The folder of recorded runs that ``scenarios`` names: a missing one is named before any library is
    loaded or asked."""
    folder = Path(scenarios).resolve()
    if not folder.is_dir():
        raise DseError(f"--scenarios {scenarios}: not a folder")
    return folder


def space_with(
    space: str | Path,
    scenarios: str | Path | None,
    out: Path | None,
    multimodel: str | Path | None = None,
    n_workers: int | None = None,
    address: str | None = None,
) -> Space:
    """The space to diagnose: ``space`` (a file or ``bundled:…``), with every run in ``scenarios`` as
    its scenarios when given, ``multimodel`` in place of its own, results in ``out`` (None: its own)."""
    path = bundled.resolve(space, Path.cwd())
    update: dict[str, Any] = {"keep_trajectories": 0}
    if out is not None:
        update["output"] = str(out)
    if scenarios is not None:
        update["scenarios"] = [str(runs_folder(scenarios) / "*")]
    if multimodel is not None:
        update["multimodel"] = str(Path(multimodel).resolve())
    spec = calibrated_by_search(read_spec(path).model_copy(update=update))
    return resolve_space(spec, path).with_overrides(address=address, n_workers=n_workers)


CALIBRATION_SEARCH = {"strategy": "sobol", "max_points": 64}  # where intervals are calibrated from


def calibrated_by_search(spec: SpaceSpec) -> SpaceSpec:
    """A spec that says no search of its own and has intervals among its parameters: a grid cannot cover
    them, so the calibration samples them (a Sobol' design of 64 points), and the fits start from its best.
    A search the spec names is kept."""
    intervals = [name for name, p in spec.parameters.items() if isinstance(p, Interval)]
    if "search" in spec.model_fields_set or not intervals:
        return spec
    return spec.model_copy(update={"search": Search(**CALIBRATION_SEARCH)})


def serving(space: Space, found: list[HypothesisLibrary] | None = None) -> HypothesisLibrary:
    """The first library that serves ``space``; none is an error naming the space and the libraries."""
    found = libraries() if found is None else found
    for library in found:
        if library.serves(space):
            return library
    raise DseError(
        f"{space.path}: no hypothesis library serves this space (installed: "
        f"{', '.join(lib.name for lib in found)}); the built-in signal effects need an objective "
        "{signal: inst.var, recorded: column, metric: rmse} comparing a signal with a recording"
    )


@one_thread
def diagnose(
    space: str | Path | None = None,
    scenarios: str | Path | None = None,
    request: Request = Request(),
    say: Messages | None = None,
    multimodel: str | Path | None = None,
    n_workers: int | None = None,
    address: str | None = None,
) -> Result:
    """Diagnose a space (with ``scenarios`` as its runs, if given) with the first library that serves it.

    With ``scenarios`` and no ``space``, the runs go into each library's own calibration space in
    turn (``HypothesisLibrary.calibration``) until one serves them: the Robotti's field data this way
    needs no space file."""
    say = say or (lambda message: None)
    out = Path(request.out).resolve()
    if scenarios is not None:
        runs_folder(scenarios)
    found = libraries()
    if space is not None:
        target = space_with(space, scenarios, out, multimodel, n_workers, address)
        return checked(serving(target, found), target, request).diagnose(target, request, say)
    if scenarios is None:
        raise DseError(
            "diagnose: give --space SPACE.yaml (any model with recordings), or --scenarios DIR "
            "(runs a library's own calibration space reads, such as the Robotti's field data)"
        )
    reasons = []
    for library in found:
        if library.calibration is None:
            continue
        try:
            target = space_with(library.calibration, scenarios, out, multimodel, n_workers, address)
        except DseError as e:  # these runs are not what this library's calibration reads
            reasons.append(f"{library.name}: {e}")
            continue
        if library.serves(target):
            return checked(library, target, request).diagnose(target, request, say)
        reasons.append(f"{library.name}: its calibration does not serve these runs")
    raise DseError(
        f"--scenarios {scenarios}: no installed hypothesis library has a calibration space for these "
        f"runs ({'; '.join(reasons) or 'none has one'}); give --space SPACE.yaml whose scenarios they are"
    )
