"""The FMUs built from our C sources beyond the Robotti ones: every FMI type in and out (FMI 2.0 and
3.0 layers), the water tank and its controller, and a PythonFMU-exported FMU for comparison.

The expected values are the functions documented in each model.c's header comment.
"""

from __future__ import annotations

import itertools
import math
import sysconfig
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from dse_runner.simulation.build import build_fmu

TYPES2 = REPO / "tests" / "fmus" / "types2"
TYPES3 = REPO / "tests" / "fmus" / "types3"
TANK = REPO / "jobs" / "watertank" / "fmus" / "tank"
CONTROLLER = REPO / "jobs" / "watertank" / "fmus" / "controller"

STEP = 0.25
TIMES = np.arange(5) * STEP  # 0 .. 1 s, the types FMUs' default experiment


class Instance:
    """An FMU instance driven by hand through FMPy's low-level API, by variable name."""

    def __init__(self, path: Path, tmp_path: Path, log: list | None = None):
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        unzipped = extract(str(path), unzipdir=str(tmp_path / f"{path.stem}-{len(list(tmp_path.iterdir()))}"))
        kind = FMU2Slave if self.md.fmiVersion == "2.0" else FMU3Slave
        self.fmu = kind(
            guid=self.md.guid,
            unzipDirectory=unzipped,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName="test",
        )
        if kind is FMU3Slave and log is not None:
            self.fmu.instantiate(logMessage=lambda env, status, category, text: log.append(text.decode()))
        else:
            self.fmu.instantiate()
        self.time = 0.0

    def set(self, kind: str, **values):
        getattr(self.fmu, f"set{kind}")([self.vr[n] for n in values], list(values.values()))

    def get(self, kind: str, *names):
        return getattr(self.fmu, f"get{kind}")([self.vr[n] for n in names])

    def initialize(self):
        self.time = 0.0
        if self.md.fmiVersion == "2.0":
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=0.0)
        self.fmu.exitInitializationMode()

    def step(self, h: float = STEP):
        self.fmu.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        self.time += h

    def close(self):
        self.fmu.freeInstance()


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    cache = tmp_path_factory.mktemp("fmus")
    return {p.name: build_fmu(p, cache) for p in (TYPES2, TYPES3, TANK, CONTROLLER)}


@pytest.mark.parametrize(
    "name, platform",
    [("types2", "linux64"), ("types3", "x86_64-linux"), ("tank", "linux64"), ("controller", "linux64")],
)
def test_fmu_builds_valid(built, name, platform):
    path = built[name]
    assert validate_fmu(str(path)) == []
    with zipfile.ZipFile(path) as fmu:
        assert f"binaries/{platform}/{name}.so" in fmu.namelist()


@pytest.mark.parametrize(
    "name, bounds",
    [
        ("types2", {"real_gain": ("0", "10"), "int_offset": ("-100", "100"), "enum_in": ("1", "3")}),
        ("types3", {"float64_gain": ("0", "10"), "int32_offset": ("-100", "100"), "enum_in": ("1", "3")}),
    ],
)
def test_types_declare_bounds(built, name, bounds):
    variables = {v.name: v for v in read_model_description(str(built[name])).modelVariables}
    assert {n: (variables[n].min, variables[n].max) for n in bounds} == bounds


def test_types2_outputs(built):
    result = simulate_fmu(
        str(built["types2"]),
        stop_time=1.0,
        output_interval=STEP,
        start_values={
            "real_in": 1.5,
            "real_gain": 3.0,
            "int_in": 3,
            "int_offset": 10,
            "enum_in": 2,
            "bool_in": True,
            "string_in": "ab",
        },
    )
    n = np.arange(len(TIMES))
    assert np.allclose(result["time"], TIMES)
    assert np.allclose(result["real_out"], 3.0 * 1.5 + TIMES, rtol=0, atol=1e-12)
    assert list(result["int_out"]) == list(3 + 10 + n)
    assert list(result["steps"]) == list(n)
    assert list(result["enum_out"]) == list((2 - 1 + n) % 3 + 1)
    assert list(result["bool_out"]) == [False] * len(n)  # invert defaults to true: not bool_in


def test_types2_strings_booleans_and_reset(built, tmp_path):
    fmu = Instance(built["types2"], tmp_path)
    try:
        fmu.set("String", string_in="ab", suffix="?")
        fmu.set("Boolean", bool_in=True, invert=False)
        fmu.set("Integer", int_in=-7)
        fmu.initialize()
        assert fmu.get("String", "string_out") == [b"ab?"]
        assert fmu.get("Boolean", "bool_out") == [True]
        fmu.step()
        fmu.step()
        assert fmu.get("Integer", "int_out", "steps", "enum_out") == [-7 + 2, 2, 3]
        fmu.fmu.terminate()
        fmu.fmu.reset()  # back to the start values of every type
        assert fmu.get("Integer", "int_in", "int_offset", "steps", "enum_in") == [0, 0, 0, 1]
        assert fmu.get("Boolean", "bool_in", "invert") == [False, True]
        assert fmu.get("String", "string_in", "suffix") == [b"", b"!"]
    finally:
        fmu.close()


def test_types2_rejects_unknown_references(built, tmp_path):
    fmu = Instance(built["types2"], tmp_path)
    try:
        with pytest.raises(FMICallException):
            fmu.fmu.getBoolean([3])  # Booleans are 0..2
    finally:
        fmu.close()


def test_types3_outputs(built):
    result = simulate_fmu(
        str(built["types3"]),
        stop_time=1.0,
        output_interval=STEP,
        start_values={
            "float64_in": 1.5,
            "float64_gain": 3.0,
            "float32_in": 3.0,
            "int32_in": 3,
            "int32_offset": 10,
            "int64_in": 2**40,
            "uint16_in": 65535,
            "bool_in": True,
            "string_in": "ab",
            "enum_in": 2,
        },
    )
    n = np.arange(len(TIMES))
    assert np.allclose(result["time"], TIMES)
    assert np.allclose(result["float64_out"], 3.0 * 1.5 + TIMES, rtol=0, atol=1e-12)
    assert result["float32_out"].dtype == np.float32 and list(result["float32_out"]) == [1.5] * len(n)
    assert list(result["int32_out"]) == list(3 + 10 + n)
    assert list(result["steps"]) == list(n)
    assert result["int64_out"].dtype == np.int64 and list(result["int64_out"]) == [2**41 + k for k in n]
    assert list(result["uint16_out"]) == [65535, 0, 1, 2, 3]  # wraps
    assert list(result["bool_out"]) == [False] * len(n)
    assert list(result["enum_out"]) == list((2 - 1 + n) % 3 + 1)


def test_types3_strings_time_and_reset(built, tmp_path):
    fmu = Instance(built["types3"], tmp_path)
    try:
        fmu.set("String", string_in="ab", suffix="?")
        fmu.initialize()
        assert fmu.get("String", "string_out") == ["ab?"]
        fmu.step(0.5)
        assert fmu.get("Float64", "time") == [0.5]
        assert fmu.get("Int64", "enum_out") == [2]
        fmu.fmu.terminate()
        fmu.fmu.reset()
        assert fmu.get("String", "string_in", "suffix") == ["", "!"]
        assert fmu.get("Float64", "float64_gain") == [2.0]
        assert fmu.get("Boolean", "invert") == [True]
    finally:
        fmu.close()


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda f: f.fmu.getInt32([1]), "fmi3GetInt32: value reference 1 is a Float64 variable"),
        (lambda f: f.fmu.getFloat64([99]), "fmi3GetFloat64: unknown value reference 99"),
        (lambda f: f.fmu.setFloat64([0], [1.0]), "value reference 0 is the independent variable (time)"),
        (lambda f: f.fmu.enterEventMode(), "fmi3EnterEventMode is not supported by this FMU"),
        (lambda f: f.fmu.getBinary([1]), "fmi3GetBinary is not supported by this FMU"),
    ],
)
def test_types3_refuses_with_a_message(built, tmp_path, call, message):
    log: list[str] = []
    fmu = Instance(built["types3"], tmp_path, log)
    try:
        with pytest.raises(FMICallException):
            call(fmu)
        assert message in log[-1]
    finally:
        fmu.close()


# ---- water tank ---------------------------------------------------------------


def test_tank_fills_with_the_valve_closed(built):
    result = simulate_fmu(
        str(built["tank"]), stop_time=10.0, output_interval=0.5, start_values={"valvecontrol": 0.0}
    )
    assert np.allclose(result["level"], 0.5 + 0.2 * result["time"], rtol=0, atol=1e-9)


def test_tank_drains_exponentially_with_the_valve_open(built):
    result = simulate_fmu(
        str(built["tank"]),
        stop_time=10.0,
        output_interval=0.5,
        start_values={"valvecontrol": 1.0, "initial_level": 2.0},
    )
    # area * dl/dt = inflow - k * l: relaxes towards inflow / k = 0.5 m at rate k / area = 0.4 / s
    expected = 0.5 + 1.5 * np.exp(-0.4 * result["time"])
    assert np.allclose(result["level"], expected, rtol=0, atol=1e-9)


def test_controller_switches_with_hysteresis(built):
    # a level going 0.05 -> 3.05 -> 0.05 -> 3.05 m, so no communication point lands on a threshold
    ramp = np.array(
        [(0.0, 0.05), (3.0, 3.05), (6.0, 0.05), (9.0, 3.05)], dtype=[("time", float), ("level", float)]
    )
    result = simulate_fmu(
        str(built["controller"]), stop_time=9.0, output_interval=0.1, input=ramp, output=["valve"]
    )
    valve = [bool(v) for v in result["valve"]]
    assert not valve[0]  # starts closed
    # The level read at the start of a step decides the valve at its end.
    levels = np.interp(result["time"], ramp["time"], ramp["level"])
    for k in range(len(valve) - 1):
        expected = True if levels[k] >= 2.0 else False if levels[k] <= 1.0 else valve[k]
        assert valve[k + 1] == expected, f"t={result['time'][k + 1]}"
    toggles = sum(a != b for a, b in itertools.pairwise(valve))
    assert toggles == 3  # opens at 2 m rising, closes at 1 m falling, opens again


def test_tank_and_controller_oscillate_between_the_thresholds(built, tmp_path):
    tank, controller = Instance(built["tank"], tmp_path), Instance(built["controller"], tmp_path)
    try:
        tank.initialize()
        controller.initialize()
        levels, valves = [], []
        for _ in range(300):  # 30 s in steps of 0.1 s, Boolean valve wired to Real valvecontrol as 0/1
            (level,) = tank.get("Real", "level")
            (valve,) = controller.get("Boolean", "valve")
            levels.append(level)
            valves.append(bool(valve))
            controller.set("Real", level=level)
            tank.set("Real", valvecontrol=1.0 if valve else 0.0)
            tank.step(0.1)
            controller.step(0.1)
    finally:
        tank.close()
        controller.close()
    openings = sum(1 for a, b in itertools.pairwise(valves) if b and not a)
    assert openings >= 3
    after_first_fill = levels[levels.index(next(x for x in levels if x >= 2.0)) :]
    # one step of controller delay lets the level pass a threshold by at most a step's change
    assert 1.0 - 0.1 < min(after_first_fill) and max(after_first_fill) < 2.0 + 0.05
    assert math.isclose(levels[0], 0.5)


# ---- PythonFMU ------------------------------------------------------------------


def test_pythonfmu_slave_runs_in_process(tmp_path):
    pytest.importorskip("pythonfmu")
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        pytest.skip("PythonFMU's binary needs a Python built with a shared libpython")
    from pythonfmu_models import build_pythonfmu

    path = build_pythonfmu(tmp_path / "built")
    assert validate_fmu(str(path)) == []
    result = simulate_fmu(
        str(path),
        stop_time=1.0,
        output_interval=STEP,
        start_values={
            "real_in": 1.5,
            "gain": 3.0,
            "int_in": 3,
            "offset": 10,
            "bool_in": True,
            "string_in": "ab",
        },
    )
    n = np.arange(len(TIMES))
    # outputs keep their start values until the first step
    assert np.allclose(result["real_out"], np.where(n > 0, 4.5 + TIMES, 0.0), rtol=0, atol=1e-12)
    assert list(result["int_out"]) == [0] + [13 + k for k in n[1:]]
    assert list(result["bool_out"]) == [False] * len(n)

    fmu = Instance(path, tmp_path)
    try:
        fmu.set("String", string_in="ab", suffix="?")
        fmu.set("Boolean", bool_in=True, invert=False)
        fmu.initialize()
        fmu.step()
        assert fmu.get("String", "string_out") == [b"ab?"]
        assert fmu.get("Boolean", "bool_out") == [True]
        fmu.fmu.terminate()
    finally:
        fmu.close()
