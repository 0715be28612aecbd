"""space.yaml: validation messages, expansion, stable task ids, constraints."""

from __future__ import annotations

import shutil

import pytest
from conftest import REPO, SCENARIOS, write_space

from dse_runner import DseError
from dse_runner.sweeps.constraints import compile_constraint
from dse_runner.sweeps.expand import count, expand
from dse_runner.sweeps.rank import pareto_mask
from dse_runner.sweeps.spec import load_space


def test_the_papers_grid():
    from conftest import REPO

    space = load_space(REPO / "jobs" / "robotti" / "space.yaml")
    assert space.parameters["vehicle.cAlphaF"] == [20000.0, 24500.0, 29000.0, 33500.0, 38000.0]
    assert space.parameters["vehicle.mass"] == [1000.0, 1500.0, 2000.0, 2500.0, 3000.0]
    assert space.parameters["vehicle.mu"] == [0.3, 0.4, 0.5, 0.6, 0.7]
    assert len(space.scenarios) == 12
    assert sum(1 for _ in expand(space)) == 1500


def test_ranges_counts_and_logs(tmp_path):
    space = load_space(
        write_space(
            tmp_path,
            parameters={
                "vehicle.mass": {"start": 1000, "stop": 2000, "num": 3},
                "vehicle.cAlphaF": {"start": 1000, "stop": 100000, "num": 3, "log": True},
                "vehicle.mu": [0.5],
            },
        )
    )
    assert space.parameters["vehicle.mass"] == [1000.0, 1500.0, 2000.0]
    assert space.parameters["vehicle.cAlphaF"] == pytest.approx([1000.0, 10000.0, 100000.0])


def test_constraints_filter_points(tmp_path):
    space = load_space(
        write_space(tmp_path, constraints=["vehicle.mass / 1000 < 2.5 and vehicle.cAlphaF > 20000"])
    )
    points = {dict(t.point)["vehicle.mass"] for t in expand(space)}
    assert points == {1000.0, 2000.0}
    assert sum(1 for _ in expand(space)) == 4  # 2 points x 2 scenarios


@pytest.mark.parametrize("constraints", [[], ["vehicle.mass / 1000 < 2.5 and vehicle.cAlphaF > 20000"]])
def test_a_sweep_counts_the_tasks_it_expands(tmp_path, constraints):
    """An unconstrained grid is counted without walking it; a constrained one by walking it."""
    space = load_space(write_space(tmp_path, constraints=constraints))
    assert count(space, set()) == (len(list(expand(space))), 0) == ((4 if constraints else 12), 0)


def test_task_ids_are_stable_and_follow_the_data(tmp_path):
    space = load_space(write_space(tmp_path))
    ids = [t.task_id for t in expand(space)]
    assert ids == [t.task_id for t in expand(load_space(write_space(tmp_path)))]
    assert len(set(ids)) == len(ids)
    # A changed recording gives new ids for that scenario only.
    copy = tmp_path / "data" / "sin1"
    shutil.copytree(SCENARIOS / "sin1", copy)
    with open(copy / "gps_position.csv", "a") as f:
        f.write("84.10,1.0,1.0\n")
    changed = load_space(write_space(tmp_path, scenarios=[str(copy), str(SCENARIOS / "speed_step2")]))
    new = [t.task_id for t in expand(changed)]
    assert set(new[:6]).isdisjoint(ids) and new[6:] == ids[6:]


def test_variants_run_each_folder_once_per_parameter_set(tmp_path):
    plants = [
        {"name": "light", "parameters": {"vehicle.mass": 1200}},
        {"name": "heavy", "parameters": {"vehicle.mass": 2500, "vehicle.mu": 0.4}},
    ]
    space = load_space(
        write_space(tmp_path, scenarios=[{"path": str(SCENARIOS / "sin1"), "variants": plants}])
    )
    by_name = {s.name: s for s in space.scenarios}
    assert sorted(by_name) == ["sin1-heavy", "sin1-light"]
    assert by_name["sin1-heavy"].parameters == {"vehicle.mass": 2500, "vehicle.mu": 0.4}
    assert by_name["sin1-light"].files == by_name["sin1-heavy"].files  # the same recorded run
    tasks = list(expand(space))
    assert len(tasks) == 2 * len({t.point for t in tasks})  # every point on both plants
    assert len({t.task_id for t in tasks}) == len(tasks)


def test_a_variant_naming_an_unknown_variable_names_it(tmp_path):
    plants = [{"name": "typo", "parameters": {"vehicle.mas": 1200}}]
    with pytest.raises(
        DseError, match=r"scenario sin1-typo: parameters: unknown variable 'vehicle\.mas'.*did you mean mass"
    ):
        load_space(write_space(tmp_path, scenarios=[{"path": str(SCENARIOS / "sin1"), "variants": plants}]))


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"paramters": {}}, r"space\.yaml: paramters: Extra inputs are not permitted"),
        (
            {"parameters": {"vehicle.mass": {"start": 1, "stop": 2, "step": 1, "num": 2}}},
            r"space\.yaml: parameters\.vehicle\.mass\..*exactly one of 'step' or 'num'",
        ),
        (
            {"parameters": {"vehicle.mass": {"start": 3, "stop": 2, "num": 2}}},
            r"'stop' must not be below 'start'",
        ),
        ({"scenarios": ["nowhere/*"]}, r"space\.yaml: scenarios\.0\.path: 'nowhere/\*' matches no folder"),
        (
            {"parameters": {"vehicle.masss": [1]}},
            r"space\.yaml: parameters: unknown variable 'vehicle\.masss'.*mass",
        ),
        ({"parameters": {"vehicle.x": [1]}}, r"'vehicle\.x' is an output"),
        ({"constraints": ["__import__('os').system('true')"]}, r"constraints\.0: .*Call .* is not allowed"),
        ({"constraints": ["vehicle.mu > 0.3"]}, r"'vehicle\.mu' is not a swept parameter"),
        ({"objectives": ["cross_track_eror"]}, r"unknown objective 'cross_track_eror'"),
        (
            {"ranking": {"objective": "max_error"}, "objectives": ["cross_track_error"]},
            r"ranking uses objective 'max_error', which 'objectives' does not list",
        ),
        (
            {"search": {"strategy": "simulated_annealing"}},
            r"unknown search strategy 'simulated_annealing': available are cmaes, exhaustive, fast, genetic",
        ),
        (
            {"parameters": {"vehicle.mass": {"low": 1000, "high": 3000}}},
            r"search: exhaustive needs a list or a grid .* vehicle\.mass is an interval",
        ),
        (
            {"search": {"strategy": "tpe", "n_startup": 3}},
            r"search\.n_startup: TPESampler has no option 'n_startup' \(it takes .*n_startup_trials",
        ),
        (
            {"parameters": {"vehicle.mass": {"low": 3000, "high": 1000}}},
            r"parameters\.vehicle\.mass\.interval: 'high' must be above 'low'",
        ),
        ({"name": "a b"}, r"space\.yaml: name: String should match pattern"),
        # a union's wrong value is judged by the member its shape picks: that member's messages only
        (
            {"ranking": {"pareto": [{"objective": "max_error", "goal": "maxx"}]}},
            r"space\.yaml: ranking\.pareto\.0\.mapping\.goal: Input should be 'min' or 'max'$",
        ),
        (
            {"scenarios": [{"path": "runs/*", "variants": [{"name": "a", "parametrs": {}}]}]},
            (
                r"space\.yaml: scenarios\.0\.source\.variants\.list\.0\.parameters: Field required; "
                r"scenarios\.0\.source\.variants\.list\.0\.parametrs: Extra inputs are not permitted$"
            ),
        ),
        (
            {"parameters": {"vehicle.mass": [1800, {"kg": 2000}]}},
            (
                r"space\.yaml: parameters\.vehicle\.mass\.values\.1: "
                r"expected a number, a Boolean or a string, not a mapping$"
            ),
        ),
        (
            {"parameters": {"vehicle.mass": [None]}},
            r"space\.yaml: parameters\.vehicle\.mass\.values\.0: no value given$",
        ),
        (
            {
                "scenarios": [
                    {
                        "name": "s",
                        "inputs": {"controller.steering": {"csv": "a.csv", "colum": "q"}},
                        "recorded": {"csv": "r.csv", "tme": "t"},
                    }
                ]
            },
            (
                r"space\.yaml: scenarios\.0\.inline\.inputs\.controller\.steering\.mapping\.colum: "
                r"Extra inputs are not permitted; scenarios\.0\.inline\.recorded\.mapping\.tme: "
                r"Extra inputs are not permitted$"
            ),
        ),
        # misspelt names suggest the nearest (issue 63)
        (
            {"search": {"strategy": "sobl"}},
            r"unknown search strategy 'sobl' \(did you mean sobol\?\): available",
        ),
        (
            {"ranking": {"objective": "cross_track_eror"}},
            r"ranking uses objective 'cross_track_eror', which 'objectives' does not list \(.*; did you mean "
            + r"cross_track_error\?\)",
        ),
        (
            {"scenarios": [{"path": str(SCENARIOS / "sin1"), "kind": "fielddata"}]},
            r"unknown scenario kind 'fielddata' \(did you mean field_data\?\): installed are",
        ),
    ],
)
def test_bad_specs_name_file_key_and_reason(tmp_path, changes, message):
    with pytest.raises(DseError, match=message):
        load_space(write_space(tmp_path, **changes))


def test_constraint_grammar():
    check = compile_constraint("abs(a.x - 2) <= max(a.y, 1) or not a.y", {"a.x", "a.y"})
    assert check({"a.x": 2.5, "a.y": 0}) and not check({"a.x": 5, "a.y": 2})
    for bad in ["a.x.__class__", "[a.x]", "a.x if a.y else 1", "lambda: 1"]:
        with pytest.raises(DseError, match="not"):
            compile_constraint(bad, {"a.x", "a.y"})


def test_pareto_mask_min_and_max():
    import numpy as np

    values = np.array([[1, 5], [2, 2], [3, 1], [3, 3], [1, 5]], dtype=float)
    assert pareto_mask(values, ["min", "min"]).tolist() == [True, True, True, False, True]
    # Maximising the second objective: only the points with the largest second value for their first.
    assert pareto_mask(values, ["min", "max"]).tolist() == [True, False, False, False, True]


def test_a_space_names_an_fmu_as_simulate_does_and_a_file_that_is_no_model_is_named(tmp_path):
    """``multimodel: VanDerPol.fmu`` (one FMU, no multi-model file) was read as YAML and failed with an
    unexpected UnicodeDecodeError. The instance is named after the file, as ``simulate VanDerPol.fmu``
    names it, so a values file of one replays in the other."""
    import shutil

    import yaml

    from dse_runner.simulation.build import build_fmu
    from dse_runner.simulation.run import simulate

    fmu = tmp_path / "VanDerPol.fmu"
    shutil.copyfile(build_fmu(REPO / "tests" / "fmus" / "vdp_me"), fmu)
    spec = {
        "name": "vdp",
        "multimodel": "VanDerPol.fmu",
        "experiment": {"stop_time": 2.0, "step": 0.1},
        "parameters": {"VanDerPol.mu": [0.5, 1.5]},
        "objectives": {"x_end": {"signal": "VanDerPol.x0", "reduce": "final"}},
    }
    (tmp_path / "space.yaml").write_text(yaml.safe_dump(spec))
    space = load_space(tmp_path / "space.yaml")
    assert list(space.plan.variables) == ["VanDerPol"] and space.parameters["VanDerPol.mu"] == [0.5, 1.5]
    direct = simulate(fmu, None, {"VanDerPol.mu": 1.5}, stop_time=2.0, step=0.1)
    assert direct.values["VanDerPol.mu"] == 1.5  # the space's names are simulate's
    (tmp_path / "binary.yaml").write_bytes(fmu.read_bytes())
    (tmp_path / "space.yaml").write_text(yaml.safe_dump({**spec, "multimodel": "binary.yaml"}))
    with pytest.raises(
        DseError, match=r"binary.yaml: not a multi-model: it is not text \(a model is an .fmu file"
    ):
        load_space(tmp_path / "space.yaml")


# ---- first contact (issue 63): a calibration that ranks, names as simulate takes them -----------------


def test_a_residuals_objective_alone_ranks_by_its_sum_of_squares_and_other_vectors_say_what_to_add(tmp_path):
    """A least-squares calibration needs a vector objective, a ranking a number: the residuals alone rank by
    their sum of squares, added beside them; a vector function alone, or a ranking that names the residuals,
    gets a message naming what to add."""
    from conftest import write_msd_search

    from dse_runner.simulation.objectives import Fit

    residuals = {"position": {"signal": "msd.x", "recorded": "x", "metric": "residuals"}}
    space = load_space(write_msd_search(tmp_path / "a", {"strategy": "least_squares"}, objectives=residuals))
    assert space.spec.ranking.objective == "position_sum_squares"
    assert space.objectives["position_sum_squares"] == Fit(signal="msd.x", recorded="x", metric="sum_squares")
    assert list(space.spec.objectives) == ["position", "position_sum_squares"]  # the saved spec says what ran

    folder = tmp_path / "b"
    folder.mkdir()
    (folder / "fits.py").write_text(
        "def errors(trajectory, scenario):\n    return trajectory.column('msd.x')\n\nerrors.vector = True\n"
    )
    with pytest.raises(
        DseError,
        match=r"ranking needs an objective with one number per task, and errors is a vector \(a number per "
        r"sample\): add a scalar objective beside it, e\.g\. \{fit: \{signal: inst\.var, recorded: column, "
        r"metric: rmse\}\}",
    ):
        load_space(write_msd_search(folder, {"strategy": "random"}, objectives={"errors": "fits:errors"}))

    ranked = {"objective": "position"}
    with pytest.raises(
        DseError,
        match=r"ranking uses 'position', a vector objective \(a number per sample\); rankings need one "
        r"number per task: rank by its sum of squares, \{position_sum_squares: \{signal: msd\.x, recorded: "
        r"x, metric: sum_squares\}\}, or leave ranking\.objective out",
    ):
        load_space(
            write_msd_search(tmp_path / "c", {"strategy": "random"}, objectives=residuals, ranking=ranked)
        )


def test_the_sum_of_squares_is_that_of_the_residuals():
    from dse_runner.simulation.run import simulate

    scenario = REPO / "jobs" / "quickstart" / "rig" / "steps"
    metrics = ("residuals", "sum_squares", "rmse")
    fits = {name: {"signal": "msd.x", "recorded": "x", "metric": name} for name in metrics}
    found = simulate(REPO / "jobs" / "msd" / "fmus" / "msd", scenario, {"k": 13}, objectives=fits).objectives
    squares = sum(e * e for e in found["residuals"])
    assert found["sum_squares"] == pytest.approx(squares, rel=1e-12)
    assert found["rmse"] == pytest.approx((squares / len(found["residuals"])) ** 0.5, rel=1e-12)


def test_a_single_fmus_space_takes_bare_names_as_simulate_does(tmp_path):
    """``simulate vdp.fmu --set mu=…`` takes the bare name; so does a space on that FMU (issue 63), and the
    run it makes is the same. Names that cannot be right suggest the ones that can, also when only the case
    differs, and a variable listed under both names is one variable listed twice."""
    import yaml

    from dse_runner.simulation.build import build_fmu
    from dse_runner.sweeps.space_run import simulate_space

    fmu = tmp_path / "vdp.fmu"
    shutil.copyfile(build_fmu(REPO / "tests" / "fmus" / "vdp_me"), fmu)
    spec = {
        "name": "vdp",
        "multimodel": "vdp.fmu",
        "experiment": {"stop_time": 2.0, "step": 0.1},
        "parameters": {"mu": [1.5]},
        "objectives": {"x_end": {"signal": "x0", "reduce": "final"}},
    }
    path = tmp_path / "space.yaml"
    path.write_text(yaml.safe_dump(spec))
    assert load_space(path).parameters == {"mu": [1.5]}
    from dse_runner.simulation.run import simulate

    bare = simulate_space(path, None, {})
    direct = simulate(fmu, None, {"mu": 1.5}, stop_time=2.0, step=0.1, objectives=spec["objectives"])
    assert bare.values["vdp.mu"] == 1.5 and bare.objectives == direct.objectives

    for parameters, message in [
        (
            {"MU": [1.5]},
            r"parameters: unknown variable 'vdp\.MU': instance 'vdp' \(\w+\) has no variable 'MU' \("
            + r"did you mean mu\?\)",
        ),
        ({"Vdp.mu": [1.5]}, r"names instance 'Vdp', but the multi-model has vdp \(did you mean vdp\?\)"),
        ({"mu": [1.5], "vdp.mu": [1.0]}, r"parameters: 'mu' and 'vdp\.mu' name the same variable, vdp\.mu"),
    ]:
        path.write_text(yaml.safe_dump({**spec, "parameters": parameters}))
        with pytest.raises(DseError, match=message):
            load_space(path)


def test_a_space_whose_recordings_no_objective_reads_is_warned_of(tmp_path):
    """``submit`` warns (one line, before the sweep) of recordings its objectives never compare with: a
    comparison the author likely meant. A fit to one of them, or a function that may read it, silences it."""
    from conftest import write_msd_search

    from dse_runner.sweeps.spec import unread_recordings

    peak = {"peak": {"signal": "msd.x", "reduce": "max"}}
    space = load_space(write_msd_search(tmp_path / "a", {"strategy": "random"}, objectives=peak))
    assert unread_recordings(space) == (
        f"{space.path}: the recordings of scenario ringdown are compared by no objective (the objectives, "
        "peak, only reduce signals); compare a column with {signal: inst.var, recorded: x, metric: rmse}"
    )
    assert unread_recordings(load_space(write_msd_search(tmp_path / "b", {"strategy": "random"}))) is None
