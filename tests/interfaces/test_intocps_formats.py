"""INTO-CPS's three files read as they are (issue 15's first step): shapes INTO-CPS writes, and
errors that name the file and key."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dse_runner.errors import DseError
from dse_runner.interfaces.intocps.formats import (
    CoeConfig,
    DseConfig,
    FixedStep,
    VariableStep,
    read,
)
from dse_runner.simulation.multimodel import split_into_cps_id


def write(folder: Path, name: str, data) -> Path:
    path = folder / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def test_a_dse_config_with_every_field_reads(tmp_path):
    dse = read(
        write(
            tmp_path,
            "levels.dse.json",
            {
                "algorithm": {"type": "genetic", "initialPopulation": 10, "mutationProbability": 20},
                "objectiveConstraints": {},
                "objectiveDefinitions": {
                    "externalScripts": {
                        "settle": {
                            "scriptFile": "settle.py",
                            "scriptParameters": {"1": "time", "2": "{tank}.tank.level", "3": 0.05},
                        }
                    },
                    "internalFunctions": {"peak": {"columnID": "{tank}.tank.level", "objectiveType": "max"}},
                },
                "parameterConstraints": ["{ctrl}.ctrl.maxlevel > {ctrl}.ctrl.minlevel"],
                "parameters": {"{ctrl}.ctrl.minlevel": [1, 1.5], "{ctrl}.ctrl.maxlevel": [2.0, 2.5]},
                "ranking": {"pareto": {"peak": "-", "settle": "+"}},
                "scenarios": [""],
                "simulation": {"startTime": "0", "endTime": "30"},  # INTO-CPS ignores it; so do we
            },
        ),
        DseConfig,
    )
    assert dse.algorithm.type == "genetic" and dse.algorithm.options == {
        "initialPopulation": 10,
        "mutationProbability": 20,
    }
    assert dse.objectiveConstraints == []
    assert dse.objectiveDefinitions.externalScripts["settle"].scriptParameters == {
        "1": "time",
        "2": "{tank}.tank.level",
        "3": "0.05",
    }  # text, as on INTO-CPS's command line
    assert dse.ranking["pareto"] == {"peak": "-", "settle": "+"}
    assert (
        read(
            write(tmp_path, "old.dse.json", {"algorithm": {}, "parameters": {"{a}.a.k": [1]}}), DseConfig
        ).algorithm.type
        == "exhaustive"
    )


def test_coe_configs_read(tmp_path):
    fixed = read(
        write(
            tmp_path,
            "a.coe.json",
            {
                "startTime": 0,
                "endTime": 30,
                "multimodel_path": "Multi-models/wt/wt.mm.json",
                "algorithm": {"type": "fixed-step", "size": 0.1},
                "visible": False,
            },
        ),
        CoeConfig,
    )
    assert isinstance(fixed.algorithm, FixedStep) and fixed.algorithm.size == 0.1 and fixed.endTime == 30
    variable = read(
        write(
            tmp_path,
            "b.coe.json",
            {
                "endTime": 10,
                "algorithm": {
                    "type": "var-step",
                    "initsize": 0.1,
                    "size": [1e-6, 2],
                    "constraints": {"max": {"type": "fmumaxstepsize"}},
                },
            },
        ),
        CoeConfig,
    )
    assert isinstance(variable.algorithm, VariableStep) and variable.multimodel_path is None


def test_ids_split_into_fmu_instance_and_variable():
    assert split_into_cps_id("{bodyFMU}.body.Demux.robot_x") == ("{bodyFMU}", "body", "Demux.robot_x")
    with pytest.raises(DseError, match=r"'body\.robot_x' is not of the form \{fmu\}\.instance\.variable"):
        split_into_cps_id("body.robot_x")


@pytest.mark.parametrize(
    ("name", "text", "model", "message"),
    [
        (
            "bad.dse.json",
            '{"parameters": {"{a}.a.k": [1],}}',
            DseConfig,
            r"bad\.dse\.json line 1, column \d+: not JSON",
        ),
        (
            "bad.dse.json",
            {"parameters": {"{a}.a.k": []}},
            DseConfig,
            r"bad\.dse\.json: parameters\.\{a\}\.a\.k",
        ),
        (
            "bad.dse.json",
            {"parameters": {"{a}.a.k": [1, {"value": 2}]}},
            DseConfig,
            (
                r"bad\.dse\.json: parameters\.\{a\}\.a\.k\.1: expected "
                r"a number, a Boolean or a string, not a mapping$"
            ),
        ),
        (
            "bad.dse.json",
            {"parameters": {"{a}.a.k": [1]}, "ranking": {"pareto": {"x": "min"}}},
            DseConfig,
            r"ranking\.pareto\.x",
        ),
        (
            "bad.coe.json",
            {"endTime": 1, "algorithm": {"type": "jacobi"}},
            CoeConfig,
            r"bad\.coe\.json: algorithm: expected \{type: fixed-step, size\}",
        ),
    ],
)
def test_bad_files_name_the_file_and_key(tmp_path, name, text, model, message):
    with pytest.raises(DseError, match=message):
        read(write(tmp_path, name, text), model)
    with pytest.raises(DseError, match=r"cannot read .*missing\.dse\.json"):
        read(tmp_path / "missing.dse.json", DseConfig)


def test_paths_written_on_windows_read_with_slashes(tmp_path):
    """A project made on Windows: its scriptFile and multimodel_path use backslashes."""
    dse = read(
        write(
            tmp_path,
            "a.dse.json",
            {
                "parameters": {"{c}.c.x": [1]},
                "objectiveDefinitions": {"externalScripts": {"s": {"scriptFile": "metrics\\settle.py"}}},
            },
        ),
        DseConfig,
    )
    assert dse.objectiveDefinitions.externalScripts["s"].scriptFile == "metrics/settle.py"
    coe = read(
        write(
            tmp_path,
            "coe.json",
            {
                "endTime": 10,
                "algorithm": {"type": "fixed-step", "size": 0.001},
                "multimodel_path": "Multi-models\\Stability\\mm.json",
            },
        ),
        CoeConfig,
    )
    assert coe.multimodel_path == "Multi-models/Stability/mm.json"
