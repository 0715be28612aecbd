"""Progress as a person watches it: a sweep's bar with rate and ETA, and a diagnosis's lines, on a terminal
or in a Jupyter notebook.

On a terminal the bar is rich's live display on stderr, so that ``--json`` output stays clean. In a notebook
it is one output that is redrawn in place (IPython's display handle), at most every ``NOTEBOOK_SECONDS``:
rich's own live display needs ipywidgets there, and warns at every refresh without it, and a text bar on
stderr would leave its every state in the cell. The CLI (cli.py) and the Python API (api.py) show the
same bar: its columns, and what each report of the sweep changes in it, are here once.
"""

from __future__ import annotations

import io
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..sweeps.status import SweepReport

NOTEBOOK_SECONDS = 0.25  # a notebook's bar is redrawn at most this often (each redraw is a message)
NOTEBOOK_COLUMNS = 110  # the width a notebook's bar is laid out in


def in_notebook() -> bool:
    """Whether this runs in a Jupyter kernel (rich's test: IPython's ZMQ shell, Colab or Databricks)."""
    from rich.console import Console

    return Console().is_jupyter


def _columns() -> tuple[Any, ...]:
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]} sim/s"),
        TextColumn("{task.fields[failed]} failed"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
    )


class SweepProgressBar:
    """A sweep's progress (sweep.SweepProgress) as a terminal bar with rate and ETA, on stderr so --json
    output stays clean; first the address of Dask's dashboard, unless ``dask_link`` is false (--no-dashboard:
    no dashboard address is printed)."""

    def __init__(self, dask_link: bool = True) -> None:
        from rich.console import Console
        from rich.progress import Progress

        self.bar = Progress(*_columns(), console=Console(stderr=True), transient=False)
        self.task = None
        self.dask_link = dask_link

    def __enter__(self):
        self.bar.__enter__()
        return self

    def __exit__(self, *exc):
        return self.bar.__exit__(*exc)

    def say(self, line: str) -> None:
        """A line above the bar."""
        self.bar.console.print(line)

    def shown(self) -> None:
        """The bar after a change: a terminal's live display redraws by itself."""

    def __call__(self, report: SweepReport) -> None:
        if self.task is None:
            if report.dashboard and self.dask_link:
                self.say(f"Dask dashboard: {report.dashboard}")
            self.task = self.bar.add_task(
                report.sweep, total=report.total - report.skipped, rate="-", failed=0
            )
        rate = report.ran / report.seconds if report.seconds > 0 else 0.0
        search = report.search
        if search is not None:  # a search counts points, and shows the best so far
            best = f"best {search.best:.6g}" if search.best is not None else "no result yet"
            self.bar.update(
                self.task,
                total=search.max_points,
                completed=search.points,
                rate=f"{rate:.1f}",
                failed=search.failed,
                description=report.waiting or f"{report.sweep} ({best})",
            )
        else:
            self.bar.update(
                self.task,
                completed=report.ran,
                rate=f"{rate:.1f}",
                failed=report.failed,
                description=report.waiting or report.sweep,
            )
        self.shown()


class NotebookProgressBar(SweepProgressBar):
    """The same bar in a notebook: one output of the cell, redrawn in place at most every NOTEBOOK_SECONDS
    and once more when the sweep ends, however many reports the sweep makes."""

    def __init__(self, dask_link: bool = True) -> None:
        from rich.console import Console
        from rich.progress import Progress

        # the bar only keeps the counts: it is drawn by draw(), never by rich's live display
        self.bar = Progress(*_columns(), console=Console(file=io.StringIO()), disable=True)
        self.task = None
        self.dask_link = dask_link
        self.handle: Any = None  # IPython's handle on the cell's output that shows the bar
        self.drawn = 0.0  # when it was last drawn (monotonic)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.draw()  # the final counts, also after an interrupt
        return False

    def say(self, line: str) -> None:
        print(line, file=sys.stderr)

    def shown(self) -> None:
        if time.monotonic() - self.drawn >= NOTEBOOK_SECONDS:
            self.draw()

    def draw(self) -> None:
        if self.task is None:
            return
        view = rendered(self.bar.get_renderable())
        if self.handle is None:
            from IPython.display import display

            self.handle = display(view, display_id=True)
        else:
            self.handle.update(view)
        self.drawn = time.monotonic()


def rendered(renderable: Any) -> Any:
    """What a notebook shows of a rich renderable: its HTML, colours inline, and its plain text."""
    from rich.console import Console
    from rich.jupyter import JUPYTER_HTML_FORMAT, JupyterRenderable

    console = Console(
        record=True, file=io.StringIO(), width=NOTEBOOK_COLUMNS, force_terminal=True, force_jupyter=False
    )
    console.print(renderable)
    text = console.export_text(clear=False)
    return JupyterRenderable(console.export_html(inline_styles=True, code_format=JUPYTER_HTML_FORMAT), text)


def sweep_progress(progress: bool | Callable[[SweepReport], None], dask_link: bool = False) -> Any:
    """The bar a sweep shows: in a notebook or on a terminal as it runs (``True``), none (``False``), or the
    caller's own function of each report; always usable as a context manager."""
    import contextlib

    if progress is True:
        return NotebookProgressBar(dask_link) if in_notebook() else SweepProgressBar(dask_link)
    if not progress:
        return contextlib.nullcontext()
    return progress if hasattr(progress, "__enter__") else contextlib.nullcontext(progress)


class NotebookLine:
    """A diagnosis's progress lines in a notebook: one output showing the latest line and how many came
    before it, where a terminal prints each on stderr."""

    def __init__(self) -> None:
        self.handle: Any = None
        self.count = 0

    def __call__(self, message: str) -> None:
        from IPython.display import display

        self.count += 1
        view = {"text/plain": f"[{self.count}] {message}"}
        if self.handle is None:
            self.handle = display(view, raw=True, display_id=True)
        else:
            self.handle.update(view, raw=True)


def message_lines(progress: bool | Callable[[str], None]) -> Callable[[str], None] | None:
    """Where a diagnosis's progress lines go: one updated line in a notebook or stderr on a terminal
    (``True``), nowhere (``False``), or the caller's own function."""
    if progress is True:
        return NotebookLine() if in_notebook() else lambda message: print(message, file=sys.stderr)
    return progress or None
