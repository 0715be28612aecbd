"""docs/quickstart.ipynb, the quickstart's study from Python: kept in the repository without outputs, and run
whole as a user runs it (a real Jupyter kernel, through nbclient, on a local cluster), in a fresh copy of
the folders it reads so that no earlier result is reused."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import nbformat
import pytest
from conftest import REPO

NOTEBOOK = REPO / "docs" / "quickstart.ipynb"
COPIED = ("jobs/quickstart", "jobs/msd/fmus")  # what the notebook reads (as docs/quickstart_page.py copies)


def test_the_notebook_is_kept_without_outputs():
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(notebook)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert code and all(cell.outputs == [] and cell.execution_count is None for cell in code)


@pytest.fixture(scope="module")
def executed(tmp_path_factory) -> tuple[dict[str, list], Path]:
    """The notebook run in a fresh copy of the checkout's folders it reads, from docs/ as Jupyter opens it;
    each code cell's outputs by the start of its source."""
    from nbclient import NotebookClient

    root = tmp_path_factory.mktemp("notebook")
    for folder in COPIED:
        shutil.copytree(REPO / folder, root / folder)
    (root / "docs").mkdir()
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    NotebookClient(
        notebook, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(root / "docs")}}
    ).execute()  # a cell's error fails here, with its traceback
    return {cell.source: cell.outputs for cell in notebook.cells if cell.cell_type == "code"}, root


def outputs_of(cells: dict[str, list], start: str) -> list:
    (source,) = [source for source in cells if source.startswith(start)]
    return cells[source]


def shown(output) -> str:
    """An output's plain text: a display's or a result's text/plain, a stream's text."""
    return output.get("text") or output.get("data", {}).get("text/plain", "")


def result_of(cells: dict[str, list], start: str) -> str:
    """The text of the value a cell ends with (its one execute_result)."""
    (result,) = [shown(o) for o in outputs_of(cells, start) if o.output_type == "execute_result"]
    return result


def bars(outputs: list) -> list[str]:
    return [shown(o) for o in outputs if o.output_type == "display_data" and "sim/s" in shown(o)]


@pytest.mark.slow  # the quickstart's five studies and its diagnosis, about two minutes on two cores
def test_the_quickstart_notebook_runs_the_quickstarts_study(executed):
    cells, root = executed
    # each sweep shows one bar, redrawn in place to its final state, not a line per update
    for start, done in [
        ('sweep = dse.submit("jobs/quickstart/sweep.yaml")', "40/40"),
        ('search = dse.submit("jobs/quickstart/search.yaml")', "40/40"),
        ('design = dse.submit("jobs/quickstart/sensitivity.yaml")', "4000/4000"),
        ('calibration = dse.submit("jobs/quickstart/calibrate.yaml")', "/"),
    ]:
        outputs = outputs_of(cells, start)
        (bar,) = bars(outputs)
        assert done in bar and "0 failed" in bar, bar
        assert len(outputs) <= 4, outputs  # the bar, the result, and at most a warning or two
    study = result_of(cells, "sweep = dse.submit")
    assert study == f"Study('quickstart-sweep' in {root}/out/quickstart-sweep: 40 tasks, 40 ok, 0 failed)"
    assert result_of(cells, "sweep.best") == "{'msd.k': 16.0, 'msd.c': 6.0}"  # as the page's

    indices = result_of(cells, "design = ")
    damping = re.search(r"^msd\.c\s+(\S+)", indices, flags=re.MULTILINE)
    assert damping and float(damping[1]) > 0.8, indices  # the damping decides almost everything (S1)

    diagnosis = outputs_of(cells, "diagnosis = dse.diagnose(")
    progress = [o for o in diagnosis if o.output_type == "display_data"]
    assert len(progress) == 1 and re.match(r"\[\d+\] ", shown(progress[0])), diagnosis  # one line, redrawn
    summary = result_of(cells, "diagnosis = dse.diagnose(")
    assert "verdict: explained: input_deadzone(msd.F)" in summary, summary
    assert result_of(cells, "answer = diagnosis.answer").startswith("('explained',")

    assert (root / "out" / "quickstart-calibrate" / "report.html").stat().st_size > 100_000
