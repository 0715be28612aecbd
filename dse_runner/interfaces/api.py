"""The Python API: each command as a function, for programs and notebooks.

``dse_runner`` re-exports these (``from dse_runner import submit``), and the CLI (cli.py) is their shell: it
calls them and prints what they return. So a study submitted from Python leaves the same store, ranking
and status as one submitted from the terminal, and is resumed by either::

    study = submit("jobs/quickstart/sweep.yaml")    # runs what has no row yet, ranks: a Study
    study.results()                                   # every row, a DataFrame (arrow=True: an Arrow table)
    study.best, study.rank().table1, study.report("report.html")
    sensitivity(study); diagnose("jobs/quickstart/calibrate.yaml").answer

Progress shows where the code runs: a bar on stderr on a terminal, one bar redrawn in place in a notebook
(progress.py). Ctrl-C, or a notebook kernel's interrupt, keeps every finished result, as the command does:
:class:`Interrupted`, a KeyboardInterrupt, says how many tasks have results and carries the study to read
them. docs/python.md is this module's guide.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import DseError
from .progress import message_lines, sweep_progress

if TYPE_CHECKING:
    import pandas as pd
    import pyarrow as pa

    from ..analysis.diagnose.answer import Answer
    from ..analysis.diagnose.library import Result
    from ..analysis.sensitivity import Sensitivity
    from ..sweeps.rank import Ranking
    from ..sweeps.spec import Space
    from ..sweeps.status import SweepReport

Lines = Callable[[str], None]  # where one-line messages go: the dashboard's address, a diagnosis's progress
AGAIN = "submit again to finish the rest"  # what an interrupted line tells a Python user to do
DIAGNOSE_AGAIN = "diagnose again to resume"


def _stderr(line: str) -> None:
    import sys

    print(line, file=sys.stderr)


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (a notebook kernel's interrupt) stopped a submit or a diagnosis: every finished result is kept
    in its store. ``line`` says how many; ``study`` reads them (None if the sweep had not started)."""

    def __init__(self, line: str, study: Study | None = None) -> None:
        super().__init__(line)
        self.line = line
        self.study = study


def interrupted_line(space: Space | None, again: str = AGAIN) -> str:
    """What an interrupted submit says. The count is read from the store after the sweep's last write (its
    chunks have ended, and a cluster it started is closed), so it is the number that submitting again finds
    done; what the client itself had counted misses chunks that ended after."""
    if space is None:
        return "interrupted before the sweep started; nothing was lost"
    from ..sweeps.sweep import tasks_done

    try:
        done, total = tasks_done(space)
    except DseError:  # the store cannot be read now: the line still says where the results are
        return f"interrupted: finished chunks are in {space.output}; {again}"
    return f"interrupted: {done} of {total} tasks have results in {space.output}; {again}"


def load(spec: str | Path, multimodel: str | Path | None = None, coe: str | Path | None = None) -> Space:
    """A space.yaml, or an INTO-CPS DSE config with its multi-model and co-simulation config (by default
    those the project associates with it), read and checked whole."""
    from ..sweeps.spec import load_space
    from . import intocps

    if intocps.is_dse_config(spec):
        return intocps.load_space(spec, multimodel, coe)
    if multimodel is not None or coe is not None:
        raise DseError(f"--multimodel and --coe go with an INTO-CPS DSE config (NAME.dse.json), not {spec}")
    return load_space(spec)


class _Board:
    """The dashboard a submit serves, and how it links itself from Dask's dashboard."""

    def __init__(self, server, say: Lines) -> None:
        self.server = server
        self.say = say

    def link(self, client) -> None:
        from .dask_link import link_from_dask

        page = link_from_dask(client, self.server.url)
        if page:
            self.say(f"linked from Dask's dashboard: {page}")

    def stop(self, output) -> None:
        from .dashboard.server import farewell

        self.server.stop(farewell(output, "The sweep's submit has ended, and its dashboard server with it."))


def _start_dashboard(space: Space, address: str, say: Lines) -> _Board:
    from .dashboard.server import serve

    server = serve(space.output, space.name, address, space)
    say(f"dse-runner dashboard: {server.url}")
    return _Board(server, say)


def submit(
    space: str | Path | Space,
    *,
    out: str | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    cluster: str | None = None,
    max_points: int | None = None,
    max_seconds: float | None = None,
    multimodel: str | Path | None = None,
    coe: str | Path | None = None,
    dashboard: bool = False,
    dashboard_address: str = "127.0.0.1:0",
    progress: bool | Callable[[SweepReport], None] = True,
    rank: bool = True,
    say: Lines = _stderr,
    again: str = AGAIN,
) -> Study:
    """``dse-runner submit``: run ``space`` (a space.yaml, an INTO-CPS DSE config, or a loaded Space) on
    Dask, every task that has no row yet (a search goes on from where it stopped), then rank it and write
    the ranking as the command does (``rank=False``: only the sweep). The options are the command's:
    ``out``, ``workers``, ``scheduler``, ``cluster``, ``max_points`` and ``max_seconds`` override the
    spec; ``dashboard`` serves the live page while it runs, its address told to ``say``.

    A sweep whose ranking fails (no point has an ok row for every scenario) is returned with a warning and
    ``ranking`` None. Raises DseError on a bad spec, before any cluster starts, and :class:`Interrupted`
    on Ctrl-C once the running chunks have written their rows."""
    from ..sweeps.spec import Space

    loaded = board = None
    try:
        if isinstance(space, Space):
            if multimodel is not None or coe is not None:
                raise DseError("multimodel and coe go with a spec file, not a loaded Space")
            loaded = space
        else:
            loaded = load(space, multimodel, coe)
        loaded = loaded.with_overrides(out, scheduler, workers, cluster, max_points, max_seconds)
        from ..sweeps.spec import unread_recordings

        note = unread_recordings(loaded)  # recordings no objective compares with: said before the sweep
        if note is not None:
            say(f"warning: {note}")
        # after the spec is read: a bad one is named without waiting on Dask's and pandas' imports
        from ..sweeps.sweep import submit as run_sweep

        if dashboard:
            board = _start_dashboard(loaded, dashboard_address, say)
        with sweep_progress(progress, dashboard) as bar:
            status = run_sweep(loaded, progress=bar, on_connect=board.link if board else None)
    except KeyboardInterrupt:
        study = Study(loaded.output, loaded.name, space=loaded) if loaded is not None else None
        raise Interrupted(interrupted_line(loaded, again), study) from None
    finally:
        if board is not None:
            board.stop(loaded.output)
    study = Study(status.output, status.sweep, space=loaded, status=status)
    if status.interrupted:
        raise Interrupted(interrupted_line(loaded, again), study)
    if rank:
        try:
            study.rank()
        except DseError as e:
            warnings.warn(f"no ranking: {e}", stacklevel=2)
        except KeyboardInterrupt:
            raise Interrupted(interrupted_line(loaded, again), study) from None
    return study


class Study:
    """A sweep's results in its store: what :func:`submit` returns, or ``Study(folder)`` for a sweep run
    before (by either the command or Python). ``sweep`` names it when the folder holds several."""

    def __init__(
        self,
        results: str | Path,
        sweep: str | None = None,
        *,
        space: Space | None = None,
        status: SweepReport | None = None,
    ) -> None:
        from ..sweeps.rank import pick_sweep
        from ..sweeps.status import load_status

        self.output = results
        self.name = pick_sweep(results, sweep)
        self.space = space  # what was submitted, if this process submitted it
        self.status = status or load_status(results, self.name)  # the last submission's counts
        self.ranking: Ranking | None = None  # the last rank(), by this process
        self.files: dict[str, str] = {}  # what it wrote: the ranking's files, the best values

    def __repr__(self) -> str:
        status = self.status
        counts = f": {status.total} tasks, {status.ok} ok, {status.failed} failed" if status else ""
        return f"Study({self.name!r} in {self.output}{counts})"

    def results(self, columns: list[str] | None = None, arrow: bool = False) -> pd.DataFrame | pa.Table:
        """Every row of the current model (rows of an earlier FMU or objective list are left out): the
        parameters, each objective, status, error, timings. ``columns`` reads only those (and the keys); a
        large study is better read as an Arrow table (``arrow=True``), which pandas would copy."""
        from ..sweeps import store
        from ..sweeps.rank import current_model

        table = store.read_table(self.output, self.name, columns, model=current_model(self.output, self.name))
        return table if arrow else table.to_pandas()

    def rank(self, objective: str | None = None, best_values: str | Path | None = None) -> Ranking:
        """``dse-runner rank``: rank again (by ``objective`` instead of the spec's) and write the ranking
        beside the results; ``best_values`` also writes the best point as a values file."""
        self.ranking, self.files = ranked(self.output, self.name, objective, best_values)
        return self.ranking

    @property
    def best(self) -> dict[str, Any]:
        """The best point (parameter -> value), by the last :meth:`rank` or the sweep's own ranking."""
        from ..sweeps.rank import rank

        return (self.ranking or rank(self.output, self.name)).best

    def report(self, path: str | Path = "report.html") -> Path:
        """``dse-runner report``: one self-contained HTML file of the study."""
        return report(self.output, path, self.name)

    def sensitivity(self, objectives: Sequence[str] | None = None, **options: Any) -> Sensitivity:
        """``dse-runner sensitivity`` of this study: see :func:`sensitivity`."""
        return _warned(sensitivity_figures(self.output, self.name, objectives, **options)[0])

    def trajectory(self, scenario: str | None = None, rank: int = 1) -> pd.DataFrame:
        """The recorded signals of the ``rank``-th best point on ``scenario`` (the only one, if there is
        one), as kept by the spec's ``keep_trajectories``."""
        from ..sweeps import store

        scenarios = sorted(self.status.scenarios) if self.status else []
        if scenario is None:
            if len(scenarios) != 1:
                raise DseError(f"{self.name}: name a scenario ({', '.join(scenarios) or 'none stored'})")
            scenario = scenarios[0]
        if not store.has_trajectory(self.output, self.name, scenario, rank):
            raise DseError(
                f"{self.name}: no trajectory of the best point {rank} on {scenario!r} is kept (the spec's "
                "keep_trajectories keeps the best few; scenarios: "
                f"{', '.join(scenarios) or 'none stored'})"
            )
        return store.read_trajectory(self.output, self.name, scenario, rank)


def _where(results: str | Path | Study, sweep: str | None) -> tuple[str | Path, str | None]:
    """A store and sweep from a folder (or URL) or a Study."""
    if isinstance(results, Study):
        return results.output, sweep or results.name
    return results, sweep


def ranked(
    results: str | Path,
    sweep: str | None = None,
    objective: str | None = None,
    best_values: str | Path | None = None,
) -> tuple[Ranking, dict[str, str]]:
    """The ranking of a sweep (by ``objective`` instead of its spec's, if given), written beside its
    results, and the files written: what ``dse-runner rank`` prints."""
    from ..simulation.values import write_values
    from ..sweeps.rank import load_sweep_spec, write_ranking
    from ..sweeps.rank import rank as rank_sweep
    from ..sweeps.store import sweeps

    settings = None
    if objective is not None:
        names = [sweep] if sweep else sweeps(results)
        if not names:
            raise DseError(f"{results}: no results")
        settings = load_sweep_spec(results, names[0]).ranking.model_copy(update={"objective": objective})
    ranking = rank_sweep(results, sweep, settings)
    files = write_ranking(ranking, results, ranking.sweep)
    if best_values is not None:
        files["best_values"] = write_values(
            Path(best_values),
            ranking.best,
            (
                f"The best point of sweep {ranking.sweep} by {ranking.objective} ({ranking.goal}imised "
                f"{ranking.best_total:.6g}), written by dse-runner rank."
            ),
        )
    return ranking, files


def rank(
    results: str | Path | Study,
    sweep: str | None = None,
    objective: str | None = None,
    best_values: str | Path | None = None,
) -> Ranking:
    """``dse-runner rank``: totals, Table 1, Pareto front, groups and weighted sums of a sweep's results,
    written beside them (``best_values``: the best point too, as a values file)."""
    return ranked(*_where(results, sweep), objective, best_values)[0]


def written_report(
    results: str | Path, path: str | Path = "report.html", sweep: str | None = None
) -> tuple[Path, Path | None]:
    """The report's HTML file, and for a sweep of an INTO-CPS DSE config the folder of INTO-CPS's result
    files beside it (else None): what ``dse-runner report`` writes."""
    from ..sweeps.rank import load_sweep_spec, pick_sweep
    from . import intocps
    from .report import write_report

    written = write_report(results, Path(path), sweep)
    name = pick_sweep(results, sweep)
    if load_sweep_spec(results, name).origin is None:
        return written, None
    folder = written.parent / f"{name}-intocps"
    return written, folder if intocps.write_result_files(results, folder, name) else None


def report(results: str | Path | Study, path: str | Path = "report.html", sweep: str | None = None) -> Path:
    """``dse-runner report``: one self-contained HTML file (opens offline) of a sweep's results."""
    output, sweep = _where(results, sweep)
    return written_report(output, path, sweep)[0]


def sensitivity_figures(
    results: str | Path,
    sweep: str | None = None,
    objectives: Sequence[str] | None = None,
    confidence: float | None = None,
    resamples: int | None = None,
    figures: str | Path | None = None,
) -> tuple[Sensitivity, dict[str, Path]]:
    """The indices, and the figures written (one per objective) if ``figures`` names a folder: what
    ``dse-runner sensitivity`` prints. SALib's own warnings are dropped: the indices' ``warnings`` say
    more."""
    from ..analysis import sensitivity as indices

    chosen = {"confidence": confidence, "resamples": resamples}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        found = indices.sensitivity(
            results,
            sweep,
            list(objectives) if objectives else None,
            **{k: v for k, v in chosen.items() if v is not None},
        )
    if figures is None:
        return found, {}
    from .sensitivity_figures import write_figures

    return found, write_figures(found, Path(figures))


def sensitivity(
    results: str | Path | Study,
    sweep: str | None = None,
    objectives: Sequence[str] | None = None,
    confidence: float | None = None,
    resamples: int | None = None,
    figures: str | Path | None = None,
) -> Sensitivity:
    """``dse-runner sensitivity``: which parameters move each objective (Sobol' or eFAST S1/ST, or Morris
    mu*/sigma, with bootstrap intervals at ``confidence`` from ``resamples``), overall and per scenario
    group, of a sweep sampled by sobol_indices, morris or fast; ``figures``: a folder for a figure per
    objective. Its warnings (a sample too small for narrow intervals) are Python warnings too."""
    output, sweep = _where(results, sweep)
    return _warned(sensitivity_figures(output, sweep, objectives, confidence, resamples, figures)[0])


def _warned(found: Sensitivity) -> Sensitivity:
    """The indices, their warnings said as Python warnings, from the line that asked for them."""
    for line in found.warnings:
        warnings.warn(line, stacklevel=3)
    return found


class Diagnosis:
    """What :func:`diagnose` returns: the library's result, and its JSON as the pydantic model every
    diagnosis answers (``answer``, analysis/diagnose/answer.py)."""

    def __init__(self, result: Result) -> None:
        self.result = result

    @cached_property
    def answer(self) -> Answer:
        """The answer, typed: verdict, effects with intervals, held-out errors, noise floor, files."""
        from ..analysis.diagnose.answer import Answer

        return Answer.model_validate(self.result.to_json())

    @property
    def verdict(self) -> str:
        return self.result.verdict

    def summary(self) -> list[str]:
        """The lines ``dse-runner diagnose`` prints."""
        return self.result.summary()

    def to_json(self) -> dict[str, Any]:
        """What ``dse-runner diagnose --json`` prints."""
        return self.result.to_json()

    def __repr__(self) -> str:
        return "\n".join(self.summary())


def diagnose(
    space: str | Path | None = None,
    scenarios: str | Path | None = None,
    *,
    out: str | Path | None = None,
    multimodel: str | Path | None = None,
    folds: int | None = None,
    hypotheses: Sequence[str] = (),
    noise_factor: float | None = None,
    discovery: bool | None = None,
    screen: str | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool | Lines = True,
    again: str = DIAGNOSE_AGAIN,
) -> Diagnosis:
    """``dse-runner diagnose``: calibrate ``space``, locate the mismatch with its recordings, name what the
    model leaves out and show the held-out fit improve. ``scenarios`` is a folder of recorded runs in
    place of the space's (alone, a library's own calibration space reads them); ``screen`` names the
    combination screen (``mixed`` or ``linearised``; None: the library's own); the other options are the
    command's, None for its defaults. Progress lines go to stderr, or to one line redrawn in a notebook.
    Raises :class:`Interrupted` on Ctrl-C: finished simulations are kept in ``out``, and a second call
    resumes from them."""
    from ..analysis.diagnose import Request
    from ..analysis.diagnose import diagnose as run_diagnosis

    given = {
        "out": out,
        "folds": folds,
        "noise_factor": noise_factor,
        "discovery": discovery,
        "screen": screen,
    }
    request = Request(
        **{k: Path(v) if k == "out" else v for k, v in given.items() if v is not None},
        hypotheses=tuple(hypotheses),
    )
    try:
        result = run_diagnosis(
            space, scenarios, request, message_lines(progress), multimodel, workers, scheduler
        )
    except KeyboardInterrupt:
        raise Interrupted(f"interrupted: finished simulations are kept in {request.out}; {again}") from None
    return Diagnosis(result)
