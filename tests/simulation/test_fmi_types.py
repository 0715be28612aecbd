"""Every FMI type, both interfaces and FMUs from the wild, through our own master (dse_runner.simulate).

The references are FMPy's ``simulate_fmu`` on the same FMU at the same communication points, FMPy
driven by hand for a coupled pair, and the functions each test FMU's model.c documents:
tests/fmus/types2 (FMI 2.0, every FMI 2 type), tests/fmus/types3 (FMI 3.0), the water tank and
its controller (jobs/watertank), the mass-spring-damper (jobs/msd, model exchange only), a
PythonFMU export, and an FMU offering both interfaces merged here from tests/fmus/wild_dual_cs and
wild_dual_me.
"""

from __future__ import annotations

import functools
import json
import re
import shutil
import sysconfig
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import REPO, strict_loads
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu
from typer.testing import CliRunner

from dse_runner.errors import DseError
from dse_runner.interfaces.cli import app
from dse_runner.simulation import cosim
from dse_runner.simulation.build import build_fmu
from dse_runner.simulation.fmu import FmuWarning
from dse_runner.simulation.multimodel import MultiModel
from dse_runner.simulation.run import as_plan, simulate
from dse_runner.simulation.trajectory import CosimError
from dse_runner.simulation.variables import check_value

SOURCES = {
    "types2": REPO / "tests" / "fmus" / "types2",
    "types3": REPO / "tests" / "fmus" / "types3",
    "tank": REPO / "jobs" / "watertank" / "fmus" / "tank",
    "controller": REPO / "jobs" / "watertank" / "fmus" / "controller",
    "msd": REPO / "jobs" / "msd" / "fmus" / "msd",
    "dual_cs": REPO / "tests" / "fmus" / "wild_dual_cs",
    "dual_me": REPO / "tests" / "fmus" / "wild_dual_me",
}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, Path]:
    """Every test FMU built, as ``<name>.fmu`` so that a single-FMU run's instance is ``<name>``."""
    cache, folder = tmp_path_factory.mktemp("cache"), tmp_path_factory.mktemp("fmus")
    built = {}
    for name, source in SOURCES.items():
        built[name] = folder / f"{name}.fmu"
        shutil.copyfile(build_fmu(source, cache), built[name])
    built["dual"] = merge_dual(built["dual_cs"], built["dual_me"], folder / "dual.fmu")
    return built


@pytest.fixture(scope="module")
def pythonfmu_path(tmp_path_factory) -> Path:
    pytest.importorskip("pythonfmu")
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        pytest.skip("PythonFMU's binary needs a Python built with a shared libpython")
    from pythonfmu_models import build_pythonfmu

    return build_pythonfmu(tmp_path_factory.mktemp("pythonfmu"))


def merge_dual(cs: Path, me: Path, target: Path) -> Path:
    """One FMU offering both FMI 2.0 interfaces, each with its own model identifier and binary."""
    with zipfile.ZipFile(cs) as a, zipfile.ZipFile(me) as b:
        cs_xml, me_xml = a.read("modelDescription.xml").decode(), b.read("modelDescription.xml").decode()
        element = re.search(r"  <CoSimulation.*?</CoSimulation>\n", cs_xml, re.DOTALL).group(0)
        xml = me_xml.replace("</ModelExchange>\n", "</ModelExchange>\n" + element)  # the schema's order
        with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as out:
            out.writestr("modelDescription.xml", xml)
            for archive in (a, b):
                for name in archive.namelist():
                    if name.startswith("binaries/"):
                        out.writestr(name, archive.read(name))
    return target


def bare(result) -> dict[str, np.ndarray]:
    """A single FMU's recorded signals by the variables' own names."""
    return {name.partition(".")[2]: column for name, column in result.outputs.items()}


def write_multimodel(folder: Path, fmus: dict[str, Path], connections: dict, **more) -> Path:
    path = folder / "multimodel.yaml"
    path.write_text(
        yaml.safe_dump({"fmus": {k: str(v) for k, v in fmus.items()}, "connections": connections, **more})
    )
    return path


def rewrite(
    source: Path, target: Path, rename: dict | None = None, add: dict | None = None, edit=None
) -> Path:
    """A copy of an FMU with members renamed, added, or its modelDescription.xml edited."""
    rename = rename or {}
    with zipfile.ZipFile(source) as a, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as b:
        for name in a.namelist():
            data = a.read(name)
            if name == "modelDescription.xml" and edit is not None:
                data = edit(data.decode()).encode()
            b.writestr(rename.get(name, name), data)
        for name, data in (add or {}).items():
            b.writestr(name, data)
    return target


# ---- 1. the same numbers as FMPy ---------------------------------------------------------------

CS_CASES = {
    "types2": (
        {
            "real_in": 1.5,
            "real_gain": 3.0,
            "int_in": 3,
            "int_offset": 10,
            "enum_in": 2,
            "bool_in": True,
            "string_in": "ab",
        },
        3.0,
        0.1,
    ),
    "types3": (
        {
            "float64_in": 1.5,
            "float64_gain": 3.0,
            "float32_in": 3.0,
            "int32_in": 3,
            "int32_offset": 10,
            "int64_in": 2**40,
            "uint16_in": 65530,
            "bool_in": True,
            "string_in": "ab",
            "enum_in": 2,
        },
        3.0,
        0.1,
    ),
    "tank": ({"valvecontrol": 1.0, "initial_level": 2.0, "inflow": 0.3}, 10.0, 0.05),
}


def assert_agrees_with_fmpy(result, theirs, tolerance: float) -> None:
    """Same communication points; every output FMPy records we record, equal within ``tolerance``."""
    ours = bare(result)
    assert len(result.time) == len(theirs["time"])
    assert np.abs(result.time - theirs["time"]).max() < 1e-12
    names = [n for n in theirs.dtype.names if n != "time"]
    assert sorted(names) == sorted(n.partition(".")[2] for n in result.trajectory.names)
    for name in names:
        error = np.abs(ours[name] - theirs[name].astype(float)).max()
        assert error <= tolerance, f"{name}: {error:g}"


@pytest.mark.parametrize("name", CS_CASES)
def test_co_simulation_agrees_with_fmpy(fmus, name):
    values, stop, step = CS_CASES[name]
    theirs = simulate_fmu(str(fmus[name]), stop_time=stop, output_interval=step, start_values=values)
    result = simulate(fmus[name], values=values, stop_time=stop, step=step)
    assert_agrees_with_fmpy(result, theirs, 1e-9)


def test_string_outputs_follow_their_documented_function(fmus):
    """FMPy does not record strings; model.c says string_out = string_in followed by suffix."""
    for name in ("types2", "types3"):
        result = simulate(fmus[name], values={"string_in": "ab", "suffix": "?"}, stop_time=1.0, step=0.25)
        assert result.trajectory.texts == {f"{name}.string_out": ["ab?"] * 5}


def test_a_pythonfmu_export_agrees_with_fmpy(pythonfmu_path):
    values = {"real_in": 1.5, "gain": 3.0, "int_in": 3, "offset": 10, "bool_in": True, "string_in": "ab"}
    theirs = simulate_fmu(str(pythonfmu_path), stop_time=2.0, output_interval=0.25, start_values=values)
    result = simulate(pythonfmu_path, values=values, stop_time=2.0, step=0.25)
    assert_agrees_with_fmpy(result, theirs, 1e-9)
    # outputs are computed in do_step only: the start value "" until the first step
    assert result.trajectory.texts == {"types_slave.string_out": [""] + ["ab!"] * 8}


MSD_VALUES = {"k": 14.0, "c": 0.8}


def test_model_exchange_with_cvode_agrees_with_fmpy_within_its_tolerance(fmus):
    theirs = simulate_fmu(
        str(fmus["msd"]), solver="CVode", stop_time=5.0, output_interval=0.01, start_values=MSD_VALUES
    )
    result = simulate(fmus["msd"], values=MSD_VALUES, stop_time=5.0, step=0.01)
    assert result.trajectory.names == ("msd.x", "msd.v")
    # the same solver at the same (default) relative tolerance 1e-5, on an amplitude of 0.1 m
    assert_agrees_with_fmpy(result, theirs, 1e-6)


def test_model_exchange_with_euler_agrees_with_fmpy_exactly(fmus):
    model = MultiModel(fmus={"msd": str(fmus["msd"])}, instances={"msd": {"solver": "euler"}})
    theirs = simulate_fmu(
        str(fmus["msd"]),
        solver="Euler",
        step_size=0.01,
        stop_time=5.0,
        output_interval=0.01,
        start_values=MSD_VALUES,
    )
    result = simulate(model, values={f"msd.{k}": v for k, v in MSD_VALUES.items()}, stop_time=5.0, step=0.01)
    assert_agrees_with_fmpy(result, theirs, 1e-12)


# ---- 2. every type in and out ------------------------------------------------------------------


@pytest.mark.parametrize("bool_in, invert", [(True, False), (False, False), (True, True), (False, True)])
def test_every_fmi2_type_round_trips(fmus, bool_in, invert):
    values = {
        "real_in": -2.5,
        "real_gain": 4.0,
        "int_in": -7,
        "int_offset": 100,
        "enum_in": 3,
        "bool_in": bool_in,
        "invert": invert,
        "string_in": "héllo",
        "suffix": "?",
    }
    result = simulate(fmus["types2"], values=values, stop_time=1.0, step=0.25)
    out, t, n = bare(result), result.time, np.arange(5)
    assert np.array_equal(out["real_out"], -10.0 + t)
    assert np.array_equal(out["int_out"], -7 + 100 + n)
    assert np.array_equal(out["steps"], n)
    assert np.array_equal(out["enum_out"], (3 - 1 + n) % 3 + 1)
    assert np.array_equal(out["bool_out"], np.full(5, float(bool_in != invert)))  # a Boolean is 0 or 1
    assert result.trajectory.texts == {"types2.string_out": ["héllo?"] * 5}
    assert result.trajectory.values.dtype == np.float64


@pytest.mark.parametrize("as_text", [False, True], ids=["values", "text"])
def test_every_fmi3_type_round_trips(fmus, as_text):
    values = {
        "float64_in": 0.1,
        "float64_gain": 10.0,
        "float32_in": 0.75,
        "int32_in": -3,
        "int32_offset": -100,
        "int64_in": 2**40 + 1,
        "uint16_in": 65534,
        "bool_in": True,
        "invert": False,
        "string_in": "abc",
        "suffix": "",
        "enum_in": 2,
    }
    if as_text:  # as the command line's --set gives them
        values = {k: str(v).lower() if isinstance(v, bool) else str(v) for k, v in values.items()}
    result = simulate(fmus["types3"], values=values, stop_time=1.0, step=0.25)
    out, t, n = bare(result), result.time, np.arange(5)
    assert np.array_equal(out["float64_out"], 10.0 * 0.1 + t)
    assert np.array_equal(out["float32_out"], np.full(5, 0.375))
    assert np.array_equal(out["int32_out"], -3 - 100 + n)
    assert np.array_equal(out["steps"], n)
    assert np.array_equal(out["int64_out"], 2**41 + 2 + n)  # exact: below 2^53
    assert np.array_equal(out["uint16_out"], (65534 + n) % 65536)  # wraps inside the FMU
    assert np.array_equal(out["bool_out"], np.ones(5))
    assert np.array_equal(out["enum_out"], (2 - 1 + n) % 3 + 1)
    assert result.trajectory.texts == {"types3.string_out": ["abc"] * 5}


@pytest.mark.parametrize(
    "name, variable, value, message",
    [
        ("types3", "int32_in", 2**40, "types3.int32_in = 1099511627776 does not fit an Int32"),
        ("types3", "uint16_in", -1, "types3.uint16_in = -1 does not fit a UInt16 (0 to 65535)"),
        ("types3", "uint16_in", 65536, "does not fit a UInt16"),
        ("types2", "int_in", 2**31, "types2.int_in = 2147483648 does not fit an Integer"),
        ("types2", "enum_in", 4, "types2.enum_in = 4 is above its declared max 3"),
        ("types2", "int_in", 1.5, "types2.int_in: 1.5 is not a whole number"),
        ("types2", "bool_in", 2, "types2.bool_in: 2 is not a Boolean"),
        ("types2", "bool_in", "yes", "types2.bool_in: 'yes' is not a valid Boolean"),
        ("types2", "real_gain", 11, "types2.real_gain = 11 is above its declared max 10"),
        ("types2", "real_out", 1.0, "'types2.real_out' is an output, not a parameter or input"),
    ],
)
def test_a_value_its_type_cannot_hold_is_refused(fmus, name, variable, value, message):
    with pytest.raises(DseError, match=re.escape(message)):
        simulate(fmus[name], values={variable: value}, stop_time=1.0, step=0.25)


def test_int64_values_stay_exact_beyond_float_precision(fmus):
    int64_in = as_plan(fmus["types3"]).variable("types3.int64_in", "test")
    assert check_value(int64_in, 2**62 + 1) == 2**62 + 1
    assert check_value(int64_in, str(2**62 + 1)) == 2**62 + 1  # text is not read through a float
    assert check_value(int64_in, 3.0) == 3 and type(check_value(int64_in, 3.0)) is int


# ---- 3. connections between types --------------------------------------------------------------


def hand_coupled_watertank(fmus, tmp_path, stop: float, step: float) -> tuple[np.ndarray, np.ndarray]:
    """The tank and controller coupled by hand through FMPy, Jacobi as our master: read both outputs,
    set both inputs (the Boolean valve as 0.0/1.0), step both."""
    instances = {}
    for name in ("tank", "controller"):
        md = read_model_description(str(fmus[name]))
        slave = FMU2Slave(
            guid=md.guid,
            unzipDirectory=extract(str(fmus[name]), str(tmp_path / name)),
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        instances[name] = (slave, {v.name: v.valueReference for v in md.modelVariables})
    (tank, tv), (controller, cv) = instances["tank"], instances["controller"]
    levels, valves = [], []
    n = round(stop / step)
    try:
        for k in range(n + 1):
            (level,), (valve,) = tank.getReal([tv["level"]]), controller.getBoolean([cv["valve"]])
            levels.append(level)
            valves.append(float(valve))
            if k == n:
                break
            controller.setReal([cv["level"]], [level])
            tank.setReal([tv["valvecontrol"]], [1.0 if valve else 0.0])
            tank.doStep(k * step, step)
            controller.doStep(k * step, step)
    finally:
        for slave, _ in instances.values():
            slave.terminate()
            slave.freeInstance()
    return np.array(levels), np.array(valves)


def test_boolean_valve_drives_real_valvecontrol_as_fmpy_by_hand(fmus, tmp_path):
    path = write_multimodel(
        tmp_path,
        {"tank": fmus["tank"], "controller": fmus["controller"]},
        {"tank.level": ["controller.level"], "controller.valve": ["tank.valvecontrol"]},
    )
    result = simulate(path, stop_time=30.0, step=0.1)
    levels, valves = hand_coupled_watertank(fmus, tmp_path, 30.0, 0.1)
    assert np.abs(result.trajectory.column("tank.level") - levels).max() < 1e-12
    assert np.array_equal(result.trajectory.column("controller.valve"), valves)
    assert set(valves) == {0.0, 1.0} and np.count_nonzero(np.diff(valves) > 0) >= 3  # it oscillates


@pytest.fixture
def pair(fmus, tmp_path):
    """A multi-model of two types2 instances and a types3, with the given connections."""

    def make(connections: dict) -> Path:
        return write_multimodel(
            tmp_path, {"a": fmus["types2"], "b": fmus["types2"], "c": fmus["types3"]}, connections
        )

    return make


@pytest.mark.parametrize(
    "target, needs",
    [
        ({"input": "b.int_in"}, "round: true"),
        ({"input": "b.bool_in"}, "threshold: 0.5"),
        ({"input": "c.int64_in"}, "round: true"),
        ({"input": "c.enum_in"}, "round: true"),
        ({"input": "c.bool_in"}, "threshold: 0.5"),
    ],
)
def test_a_real_feeds_an_integer_or_boolean_only_when_told_how(pair, target, needs):
    with pytest.raises(DseError) as caught:
        as_plan(pair({"a.real_out": [target]}))
    message = str(caught.value)
    assert f"connection a.real_out -> {target['input']}" in message and needs in message
    assert "\n" not in message


@pytest.mark.parametrize(
    "source, target, message",
    [
        ("a.string_out", "b.real_in", "a String cannot feed a Real: strings connect only to strings"),
        ("a.real_out", "b.string_in", "a Real cannot feed a String"),
        ("a.string_out", "c.int32_in", "a String cannot feed an Int32"),
        ("a.int_out", "b.bool_in", "an Integer feeds a Boolean only through a threshold"),
    ],
)
def test_strings_connect_only_to_strings(pair, source, target, message):
    with pytest.raises(DseError) as caught:
        as_plan(pair({source: [target]}))
    assert f"connection {source} -> {target}" in str(caught.value) and message in str(caught.value)


def test_a_misspelt_connection_option_gets_one_message(pair):
    """A target mapping with a typo is judged as a mapping only: not also as an input's name."""
    with pytest.raises(DseError) as caught:
        as_plan(pair({"a.real_out": [{"input": "c.bool_in", "treshold": 0.5}]}))
    assert (
        str(caught.value).split(": ", 1)[1]
        == "connections.a.real_out.0.mapping.treshold: Extra inputs are not permitted"
    )


def test_an_option_a_connection_does_not_need_is_refused(pair):
    with pytest.raises(DseError, match="this connection needs neither"):
        as_plan(pair({"a.real_out": [{"input": "b.real_in", "round": True}]}))
    with pytest.raises(DseError, match="either 'round' or 'threshold', not both"):
        as_plan(pair({"a.real_out": [{"input": "b.int_in", "round": True, "threshold": 1.0}]}))


def test_conversions_round_threshold_and_widen(pair):
    """a.real_out = 1.3 + t feeds b's Integer rounded, b's Boolean through a threshold and c's UInt16
    rounded; Boolean, Integer, Int64 and String outputs feed their own or wider types as they are."""
    path = pair(
        {
            "a.real_out": [
                {"input": "b.int_in", "round": True},
                {"input": "b.bool_in", "threshold": 1.5},
                {"input": "c.uint16_in", "round": True},
            ],
            "a.bool_out": ["c.bool_in"],  # FMI 2 Boolean -> FMI 3 Boolean
            "a.int_out": ["c.float64_in"],  # Integer -> Float64, exact
            "c.int64_out": ["b.real_in"],  # Int64 -> Real
            "a.enum_out": ["c.int32_in"],  # an enumeration is an integer
            "a.string_out": ["b.string_in"],
        }
    )
    values = {"a.real_in": 1.3, "a.real_gain": 1.0, "a.string_in": "x", "c.int64_in": 5}
    result = simulate(path, values=values, stop_time=2.0, step=0.25)
    col = result.trajectory.column
    source, n, t = col("a.real_out"), np.arange(len(result.time)), result.time
    assert np.array_equal(source, 1.3 + t)
    k = n[1:]  # each step's inputs are the outputs at its start (Jacobi): index k sees k - 1
    assert np.array_equal(col("b.int_out")[k], np.rint(source[k - 1]) + k)
    assert np.array_equal(col("b.bool_out")[k], (~(source[k - 1] > 1.5)).astype(float))  # invert: not bool_in
    assert np.array_equal(col("c.uint16_out")[k], np.rint(source[k - 1]) + k)
    assert np.array_equal(col("c.bool_out")[k], 1.0 - col("a.bool_out")[k - 1])
    assert np.array_equal(col("c.float64_out")[k], 2.0 * col("a.int_out")[k - 1] + t[k])
    assert np.array_equal(col("b.real_out")[k], 2.0 * col("c.int64_out")[k - 1] + t[k])
    assert np.array_equal(col("c.int32_out")[k], col("a.enum_out")[k - 1] + k)
    assert result.trajectory.texts["b.string_out"][1:] == ["x!!"] * (len(t) - 1)


@pytest.mark.parametrize(
    "real_in, target, type_name", [(1e12, "b.int_in", "Integer"), (-5.0, "c.uint16_in", "UInt16")]
)
def test_a_rounded_value_the_target_cannot_hold_stops_the_run(pair, real_in, target, type_name):
    path = pair({"a.real_out": [{"input": target, "round": True}]})
    expected = rf"{re.escape(target)} is fed .* which rounded does not fit an? {type_name} at t=0\b"
    with pytest.raises(CosimError, match=expected):
        simulate(path, values={"a.real_in": real_in, "a.real_gain": 1.0}, stop_time=1.0, step=0.25)


# ---- 4. which interface ------------------------------------------------------------------------


def test_an_me_only_fmu_runs_through_model_exchange_and_refuses_co_simulation(fmus):
    assert as_plan(fmus["msd"]).interfaces == {"msd": "me"}
    with pytest.raises(DseError) as caught:
        simulate(fmus["msd"], interface="cs", stop_time=1.0, step=0.1)
    assert str(caught.value) == (
        f"{fmus['msd']}: co-simulation was asked for, but the FMU offers only model exchange"
    )


def test_a_dual_interface_fmu_uses_co_simulation_unless_model_exchange_is_asked(fmus, tmp_path):
    assert validate_fmu(str(fmus["dual"])) == []
    exact = np.exp(-np.arange(21) * 0.1)
    cs = simulate(fmus["dual"], stop_time=2.0, step=0.1)
    assert cs.trajectory.names == ("dual.x", "dual.me") and not cs.trajectory.column("dual.me").any()
    assert np.abs(cs.trajectory.column("dual.x") - exact).max() < 1e-14
    path = write_multimodel(tmp_path, {"dual": fmus["dual"]}, {}, instances={"dual": {"interface": "me"}})
    asked = simulate(fmus["dual"], interface="me", stop_time=2.0, step=0.1)
    for me in (simulate(path, stop_time=2.0, step=0.1), asked):
        assert (me.trajectory.column("dual.me") == 1.0).all()
        error = np.abs(me.trajectory.column("dual.x") - exact).max()
        assert 0 < error < 1e-4  # CVode's, not the exact steps'
    theirs = simulate_fmu(str(fmus["dual"]), fmi_type="ModelExchange", stop_time=2.0, output_interval=0.1)
    assert_agrees_with_fmpy(me, theirs, 1e-9)


# ---- 5. FMUs from the wild ---------------------------------------------------------------------


def fmu_warnings(caught) -> list[str]:
    return [str(w.message) for w in caught if issubclass(w.category, FmuWarning)]


def test_a_binary_named_otherwise_loads_with_one_warning_and_the_same_results(fmus, tmp_path):
    wild = rewrite(
        fmus["types2"],
        tmp_path / "types2.fmu",
        rename={"binaries/linux64/types2.so": "binaries/linux64/libtypes2-1.0.so"},
        add={"documentation/test.txt": str(tmp_path)},
    )  # its own content: warned once per process
    values = {"real_in": 1.5, "bool_in": True, "string_in": "ab", "enum_in": 2}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = simulate(wild, values=values)
        again = simulate(wild, values=values)
    assert fmu_warnings(caught) == [
        (
            "types2.fmu: no binaries/linux64/types2.so; using "
            "binaries/linux64/libtypes2-1.0.so, the only binary for this platform"
        )
    ]
    reference = simulate(fmus["types2"], values=values)
    for run in (result, again):
        assert np.array_equal(run.trajectory.values, reference.trajectory.values)
        assert run.trajectory.texts == reference.trajectory.texts


def test_two_binaries_named_otherwise_are_an_error_naming_them(fmus, tmp_path):
    with zipfile.ZipFile(fmus["types2"]) as z:
        binary = z.read("binaries/linux64/types2.so")
    wild = rewrite(
        fmus["types2"],
        tmp_path / "two.fmu",
        rename={"binaries/linux64/types2.so": "binaries/linux64/a.so"},
        add={"binaries/linux64/b.so": binary},
    )
    with pytest.raises(DseError) as caught:
        simulate(wild)
    assert str(caught.value) == (
        f"{wild}: no binary for this platform: binaries/linux64/types2.so is "
        "missing (it has binaries/linux64/a.so, binaries/linux64/b.so)"
    )


def test_a_start_value_on_a_calculated_output_warns_and_runs(fmus, tmp_path):
    wild = rewrite(
        fmus["types2"],
        tmp_path / "started.fmu",
        edit=lambda xml: xml.replace(
            'initial="calculated">\n      <Real/>', 'initial="calculated">\n      <Real start="7"/>'
        ),
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = simulate(wild, values={"real_in": 1.0})
    (message,) = fmu_warnings(caught)
    assert message.startswith("started.fmu: modelDescription.xml breaks the FMI standard: ")
    assert '"real_out"' in message and message.endswith("; loaded anyway") and "\n" not in message
    assert np.array_equal(result.trajectory.column("started.real_out"), 2.0 + result.time)


@pytest.mark.parametrize(
    "change, message",
    [
        (
            {"edit": lambda xml: xml.replace('fmiVersion="2.0"', 'fmiVersion="1.0"')},
            "FMI 1.0: dse-runner runs FMI 2.0 and 3.0 FMUs; export this model as FMI 2.0 or 3.0",
        ),
        (
            {"rename": {"binaries/linux64/types2.so": "binaries/win64/types2.dll"}},
            "no binary for this platform: binaries/linux64/types2.so is missing (it has binaries for win64)",
        ),
        (
            {"edit": lambda xml: re.sub(r"<CoSimulation.*?</CoSimulation>", "", xml, flags=re.DOTALL)},
            "offers neither co-simulation nor model exchange",
        ),
    ],
    ids=["fmi1", "win64-only", "no-interface"],
)
def test_what_cannot_run_is_a_one_line_error(fmus, tmp_path, change, message):
    wild = rewrite(fmus["types2"], tmp_path / "wild.fmu", **change)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FmuWarning)
        with pytest.raises(DseError) as caught:
            simulate(wild)
    assert str(caught.value) == f"{wild}: {message}"


def test_the_command_line_prints_an_fmu_warning_as_one_line(fmus, tmp_path):
    wild = rewrite(
        fmus["types2"],
        tmp_path / "renamed.fmu",
        rename={"binaries/linux64/types2.so": "binaries/linux64/other.so"},
        add={"documentation/test.txt": str(tmp_path)},
    )
    done = CliRunner().invoke(app, ["simulate", str(wild), "--json"])
    assert done.exit_code == 0, done.output
    assert done.stderr == (
        "warning: renamed.fmu: no binaries/linux64/types2.so; using "
        "binaries/linux64/other.so, the only binary for this platform\n"
    )
    strict_loads(done.stdout)
    failed = CliRunner().invoke(
        app,
        [
            "simulate",
            str(
                rewrite(
                    fmus["types2"], tmp_path / "old.fmu", edit=lambda xml: xml.replace('"2.0"', '"1.0"', 1)
                )
            ),
        ],
    )
    assert failed.exit_code == 2 and failed.stderr.startswith("error: ") and failed.stderr.count("\n") == 1


def test_fmpys_own_instances_still_print_their_messages_after_ours(fmus, tmp_path, capsys):
    """FMPy's varargs logger proxy has one target per process, and our instances take it:
    messages of instances FMPy made with its default callbacks must still be printed (on
    stderr: stdout may carry JSON)."""
    simulate(fmus["types2"])
    md = read_model_description(str(fmus["types2"]))
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(str(fmus["types2"]), str(tmp_path / "x")),
        modelIdentifier="types2",
        instanceName="plain",
    )
    slave.instantiate()
    try:
        with pytest.raises(FMICallException):
            slave.getBoolean([3])  # Booleans are 0..2: the FMU logs an error
    finally:
        slave.freeInstance()
    out, err = capsys.readouterr()
    assert "[Error] plain:" in err and out == ""


# ---- 6. simulate model.fmu --csv --json ---------------------------------------------------------


def test_simulate_an_fmu_writes_bare_names_and_strict_json(fmus, tmp_path):
    csv_path = tmp_path / "out.csv"
    done = CliRunner().invoke(
        app,
        [
            "simulate",
            str(fmus["types3"]),
            "--set",
            "int64_in=1099511627776",
            "--set",
            "bool_in=true",
            "--set",
            "string_in=a,b",
            "--set",
            "enum_in=3",
            "--stop-time",
            "0.5",
            "--step",
            "0.25",
            "--csv",
            str(csv_path),
            "--json",
        ],
    )
    assert done.exit_code == 0, done.output
    lines = csv_path.read_text().splitlines()
    names = [
        "float64_out",
        "float32_out",
        "int32_out",
        "steps",
        "int64_out",
        "uint16_out",
        "bool_out",
        "enum_out",
        "string_out",
    ]
    assert lines[0].split(",") == ["time", *names]
    assert lines[1:] == [
        f'{t:g},{t},0,{n},{n},{2**41 + n},{n},0,{(2 + n) % 3 + 1},"a,b!"'  # exact
        for n, t in enumerate((0, 0.25, 0.5))
    ]
    summary = strict_loads(done.stdout)
    assert summary["final"] == {
        "float64_out": 0.5,
        "float32_out": 0.0,
        "int32_out": 2.0,
        "steps": 2.0,
        "int64_out": 2.0**41 + 2,
        "uint16_out": 2.0,
        "bool_out": 0.0,
        "enum_out": 2.0,
        "string_out": "a,b!",
    }
    assert summary["values"]["types3.int64_in"] == 2**40 and summary["stop_time"] == 0.5
    assert json.loads(done.stdout) == summary


# ---- 7. conversions cost only where a connection needs them -------------------------------------


def captured_units(monkeypatch, path, **kwargs) -> dict[str, cosim._Unit]:
    """The prepared units the Python step loop gets, by instance (the native loop takes the same units)."""
    seen = {}
    original = cosim._step_loop

    def spy(units, *args):
        seen.update({u.stepper.name: u for u in units})
        return original(units, *args)

    monkeypatch.setattr(cosim, "_step_loop", spy)
    simulate(path, loop="python", **kwargs)
    return seen


def is_direct(feed) -> bool:
    """The direct filler: the signals array's own take straight into the
    ctypes buffer, no Python in between."""
    fill = feed.fill
    return (
        isinstance(fill, functools.partial)
        and getattr(fill.func, "__name__", "") == "take"
        and isinstance(getattr(fill.func, "__self__", None), np.ndarray)
    )


def test_real_and_boolean_to_real_feeds_are_a_direct_take(fmus, tmp_path, monkeypatch):
    path = write_multimodel(
        tmp_path,
        {"tank": fmus["tank"], "controller": fmus["controller"]},
        {"tank.level": ["controller.level"], "controller.valve": ["tank.valvecontrol"]},
    )
    units = captured_units(monkeypatch, path, stop_time=1.0, step=0.1)
    for name in ("tank", "controller"):
        (feed,) = units[name].feeds
        assert is_direct(feed) and feed.name == "fmi2SetReal"
        assert units[name].texts is None  # and no string exchange: the loop's plain path


def test_only_the_converting_feeds_do_more_than_a_take(pair, monkeypatch):
    path = pair(
        {
            "a.real_out": [
                {"input": "b.int_in", "round": True},
                {"input": "b.bool_in", "threshold": 1.5},
                "b.real_in",
            ],
            "a.int_out": ["c.float64_in"],
        }
    )
    units = captured_units(monkeypatch, path, stop_time=1.0, step=0.25)
    feeds = {feed.name: feed for feed in units["b"].feeds}
    assert set(feeds) == {"fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean"}
    assert is_direct(feeds["fmi2SetReal"])
    assert not is_direct(feeds["fmi2SetInteger"]) and not is_direct(feeds["fmi2SetBoolean"])
    (widening,) = units["c"].feeds
    assert is_direct(widening) and widening.name == "fmi3SetFloat64"
    assert units["a"].feeds == []
