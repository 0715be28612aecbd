"""The ``dse-runner`` command: a thin shell over the Python API.

Every command that reports results takes ``--json`` and then prints one JSON
object on stdout and nothing else; errors go to stderr with exit code 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from . import __version__
from .errors import DseError

app = typer.Typer(
    name="dse-runner",
    help="Design-space exploration for FMI co-simulation.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

JsonFlag = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout, nothing else.")]


def fail(error: Exception) -> None:
    typer.echo(f"error: {error}", err=True)
    raise typer.Exit(2)


def emit_json(data: dict[str, Any]) -> None:
    sys.stdout.write(json.dumps(data, indent=2, default=str) + "\n")


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
    sources: Annotated[Path, typer.Argument(help="Folder of FMU source folders.")] = Path("fmus"),
    out: Annotated[Path | None, typer.Option(help="Copy the built .fmu files here.")] = None,
    as_json: JsonFlag = False,
) -> None:
    """Compile every FMU under SOURCES with the system C compiler (cached by source hash)."""
    import shutil

    from .build import build_fmu, find_source_dirs

    try:
        built = {d.name: build_fmu(d) for d in find_source_dirs(sources)}
        if not built:
            raise DseError(f"no FMU source folders (modelDescription.xml + *.c) under {sources}")
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
def simulate(
    multimodel: Annotated[Path, typer.Argument(help="Multi-model file (YAML, or INTO-CPS mm.json).")],
    scenario: Annotated[Path, typer.Option("--scenario", "-s", help="Scenario folder (field-data format).")],
    set_: Annotated[list[str] | None, typer.Option("--set", help="instance.variable=value; repeatable.")] = None,
    objective: Annotated[list[str] | None, typer.Option(
        "--objective", help="Built-in name or module:function; repeatable. Default: all built-ins.")] = None,
    step: Annotated[float | None, typer.Option(help="Communication step [s]. Default: the control log's period.")] = None,
    out: Annotated[Path | None, typer.Option(help="Folder for trajectory.csv and track.png. Default: out/<scenario>.")] = None,
    as_json: JsonFlag = False,
) -> None:
    """Co-simulate MULTIMODEL on one recorded scenario; print the objectives, write the track."""
    from . import objectives as objs
    from .plots import track_plot
    from .simulate import simulate as run_simulation

    try:
        overrides = dict(parse_assignment(a) for a in set_ or [])
        result = run_simulation(multimodel, scenario, overrides, tuple(objective or objs.DEFAULT), step)
        folder = out or Path("out") / result.scenario.name
        folder.mkdir(parents=True, exist_ok=True)
        csv_path = folder / "trajectory.csv"
        result.trajectory.to_csv(csv_path)
        png_path = track_plot(result, folder / "track.png") if result.trajectory.track else None
    except DseError as e:
        fail(e)
    if as_json:
        emit_json({
            "scenario": result.scenario.name,
            "step": result.step,
            "values": result.values,
            "objectives": result.objectives,
            "trajectory": str(csv_path),
            "plot": str(png_path) if png_path else None,
        })
        return
    typer.echo(f"scenario {result.scenario.name}  ({result.scenario.group}, {result.scenario.info.duration:g} s, "
               f"step {result.step:g} s)")
    for name, value in result.objectives.items():
        typer.echo(f"  {name:<20} {value:10.4f}")
    typer.echo(f"trajectory: {csv_path}")
    if png_path:
        typer.echo(f"plot:       {png_path}")


@app.command()
def version() -> None:
    """Print the version."""
    typer.echo(__version__)


if __name__ == "__main__":
    app()
