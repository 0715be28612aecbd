"""The ``dse-runner`` command: a thin shell over the Python API.

Every command that reports results takes ``--json`` and then prints one JSON
object on stdout and nothing else; errors go to stderr with exit code 2. The
exit code does not depend on ``--json``: a ``submit`` whose sweep ran but could
rank no point exits 1 either way (its JSON then says ``"ranking": null``). Ctrl-C
during ``submit`` prints one line on stderr, nothing on stdout, and exits 130.
"""

from __future__ import annotations

import os
import sys
import traceback
import warnings
from pathlib import Path
from typing import Annotated, Any, NoReturn

import typer

from .. import __version__
from ..errors import DseError

app = typer.Typer(
    name="dse-runner",
    help="Design-space exploration for FMI co-simulation.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # click's plain help: it fits 80 columns, where rich's boxed tables cut names off
)

JsonFlag = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout, nothing else.")]
DashboardAddress = Annotated[
    str,
    typer.Option(
        help="host:port the dashboard listens on (port 0: any free one). Loopback by default: the page "
        "has no login; reach it from elsewhere through an SSH tunnel."
    ),
]


class CommandOptions:
    """Options of the whole command, given before the subcommand."""

    debug = False  # show tracebacks


@app.callback()
def options(
    debug: Annotated[
        bool, typer.Option("--debug", help="Show the traceback behind an error message.")
    ] = False,
) -> None:
    """Design-space exploration for FMI co-simulation."""
    CommandOptions.debug = debug
    warnings.showwarning = _one_line_warning
    sys.unraisablehook = _interrupt_again


def _interrupt_again(unraisable) -> None:
    """A Ctrl-C that lands while Python runs a finalizer (``__del__``, e.g. of a zip file an FMU was read
    from) cannot be raised there: Python would print it as "Exception ignored" with a traceback, and the
    command would go on as if no key had been pressed. It is raised again in the main thread, a moment
    later: raised at once, it would land in this hook, which is no better place."""
    if issubclass(unraisable.exc_type, KeyboardInterrupt):
        import _thread
        import threading

        later = threading.Timer(0.1, _thread.interrupt_main)
        later.daemon = True  # nor does it hold Python up on its way out
        later.start()
        return
    sys.__unraisablehook__(unraisable)


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning is one line on stderr, ``warning: ...``, like an error (the source line with --debug)."""
    where = f" ({filename}:{lineno})" if CommandOptions.debug else ""
    typer.echo(f"warning: {message}{where}", err=True)


def fail(error: Exception) -> None:
    """A user's error: one line naming the culprit on stderr, exit code 2 (the traceback with --debug,
    and that of the exception behind it: our messages are raised ``from None``)."""
    if CommandOptions.debug:
        if error.__context__ is not None:
            traceback.print_exception(error.__context__)
        traceback.print_exc()
    typer.echo(f"error: {error}", err=True)
    raise typer.Exit(2)


def emit_json(data: dict[str, Any]) -> None:
    """One strict JSON object on stdout: missing numbers are null, never NaN."""
    from ..strict_json import dumps

    sys.stdout.write(dumps(data) + "\n")


def parse_assignment(text: str) -> tuple[str, Any]:
    """``vehicle.mass=1500`` -> ('vehicle.mass', 1500.0); non-numbers stay strings."""
    ref, eq, raw = text.partition("=")
    if not eq or not ref.strip():
        raise DseError(f"--set {text!r}: expected instance.variable=value")
    raw = raw.strip()
    try:
        value: Any = float(raw)
    except ValueError:
        value = {"true": True, "false": False}.get(raw.lower(), raw)
    return ref.strip(), value


@app.command("build-fmus")
def build_fmus(
    sources: Annotated[
        Path | None,
        typer.Argument(
            metavar="SOURCES", help="Folder of FMU source folders. Default: the FMUs bundled with dse-runner."
        ),
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Copy the built .fmu files here.")] = None,
    as_json: JsonFlag = False,
) -> None:
    """Compile every FMU under SOURCES with the system C compiler (cached by source hash)."""
    import shutil

    from ..simulation.build import build_fmu, find_source_dirs

    try:
        built = {d.name: build_fmu(d) for d in find_source_dirs(sources)}
        if not built:
            raise DseError(
                f"no FMU source folders (modelDescription.xml + *.c) under {sources or 'the bundle'}"
            )
        if out is not None:
            out.mkdir(parents=True, exist_ok=True)
            built = {name: Path(shutil.copy(path, out / f"{name}.fmu")) for name, path in built.items()}
    except DseError as e:
        fail(e)
    if as_json:
        emit_json({"fmus": {name: str(path) for name, path in built.items()}})
    else:
        for name, path in built.items():
            typer.echo(f"{name}: {path}")


@app.command()
def describe(
    model: Annotated[
        Path,
        typer.Argument(
            metavar="MODEL",
            help="An .fmu file, an FMU source folder, a multi-model file, or a space.yaml (its model).",
        ),
    ],
    every: Annotated[bool, typer.Option("--all", help="Every variable, locals too.")] = False,
    as_json: JsonFlag = False,
) -> None:
    """List MODEL's parameters, inputs and outputs by the names --set, values files and spaces use."""
    from ..simulation.model_info import model_info
    from ..sweeps.space_run import is_space_file

    try:
        if is_space_file(model):  # a space: the model it names, as its sweeps run it
            from ..sweeps.spec import load_space

            found = model_info(load_space(model).plan, every)
        else:
            found = model_info(model, every)
    except DseError as e:
        fail(e)
    if as_json:
        emit_json({"instances": [i.model_dump(mode="json") for i in found]})
        return
    for instance in found:
        times = ", ".join(
            f"{label} {value:g}"
            for label, value in (
                ("start", instance.start_time),
                ("stop", instance.stop_time),
                ("step", instance.step),
            )
            if value is not None
        )
        typer.echo(
            f"{instance.instance}: {instance.model_name}, FMI {instance.fmi_version}, "
            f"{'co-simulation' if instance.interface == 'cs' else 'model exchange'}"
            f"{f'; default experiment {times}' if times else ''}"
        )
        width = max((len(v.name) for v in instance.variables), default=0)
        for v in instance.variables:
            start = "" if v.start is None else v.start
            column = "settable " if v.settable else "connected" if v.fed_by else ""
            fed = f" (set from {v.fed_by} at every step)" if v.fed_by else ""
            typer.echo(
                f"  {v.name:<{width}}  {v.causality:<10} {start:>10} {v.unit or '':<8} "
                f"{column:<9} {v.description or ''}{fed}".rstrip()
            )
    typer.echo(
        "set a value: --set NAME=VALUE (one .fmu: also the bare variable name); in a space: "
        "parameters: {NAME: [values]}"
    )


@app.command()
def simulate(
    model: Annotated[
        Path,
        typer.Argument(
            metavar="MODEL",
            help="An .fmu file, an FMU source folder, a multi-model "
            "file (YAML, or INTO-CPS mm.json), or a space.yaml: "
            "its model, experiment and objectives.",
        ),
    ],
    scenario: Annotated[
        Path | None,
        typer.Option(
            "--scenario",
            "-s",
            help="Scenario folder (scenario.yaml, or a kind's format such as field data); for a "
            "space, also one of its scenarios by name.",
        ),
    ] = None,
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="instance.variable=value (for one .fmu: variable=value); repeatable."),
    ] = None,
    values_file: Annotated[
        Path | None,
        typer.Option(
            "--values",
            help="A YAML file of instance.variable: value lines (e.g. rank --best-values); --set "
            "overrides it.",
        ),
    ] = None,
    best: Annotated[
        bool,
        typer.Option(
            "--best",
            help="A space only: run the best point of its sweep (its output folder), as rank ranks it; "
            "--values and --set override it.",
        ),
    ] = False,
    start_time: Annotated[
        float | None, typer.Option(help="Start time [s]. Default: the scenario's, the FMU's, 0.")
    ] = None,
    stop_time: Annotated[
        float | None, typer.Option(help="Stop time [s]. Default: the scenario's or the FMU's.")
    ] = None,
    step: Annotated[
        float | None, typer.Option(help="Communication step [s]. Default: see docs/space.md.")
    ] = None,
    interface: Annotated[
        str | None,
        typer.Option(
            help="cs or me: run every FMU through this interface. Default: co-simulation when offered."
        ),
    ] = None,
    objective: Annotated[
        list[str] | None,
        typer.Option(
            "--objective",
            help="A registered objective, module:function, or a spec as space.yaml writes one: "
            "'{signal: inst.var, recorded: column, metric: rmse}'; repeatable. Default: the "
            "scenario kind's (field data: the GPS objectives), or each recorded column named "
            "like an output, by its RMS error.",
        ),
    ] = None,
    csv: Annotated[
        Path | None, typer.Option(help="Write every output here: time, then one column per output.")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Folder for trajectory.csv and a plot (plot.png).")] = None,
    as_json: JsonFlag = False,
) -> None:
    """Simulate MODEL once (on a scenario if given); print the objectives and final outputs."""
    from ..simulation import objectives as objs
    from ..simulation.run import simulate as run_simulation
    from ..simulation.run import summary, write_csv
    from ..simulation.scenario import dropouts_line
    from ..simulation.user_modules import import_beside
    from ..simulation.values import read_values
    from ..sweeps.space_run import is_space_file, simulate_space

    files: dict[str, Path] = {}
    try:
        if interface not in (None, "cs", "me"):
            raise DseError(f"--interface {interface!r}: use cs (co-simulation) or me (model exchange)")
        values = {
            **(read_values(values_file) if values_file is not None else {}),
            **dict(parse_assignment(a) for a in set_ or []),
        }
        asked = objs.from_command_line(objective) if objective else None
        if asked:  # module:function with the module a file here, as a script finds its neighbours
            import_beside(asked.values(), Path.cwd())
        if is_space_file(model):  # the space's own model, experiment, scenarios and objectives
            if interface is not None:
                raise DseError("--interface: a space's model runs as its multi-model says")
            result = simulate_space(model, scenario, values, asked, start_time, stop_time, step, best)
        elif best:
            raise DseError(f"--best: {model} is not a space.yaml; the best point is that of a space's sweep")
        else:
            result = run_simulation(
                model, scenario, values, start_time, stop_time, step, objectives=asked, interface=interface
            )
        bare = model.suffix.lower() == ".fmu"  # one FMU: its variables' own names
        if csv is not None:
            files["csv"] = write_csv(result, csv, bare)
        if out is not None:
            from .plots import result_plot  # matplotlib only when a plot is asked for

            out.mkdir(parents=True, exist_ok=True)
            files["trajectory"] = write_csv(result, out / "trajectory.csv", bare)
            files["plot"] = result_plot(result, out / "plot.png")
    except DseError as e:
        fail(e)
    except OSError as e:  # an output file: not writable, or a folder of that name
        fail(DseError(f"cannot write {e.filename}: {e.strerror}"))
    final = summary(result, bare)
    for note in result.notes:  # stderr, as every warning: --json's stdout stays one object (it has them too)
        typer.echo(f"warning: {note}", err=True)
    if as_json:
        emit_json({**final, **{name: str(path) for name, path in files.items()}})
        return
    typer.echo(
        f"scenario {result.scenario.name}  ({result.scenario.group}, "
        f"{result.times.start:g}..{result.times.stop:g} s, step {result.step:g} s)"
    )
    if result.trajectory.stopped:
        stopped = result.trajectory.stopped
        typer.echo(
            f"{stopped.instance}: {stopped.message} (of {result.times.stop:g} s): the results and objectives "
            f"are up to t = {stopped.time:g}"
        )
    if best or values:
        shown = [
            f"{name} = {value:g}" if isinstance(value, float) else f"{name} = {value!r}"
            for name, value in result.values.items()
        ]
        typer.echo(f"values: {', '.join(shown[:MAX_PRINTED])}{' ...' if len(shown) > MAX_PRINTED else ''}")
    for name, verdict in result.lifecycle.items():
        if verdict.mode == "process":
            typer.echo(f"{name} ran in a fresh process: {verdict.reason}")
    for name, value in result.objectives.items():
        shown = f"{value:10.4f}" if isinstance(value, float) else f"[{len(value)} values]"
        typer.echo(f"  {name:<20} {shown}")
    if final["final"]:
        typer.echo("final values:")
        for name, value in list(final["final"].items())[:MAX_PRINTED]:
            typer.echo(f"  {name:<28} {value:.6g}" if isinstance(value, float) else f"  {name:<28} {value!r}")
        if len(final["final"]) > MAX_PRINTED:
            typer.echo(f"  ... and {len(final['final']) - MAX_PRINTED} more (--json or --csv has them all)")
    if result.scenario.dropouts:
        typer.echo(f"  {dropouts_line({result.scenario.name: result.scenario.dropouts})}")
    for label, path in files.items():
        typer.echo(f"{label + ':':<12}{path}")


MAX_PRINTED = 30  # final values printed as text


def _print_table1(ranking) -> None:
    """Table 1 with the report's column names, saying which points its min, max and average are over."""
    from ..sweeps.rank import TABLE1_HEADINGS as heads
    from ..sweeps.rank import format_point, table1_scope

    typer.echo(f"Table 1: {ranking.objective} per scenario ({table1_scope(ranking)})")
    for line in table1_lines(ranking.table1, heads):
        typer.echo(f"  {line}")
    typer.echo(f"best: {format_point(ranking.best)}  ({ranking.ranked_label} {ranking.best_total:.3f})")
    if ranking.stopped_points:
        typer.echo(
            f"ranked last: {ranking.stopped_points} points with a run an FMU stopped early (their objectives "
            "cover a shorter span; column stopped)"
        )
    if ranking.uncertainty is not None:
        _print_draws(ranking)


# Table 1's figure columns: each one's format and narrowest width. Values that need more widen their column,
# so that two never run together (300.000 beside 86400.000).
TABLE1_FIGURES = {
    "min_error": (".3f", 9),
    "max_error": (".3f", 9),
    "average_error": (".3f", 9),
    "computed": (".3f", 9),
    "difference": ("+.3f", 12),
}


def table1_lines(table1, heads: dict[str, str]) -> list[str]:
    """Table 1 as text, the scenario left and the figures right, each column two spaces wider than its widest
    value or heading (and no narrower than for the usual values)."""
    cells = {c: [format(v, spec) for v in table1[c]] for c, (spec, _) in TABLE1_FIGURES.items()}
    widths = {
        c: max([least, len(heads[c]) + 2, *(len(text) + 2 for text in cells[c])])
        for c, (_, least) in TABLE1_FIGURES.items()
    }
    width = max([14, *(len(s) + 1 for s in table1["scenario"])])  # names of variants run long
    lines = ["scenario".ljust(width) + "".join(heads[c].rjust(widths[c]) for c in TABLE1_FIGURES)]
    for i, scenario in enumerate(table1["scenario"]):
        lines.append(scenario.ljust(width) + "".join(cells[c][i].rjust(widths[c]) for c in TABLE1_FIGURES))
    return lines


def _print_draws(ranking) -> None:
    """The best points' objective over the uncertain draws: mean, std, quantiles and the ranked figure."""
    from ..sweeps.rank import format_point
    from ..sweeps.uncertainty import label

    name, about = ranking.objective, ranking.uncertainty
    quantiles = [f"{name}_{label(q)}" for q in about["quantiles"]]
    typer.echo(
        f"{name} over {about['samples']} draws ({about['sampling']}, seed {about['seed']}), best first by "
        f"{about['ranked_by']}:"
    )
    for row in ranking.totals.head(5).to_dict("records"):
        spread = ", ".join(f"{c.rsplit('_', 1)[1]} {row[c]:.4g}" for c in quantiles)
        robust = f", {about['ranked_by']} {row[ranking.ranked_by]:.4g}" if ranking.ranked_by != name else ""
        typer.echo(
            f"  {format_point({p: row[p] for p in ranking.parameters}, 4)}: mean {row[name]:.4g}, "
            f"std {row[f'{name}_std']:.4g}, {spread}{robust}"
        )


@app.command()
def submit(
    spec: Annotated[
        Path,
        typer.Argument(
            metavar="SPEC",
            help="Design-space spec (space.yaml), or an INTO-CPS DSE config (NAME.dse.json) run as it is.",
        ),
    ],
    multimodel: Annotated[
        Path | None,
        typer.Option(
            "--multimodel", help="INTO-CPS only: the mm.json (default: the co-simulation config's)."
        ),
    ] = None,
    coe: Annotated[
        Path | None,
        typer.Option(
            "--coe", help="INTO-CPS only: the coe.json (default: found in the project's Multi-models folder)."
        ),
    ] = None,
    out: Annotated[
        str | None, typer.Option(help="Results folder or fsspec URL (overrides the spec's 'output').")
    ] = None,
    workers: Annotated[int | None, typer.Option(help="Workers to start (overrides the spec).")] = None,
    scheduler: Annotated[
        str | None, typer.Option(help="Address of an existing Dask scheduler (tcp:// or tls://).")
    ] = None,
    cluster: Annotated[
        str | None,
        typer.Option(
            help="Start a cluster of this kind: local, slurm, htcondor, kubernetes "
            "or a plugin's (overrides the spec)."
        ),
    ] = None,
    dashboard: Annotated[
        bool,
        typer.Option(
            help="Serve the live dashboard while the sweep runs (--no-dashboard: print no dashboard address)."
        ),
    ] = True,
    dashboard_address: DashboardAddress = "127.0.0.1:0",
    max_points: Annotated[
        int | None,
        typer.Option(min=1, help="A search's budget of points (overrides the spec's search.max_points)."),
    ] = None,
    max_seconds: Annotated[
        float | None,
        typer.Option(
            min=0.001, help="Stop asking for points after this long (overrides search.max_seconds)."
        ),
    ] = None,
    as_json: JsonFlag = False,
) -> None:
    """Run SPEC on Dask: every (point, scenario) task of a grid, or a search until its budget; resume if
    run again (a search goes on from where it stopped); rank."""
    from . import api
    from .progress import SweepProgressBar

    try:
        study = api.submit(
            spec,
            multimodel=multimodel,
            coe=coe,
            out=out,
            workers=workers,
            scheduler=scheduler,
            cluster=cluster,
            max_points=max_points,
            max_seconds=max_seconds,
            dashboard=dashboard,
            dashboard_address=dashboard_address,
            progress=SweepProgressBar(dask_link=dashboard),
            rank=False,
            say=lambda line: typer.echo(line, err=True),
            again=AGAIN,
        )
    except DseError as e:
        fail(e)
    except KeyboardInterrupt as e:
        _interrupted(e)
    from ..simulation.scenario import dropouts, dropouts_line

    report, space = study.status, study.space
    summary = {
        "sweep": report.sweep,
        "output": str(report.output),
        "tasks": report.total,
        "skipped": report.skipped,
        "ran": report.ran,
        "ok": report.ok,
        "failed": report.failed,
        "seconds": round(report.seconds, 3),
        "workers": report.workers,
        "chunk_size": report.chunk_size,
        "errors": report.errors,
        "dropouts": dropouts(space.scenarios),
        "search": report.search.model_dump(mode="json") if report.search else None,
    }
    if not as_json:
        done = "" if report.search else f"{report.total} tasks, {report.skipped} already done, "
        typer.echo(
            f"{report.sweep}: {done}ran {report.ran} simulations "
            f"({report.failed} failed) in {report.seconds:.1f} s on {report.workers} workers"
        )
        for error in report.errors:
            typer.echo(f"  failed: {error.splitlines()[0]}")
        if report.search is not None:
            _print_search(report.search)
        if summary["dropouts"]:
            typer.echo(f"  {dropouts_line(summary['dropouts'])}")
    try:
        ranking = study.rank()
        files = study.files
    except DseError as e:
        if as_json:
            emit_json({**summary, "ranking": None, "best": None, "best_total": None})
        typer.echo(f"error: no ranking: {e}", err=True)
        raise typer.Exit(1)
    except KeyboardInterrupt:
        _interrupted(api.Interrupted(api.interrupted_line(space, AGAIN)))
    if as_json:
        emit_json(
            {**summary, "ranking": str(files["json"]), "best": ranking.best, "best_total": ranking.best_total}
        )
        return
    _print_table1(ranking)
    typer.echo(f"ranking: {files['json'].rsplit('/', 1)[0]}")
    typer.echo(
        f"report: dse-runner report {report.output} -o report.html; "
        f"dashboard: dse-runner dashboard {report.output}"
    )


AGAIN = "run the same command again to finish the rest"  # what an interrupted submit's line says to do


def _interrupted(interrupt: KeyboardInterrupt) -> NoReturn:
    """Ctrl-C's one line on stderr (api.interrupted_line: how many tasks have results, read from the store),
    and exit code 130."""
    from .api import interrupted_line

    typer.echo(getattr(interrupt, "line", None) or interrupted_line(None), err=True)
    raise typer.Exit(130)


@app.command("convert-intocps")
def convert_intocps(
    dse: Annotated[
        Path, typer.Argument(metavar="DSE", help="An INTO-CPS DSE config (NAME.dse.json) in its project.")
    ],
    output: Annotated[Path, typer.Option("-o", "--output", help="The space.yaml to write.")] = Path(
        "space.yaml"
    ),
    multimodel: Annotated[
        Path | None, typer.Option("--multimodel", help="The mm.json (default: the co-simulation config's).")
    ] = None,
    coe: Annotated[
        Path | None,
        typer.Option("--coe", help="The coe.json (default: found in the project's Multi-models folder)."),
    ] = None,
    as_json: JsonFlag = False,
) -> None:
    """Write the space.yaml equivalent to an INTO-CPS DSE config, paths relative to where it is written."""
    from . import intocps

    try:
        path = intocps.convert(dse, output, multimodel, coe)
    except DseError as e:
        fail(e)
    if as_json:
        emit_json({"space": str(path)})
    else:
        typer.echo(f"space: {path}\nrun it: dse-runner submit {path}")


def _print_search(search) -> None:
    from ..sweeps.rank import format_point

    typer.echo(
        f"  search {search.strategy}: {search.points} of {search.max_points} points "
        f"({search.reused} told from the store, {search.infeasible} infeasible, {search.failed} failed); "
        f"stopped: {search.stopped or '-'}"
    )
    if search.best is not None:
        typer.echo(f"  best {search.objective} {search.best:.6g} at {format_point(search.best_point)}")
    if search.utilisation is not None:
        typer.echo(f"  worker utilisation {100 * search.utilisation:.0f}% of {search.threads} threads")
    for note in search.notes:
        typer.echo(f"  note: {note}")


@app.command("dashboard")
def dashboard_command(
    results: Annotated[str, typer.Argument(metavar="RESULTS", help="A sweep's store: output folder or URL.")],
    sweep: Annotated[str | None, typer.Option(help="Which sweep, if the folder holds several.")] = None,
    address: DashboardAddress = "127.0.0.1:0",
) -> None:
    """Serve the live dashboard of a running or finished sweep until interrupted (Ctrl-C)."""
    import time

    from ..sweeps.rank import pick_sweep
    from .dashboard.server import serve

    try:
        server = serve(results, pick_sweep(results, sweep), address)
    except DseError as e:
        fail(e)
    typer.echo(f"dse-runner dashboard: {server.url}  (Ctrl-C to stop)")
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        from .dashboard.server import farewell

        server.stop(farewell(results, "This dashboard server was stopped (Ctrl-C)."))


@app.command("report")
def report_command(
    results: Annotated[str, typer.Argument(metavar="RESULTS", help="A sweep's store: output folder or URL.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="The HTML file to write.")] = Path(
        "report.html"
    ),
    sweep: Annotated[str | None, typer.Option(help="Which sweep, if the folder holds several.")] = None,
    as_json: JsonFlag = False,
) -> None:
    """Write one self-contained HTML file (opens offline): Table 1, rankings, Pareto front, figures, spec.
    A sweep of an INTO-CPS DSE config also gets INTO-CPS's result files, in a folder beside it."""
    from .api import written_report

    try:
        path, legacy = written_report(results, output, sweep)
    except DseError as e:
        fail(e)
    if as_json:
        emit_json(
            {"report": str(path), "bytes": path.stat().st_size, "intocps": str(legacy) if legacy else None}
        )
        return
    typer.echo(f"report: {path} ({path.stat().st_size / 1e6:.1f} MB)")
    if legacy:
        typer.echo(
            f"INTO-CPS results: {legacy} (dseResults.csv, results.html, ranking.json, graphs/pareto.png)"
        )


@app.command("rank")
def rank_command(
    results: Annotated[str, typer.Argument(metavar="RESULTS", help="A sweep's store: output folder or URL.")],
    sweep: Annotated[str | None, typer.Option(help="Which sweep, if the folder holds several.")] = None,
    objective: Annotated[
        str | None, typer.Option(help="Rank by this objective instead of the spec's.")
    ] = None,
    best_values: Annotated[
        Path | None,
        typer.Option(
            help=(
                "Also write the best point here as a values file "
                "(instance.variable: value), for simulate --values."
            )
        ),
    ] = None,
    as_json: JsonFlag = False,
) -> None:
    """Aggregate a sweep's results: totals, Table 1, Pareto front, group and weighted rankings."""
    from .api import ranked

    try:
        ranking, files = ranked(results, sweep, objective, best_values)
    except DseError as e:
        fail(e)
    except OSError as e:
        fail(DseError(f"cannot write {e.filename}: {e.strerror}"))
    if as_json:
        emit_json({**ranking.to_json(), "files": {k: str(v) for k, v in files.items()}})
        return
    _print_table1(ranking)
    if len(ranking.pareto):
        typer.echo(f"Pareto front: {len(ranking.pareto)} points (pareto.csv)")
    if ranking.uncertainty and len(
        ranking.groups
    ):  # the groups rank by the mean, whatever the ranking's figure
        typer.echo(f"best per group, by the mean over the draws of total {ranking.objective}:")
    for row in ranking.groups.to_dict("records"):
        point = ", ".join(f"{p}={row[p]:g}" for p in ranking.parameters)
        typer.echo(f"  best in {row['group']:<12} {point}  ({row[f'{ranking.objective}_total']:.3f})")
    if ranking.incomplete_points or ranking.failed_rows:
        typer.echo(
            f"not ranked: {ranking.incomplete_points} points without an ok row for every scenario "
            f"({ranking.failed_rows} failed rows)"
        )
    typer.echo(f"written: {files['json'].rsplit('/', 1)[0]}")
    if best_values is not None:
        typer.echo(f"best values: {files['best_values']}")


@app.command("sensitivity")
def sensitivity_command(
    results: Annotated[str, typer.Argument(metavar="RESULTS", help="A sweep's store: output folder or URL.")],
    sweep: Annotated[str | None, typer.Option(help="Which sweep, if the folder holds several.")] = None,
    objective: Annotated[
        list[str] | None,
        typer.Option(
            "--objective", help="Only this objective (repeatable). Default: every scalar objective."
        ),
    ] = None,
    confidence: Annotated[float, typer.Option(help="Level of the bootstrap confidence intervals.")] = 0.95,
    resamples: Annotated[int, typer.Option(help="Bootstrap resamples.")] = 100,
    figures: Annotated[
        Path | None,
        typer.Option(
            help="Write a figure per objective here (sensitivity-NAME.png): index bars with their intervals, "
            "or Morris' mu*-sigma plane, overall and per group."
        ),
    ] = None,
    as_json: JsonFlag = False,
) -> None:
    """Which parameters move each objective: Sobol' or eFAST S1/ST, or Morris mu*/sigma, with bootstrap
    intervals, over all scenarios (reduced as the ranking says) and per scenario group. The sweep must
    have been sampled by search.strategy sobol_indices, morris or fast."""
    from .api import sensitivity_figures

    try:
        found, written = sensitivity_figures(results, sweep, objective, confidence, resamples, figures)
    except DseError as e:
        fail(e)
    except OSError as e:
        fail(DseError(f"cannot write {e.filename}: {e.strerror}"))
    for line in found.warnings:
        typer.echo(f"warning: {line}", err=True)
    if as_json:
        emit_json({**found.to_json(), "figures": {name: str(path) for name, path in written.items()}})
        return
    _print_sensitivity(found)
    for name, path in written.items():
        typer.echo(f"figure {name}: {path}")


def _print_sensitivity(found) -> None:
    """Per objective: each parameter's indices with their intervals, then the
    groups, least responsive first."""
    sobol = found.indices  # S1 and ST (Sobol' or eFAST), else Morris' mu*, sigma
    design = found.design
    kind = {
        "sobol": "Sobol' indices (Saltelli)",
        "fast": f"eFAST indices ({design['harmonics']} harmonics)",
    }.get(found.method, f"Morris elementary effects ({design['levels']} levels)")
    blocks = "curves" if found.method == "fast" else "blocks"
    level = f"{100 * found.confidence:g}%"
    typer.echo(
        f"{found.sweep}: {kind}, {design['blocks']} {blocks} of {design['block']} rows; +/- {level} "
        "bootstrap intervals"
    )
    width = max(len(p) for p in found.parameters) + 2
    heads = ("S1", "ST") if sobol else ("mu*", "sigma")
    for name, objective in found.objectives.items():
        overall = objective.overall
        spread = overall.spread
        stats = (
            f"mean {spread['mean']:.4g}, std {spread['std']:.4g}" if spread["mean"] is not None else "no rows"
        )
        over = f"{overall.scenarios} scenarios" if overall.scenarios > 1 else "its one scenario"
        typer.echo(f"\n{name} ({found.reduced} over {over}; {stats})")
        typer.echo(f"  {'parameter':<{width}}{heads[0]:>18}{heads[1]:>18}")
        for parameter, v in overall.parameters.items():
            typer.echo(f"  {parameter:<{width}}{_pm(v, heads[0], sobol):>18}{_pm(v, heads[1], sobol):>18}")
        for pair, v in overall.second_order.items():
            typer.echo(f"  S2 {pair}: {v['S2']:.3f} +/- {v['S2_conf']:.3f}")
        if overall.note:
            typer.echo(f"  note: {overall.note}")
        negligible = found.negligible(name)
        if negligible:
            what = "total index's interval below 0.01" if sobol else "mu*'s interval below 1% of the largest"
            typer.echo(f"  negligible ({what}: fix it anywhere in its range): {', '.join(negligible)}")
        groups = found.least_responsive(name)
        if groups:
            typer.echo(
                "  groups, least responsive first (coefficient of variation over the sample; "
                f"{heads[1] if sobol else heads[0]} per parameter):"
            )
            key = "ST" if sobol else "mu_star"
            for group, cv in groups:
                figures = ", ".join(
                    f"{p.rsplit('.', 1)[-1]} {_number(v[key])}"
                    for p, v in objective.groups[group].parameters.items()
                )
                flat = "  (barely varies)" if objective.groups[group].note else ""
                typer.echo(f"    {group:<14} cv {cv:.3g}  {figures}{flat}")


def _number(value) -> str:
    return "-" if value is None else f"{value:.3f}"


def _pm(values: dict, head: str, sobol: bool) -> str:
    """``0.314 +/- 0.021``: an index and its interval's half-width (sigma has none)."""
    key = {"S1": "S1", "ST": "ST", "mu*": "mu_star", "sigma": "sigma"}[head]
    conf = values.get(f"{key}_conf")
    if values.get(key) is None:
        return "-"
    return f"{values[key]:.3f} +/- {conf:.3f}" if conf is not None else f"{values[key]:.3f}"


@app.command()
def diagnose(
    scenarios: Annotated[
        Path | None,
        typer.Option(
            "--scenarios",
            help="Folder of recorded runs, in place of the space's scenarios. Without --space, a "
            "library's own calibration space reads them (the Robotti's, for field data).",
        ),
    ] = None,
    multimodel: Annotated[
        Path | None, typer.Option(help="Multi-model to diagnose (default: the space's).")
    ] = None,
    space: Annotated[
        Path | None,
        typer.Option(
            help="The space to diagnose: its scenarios give inputs and recordings, its objectives what is "
            "compared, its parameters the calibration. The first installed hypothesis library that serves "
            "it runs (the Robotti's for field data), else the built-in signal effects."
        ),
    ] = None,
    out: Annotated[Path, typer.Option(help="Folder for results, the new model and the report.")] = Path(
        "out/diagnosis"
    ),
    folds: Annotated[
        int,
        typer.Option(
            help="Cross-validation folds across runs; with one record, blocks of its "
            "time held out (the first, where the unknown initial state shows, is "
            "always fitted)."
        ),
    ] = 3,
    hypothesis: Annotated[
        list[str] | None,
        typer.Option(
            "--hypothesis",
            help="Try only this hypothesis of the library that serves the space, e.g. wheel_slip or "
            "'input_delay(msd.F)' (repeatable). Default: every one.",
        ),
    ] = None,
    noise_factor: Annotated[
        float,
        typer.Option(
            help="Held-out error above this many noise floors (estimated from the recordings alone) is a "
            "residual the library leaves unexplained: verdict partial or unexplained."
        ),
    ] = 2.0,
    discovery: Annotated[
        bool,
        typer.Option(
            "--discovery/--no-discovery",
            help="Seek what is missing inside the model too: with --space, physical terms in the "
            "model-exchange FMUs' state derivatives, fitted beside the effects; with field data, the "
            "Robotti's sparse correction (PySINDy), proven by the same fits and held-out runs.",
        ),
    ] = True,
    screen: Annotated[
        str | None,
        typer.Option(
            help="How combinations are screened when no single hypothesis explains the recordings: mixed "
            "(mixtures of the single fits' changes) or linearised (the residuals linearised at none and the "
            "best singles), or an installed package's (entry-point group dse_runner.screens). Default: the "
            "library's own (signal effects: mixed; the Robotti's: linearised).",
        ),
    ] = None,
    workers: Annotated[int | None, typer.Option(help="Local cluster workers (overrides the space).")] = None,
    scheduler: Annotated[str | None, typer.Option(help="Address of an existing Dask scheduler.")] = None,
    as_json: JsonFlag = False,
) -> None:
    """Calibrate, locate the mismatch, name the missing physics, model it and show the fit improve."""
    from . import api

    try:
        diagnosis = api.diagnose(
            space,
            scenarios,
            out=out,
            multimodel=multimodel,
            folds=folds,
            hypotheses=hypothesis or (),
            noise_factor=noise_factor,
            discovery=discovery,
            screen=screen,
            workers=workers,
            scheduler=scheduler,
            progress=lambda m: typer.echo(m, err=True),
            again="run again to resume",
        )
    except DseError as e:
        fail(e)
    except KeyboardInterrupt as e:
        _interrupted(e)
    if as_json:
        emit_json(diagnosis.to_json())
        return
    for line in diagnosis.summary():
        typer.echo(line)


@app.command()
def version() -> None:
    """Print the version."""
    typer.echo(__version__)


def main() -> None:
    """The console script: a bug's exception is one line too, unless --debug asks for the traceback."""
    from ..sweeps.start_method import fork_local_workers

    fork_local_workers()  # one cluster per command: its workers start from a forkserver
    # Arrow's jemalloc pool gives back what a large scan freed, where its default (mimalloc) keeps
    # it: a rank of a million rows peaks 200 MB lower (docs/performance.md). Linux wheels carry
    # it; a user's own setting stands.
    if sys.platform.startswith("linux"):
        os.environ.setdefault("ARROW_DEFAULT_MEMORY_POOL", "jemalloc")
    try:
        app()
    except Exception as e:  # anything the commands did not turn into a DseError
        if CommandOptions.debug:
            raise
        typer.echo(
            f"error: unexpected {type(e).__name__}: {e} (run with --debug for the traceback)", err=True
        )
        sys.exit(1)


if __name__ == "__main__":
    main()
