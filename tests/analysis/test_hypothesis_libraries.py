"""The hypothesis-library contract (HypothesisLibrary): every installed library holds to it, a space goes
to the first library that serves it (plug-ins before the built-in signal effects), and the Robotti's
diagnosis reaches the core only this way."""

from __future__ import annotations

import importlib.util
import shutil
from importlib.metadata import entry_points
from pathlib import Path

import pytest
from conftest import MSD, REPO, SCENARIOS, strict_loads
from support.plugins import register

from dse_runner import strict_json
from dse_runner.analysis.diagnose import (
    HypothesisLibrary,
    Request,
    diagnose,
    libraries,
    report_again,
    serving,
    space_with,
)
from dse_runner.analysis.diagnose.answer import Answer
from dse_runner.errors import DseError
from dse_runner.sweeps.spec import load_space

ROBOTTI_CALIBRATION = "bundled:robotti/calibration.yaml"

ALWAYS = """
from dse_runner.analysis.diagnose import HypothesisLibrary


class Answer:
    verdict = "none"

    def __init__(self, space):
        self.space = space

    def to_json(self):
        return {"verdict": self.verdict, "space": str(self.space.path)}

    def summary(self):
        return [f"verdict: {self.verdict}"]


class Always(HypothesisLibrary):
    name = "always"

    def serves(self, space):
        return True

    def diagnose(self, space, request, say):
        from threadpoolctl import threadpool_info

        say("diagnosed by always")
        blas = {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}
        say(f"BLAS threads {sorted(blas)}")
        return Answer(space)


class Duck:  # serves and diagnoses, but is not a HypothesisLibrary
    name = "duck"
"""


def test_every_installed_library_holds_to_the_contract():
    found = libraries()
    names = [lib.name for lib in found]
    assert names[-1] == "signals"  # the built-in one is asked last
    assert set(names) == {"signals", *(e.name for e in entry_points(group="dse_runner.hypotheses"))}
    for library in found:
        assert isinstance(library, HypothesisLibrary), library


def test_field_data_goes_to_the_robotti_library_and_any_other_recording_to_the_signal_effects(tmp_path):
    runs = space_with(ROBOTTI_CALIBRATION, SCENARIOS, tmp_path / "robotti")
    msd = space_with(MSD / "space.yaml", None, tmp_path / "msd")
    assert serving(runs).name == "robotti"
    assert serving(msd).name == "signals"
    assert str(msd.output).startswith(str(tmp_path))  # --out is where its results go


def test_the_robotti_library_lists_its_physics():
    robotti = next(lib for lib in libraries() if lib.name == "robotti")
    ids = {h.id for h in robotti.hypotheses(None)}
    assert {
        "wheel_slip",
        "steering_lag",
        "speed_lag",
        "steering_offset",
        "time_offset",
        "antenna_offset",
        "terrain_slope",
    } == ids


def test_the_signal_effects_list_every_effect_on_every_driven_input_and_compared_signal(tmp_path):
    msd = space_with(MSD / "space.yaml", None, tmp_path)
    signals = libraries()[-1]
    ids = {h.id for h in signals.hypotheses(msd)}
    # the ring-down scenario drives no input: only the compared position has effects, those a sensor has;
    # the model-exchange instance's two states have bounds, and each an overflow into the other; and every
    # physical term on each state's derivative, listed by name before a run tells which are physics
    effects = {i for i in ids if not i.startswith("derivative_term(")}
    assert effects == {
        *(f"output_{kind}(msd.x)" for kind in ("delay", "lag", "gain", "offset", "max", "min", "square")),
        *(f"state_{kind}(msd.{s})" for kind in ("max", "min") for s in ("x", "v")),
        "state_overflow(msd.x, v)",
        "state_overflow(msd.v, x)",
    }
    terms = ids - effects
    assert {"derivative_term(msd.der(v), x^3)", "derivative_term(msd.der(v), tanh(v))"} <= terms
    assert {"derivative_term(msd.der(x), 1)", "derivative_term(msd.der(v), x*F)"} <= terms


def test_a_signal_two_objectives_compare_is_diagnosed_once():
    """A least-squares space compares its signal twice (the residuals and the sum of squares the space adds
    to rank by): the diagnosis weighs that signal's residuals once, not twice."""
    from dse_runner.analysis.diagnose.signal_library import compared_signals

    space = load_space(REPO / "jobs" / "quickstart" / "calibrate.yaml")
    assert len([o for o in space.objectives.values() if getattr(o, "signal", None) == "msd.x"]) == 2
    assert [(c.signal, c.recorded) for c in compared_signals(space)] == [("msd.x", "x")]


@pytest.fixture
def always(tmp_path, monkeypatch) -> None:
    """An installed library that serves every space and says how it ran."""
    register(
        monkeypatch,
        tmp_path / "plugin",
        "always_library",
        ALWAYS,
        {"dse_runner.hypotheses": {"always": "always_library:Always"}},
    )


def test_an_installed_library_is_asked_before_the_built_in_one(tmp_path, always):
    said = []
    result = diagnose(MSD / "space.yaml", request=Request(out=tmp_path / "out"), say=said.append)
    assert result.to_json() == {"verdict": "none", "space": str((MSD / "space.yaml").resolve())}
    assert said[0] == "diagnosed by always"


def test_a_diagnosis_runs_its_client_algebra_on_one_blas_thread_then_gives_it_back(tmp_path, always):
    """A diagnosis solves thousands of small least squares in its client, where BLAS threads only spin
    (benchmarks/blas_threads.py): every library's diagnosis runs with one, and the caller's setting is
    back after."""
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas() -> list[int]:
        return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

    with threadpool_limits(limits=2, user_api="blas"):  # the caller's own setting, whatever the machine
        said = []
        diagnose(MSD / "space.yaml", request=Request(out=tmp_path / "out"), say=said.append)
        assert said[1] == "BLAS threads [1]"
        assert blas() == [2]


def test_a_library_that_is_not_a_subclass_is_named(tmp_path, monkeypatch):
    register(
        monkeypatch,
        tmp_path / "plugin",
        "duck_library",
        ALWAYS,
        {"dse_runner.hypotheses": {"duck": "duck_library:Duck"}},
    )
    with pytest.raises(DseError, match=r"hypothesis library 'duck' \(duck_library:Duck\) is not a subclass"):
        libraries()


def test_a_space_no_library_serves_is_named_with_what_would_serve_it(tmp_path):
    space = space_with(REPO / "jobs" / "watertank" / "space.yaml", None, tmp_path)
    with pytest.raises(
        DseError,
        match=r"space.yaml: no hypothesis library serves this space.*\{signal: inst.var, "
        r"recorded: column",
    ):
        diagnose(space.path, request=Request(out=tmp_path))


def test_runs_no_library_calibrates_are_refused_with_each_librarys_reason(tmp_path):
    folder = tmp_path / "runs"
    (folder / "one").mkdir(parents=True)
    with pytest.raises(
        DseError,
        match=r"--scenarios .*runs: no installed hypothesis library has a calibration "
        r"space for these runs \(robotti: ",
    ):
        diagnose(scenarios=folder, request=Request(out=tmp_path / "out"))


def test_a_missing_runs_folder_is_named_alone(tmp_path):
    """Before any library is asked: one plain reason, not each library's."""
    missing = tmp_path / "nowhere"
    with pytest.raises(DseError) as refused:
        diagnose(scenarios=missing, request=Request(out=tmp_path / "out"))
    assert str(refused.value) == f"--scenarios {missing}: not a folder"


def test_nothing_to_diagnose_is_named():
    with pytest.raises(DseError, match="give --space SPACE.yaml"):
        diagnose()


def test_a_hypothesis_the_library_lacks_is_named_before_anything_runs(tmp_path):
    with pytest.raises(
        DseError,
        match=r"--hypothesis wheel_slip: the signals library has no such hypothesis \(it "
        r"has output_delay\(msd.x\), ",
    ):
        diagnose(MSD / "space.yaml", request=Request(out=tmp_path, hypotheses=("wheel_slip",)))
    with pytest.raises(DseError, match="--hypothesis slip: the robotti library has no such hypothesis"):
        diagnose(ROBOTTI_CALIBRATION, SCENARIOS, Request(out=tmp_path, hypotheses=("slip",)))
    assert not list(tmp_path.rglob("*.parquet"))  # nothing ran


@pytest.mark.parametrize(
    "bad, named", [({"folds": 1}, "--folds 1"), ({"noise_factor": 0.0}, "--noise-factor 0.0")]
)
def test_a_request_no_diagnosis_can_honour_is_refused(bad, named):
    with pytest.raises(DseError, match=named):
        Request(**bad)


def test_a_space_of_intervals_is_calibrated_by_a_search_and_a_grid_stays_a_grid(tmp_path):
    """``msd.k: {low: 8, high: 20}`` with no search: diagnose samples the intervals (a grid cannot cover them;
    'exhaustive needs a list or a grid' was the answer once). A search the space names is kept."""
    import yaml

    spec = yaml.safe_load((MSD / "space.yaml").read_text())
    spec.update(
        multimodel=str(MSD / "multimodel.yaml"),
        output=str(tmp_path / "out"),
        parameters={"msd.k": {"low": 8, "high": 20}, "msd.c": {"low": 0.4, "high": 1.2}},
    )
    spec["scenarios"][0]["recorded"] = str(MSD / "recording" / "position.csv")
    (tmp_path / "intervals.yaml").write_text(yaml.safe_dump(spec))
    sampled = space_with(tmp_path / "intervals.yaml", None, tmp_path / "a")
    assert (sampled.spec.search.strategy, sampled.spec.search.max_points) == ("sobol", 64)
    (tmp_path / "named.yaml").write_text(
        yaml.safe_dump({**spec, "search": {"strategy": "tpe", "max_points": 20}})
    )
    assert space_with(tmp_path / "named.yaml", None, tmp_path / "b").spec.search.strategy == "tpe"
    assert space_with(MSD / "space.yaml", None, tmp_path / "c").spec.search.strategy == "exhaustive"


def _signals_case(root):
    """The msd's blind case with nothing concealed (jobs/msd/make_diagnosis_runs.py): a model's recordings."""
    spec = importlib.util.spec_from_file_location("make_diagnosis_runs", MSD / "make_diagnosis_runs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.make("clean", root / "msd"), None, ()


def _robotti_case(root):
    """One bundled run in the field-data format, with its own calibration space (held out in time blocks)."""
    runs = root / "runs"
    shutil.copytree(SCENARIOS / "sin1", runs / "sin1")
    return None, runs, ("wheel_slip",)


CONTRACT_CASES = {"signals": _signals_case, "robotti": _robotti_case}


@pytest.mark.slow
@pytest.mark.parametrize("name", [lib.name for lib in libraries()])
def test_every_installed_library_diagnoses_a_case_and_answers_in_the_one_shape(
    name, tmp_path, dask_scheduler
):
    """The contract, run: each installed library diagnoses a small case of its own on the cluster and
    answers in answer.Answer's shape (strict JSON, its own fields under ``case``), with a summary and one
    HTML page."""
    assert name in CONTRACT_CASES, f"library {name}: add a small case of its own to CONTRACT_CASES"
    space, scenarios, only = CONTRACT_CASES[name](tmp_path)
    said: list[str] = []
    result = diagnose(
        space, scenarios, Request(out=tmp_path / "out", hypotheses=only), said.append, address=dask_scheduler
    )
    answer = Answer.model_validate(strict_loads(strict_json.dumps(result.to_json())))
    assert answer.library == name and answer.verdict == result.verdict
    assert answer.effects and answer.validation is not None and answer.held_out
    assert answer.held_out_before is not None and answer.held_out_after is not None
    assert all(isinstance(line, str) for line in result.summary()) and said
    assert "data:image/png;base64," in Path(answer.files["html"]).read_text()
    page = Path(answer.files["report"]).read_text()  # the engine's skeleton, with the library's sections
    assert page.startswith(f"# Diagnosis of {answer.space}\n") and "## Named effects" in page
    assert report_again(Path(answer.files["json"]))["report"].read_text() == page  # from diagnosis.json alone
