"""FMUs built from our C sources: valid, self-contained, cached by source hash."""

from __future__ import annotations

import shutil
import zipfile

import pytest
from conftest import FMU_SOURCES, REPO
from fmpy.validation import validate_fmu

from dse_runner.simulation import build
from dse_runner.simulation.build import BuildError, build_fmu, find_source_dirs


@pytest.mark.parametrize("name", ["robotti_vehicle", "replay_controller"])
def test_built_fmu_is_valid_and_carries_its_sources(name):
    path = build_fmu(FMU_SOURCES / name)
    assert validate_fmu(str(path)) == []
    with zipfile.ZipFile(path) as fmu:
        names = set(fmu.namelist())
    assert {
        "modelDescription.xml",
        f"binaries/linux64/{name}.so",
        "sources/model.c",
        "sources/slave.c",
        "sources/slave.h",
        "sources/fmi2_common.c",
        "sources/fmi_common.c",
    } <= names
    # only the FMI 2.0 co-simulation layer and what it shares: the other layers
    # are neither compiled nor shipped
    assert not names & {
        "sources/slave3.c",
        "sources/slave3.h",
        "sources/me2.c",
        "sources/me2.h",
        "sources/fmi3_common.c",
        "sources/fmi3_common.h",
    }


def test_fmi3_description_builds_with_the_fmi3_layer():
    path = build_fmu(REPO / "tests" / "fmus" / "types3")
    assert validate_fmu(str(path)) == []
    with zipfile.ZipFile(path) as fmu:
        names = set(fmu.namelist())
    assert {
        "binaries/x86_64-linux/types3.so",
        "sources/model.c",
        "sources/slave3.c",
        "sources/slave3.h",
        "sources/fmi3_common.c",
        "sources/fmi_common.c",
    } <= names
    assert not names & {
        "binaries/linux64/types3.so",
        "sources/slave.c",
        "sources/me2.c",
        "sources/fmi2_common.c",
    }


ME_ONLY = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="{version}" modelName="me" {token}="{{5d0c7e58-1f8a-4f39-9a51-3c1b2e4d6f70}}">
  <ModelExchange modelIdentifier="me_only"/>
  <ModelVariables/>
  <ModelStructure/>
</fmiModelDescription>
"""


def me_only_source(tmp_path, version="2.0"):
    source = tmp_path / "fmus" / "me_only"
    source.mkdir(parents=True)
    token = "guid" if version == "2.0" else "instantiationToken"
    (source / "modelDescription.xml").write_text(ME_ONLY.format(version=version, token=token))
    (source / "model.c").write_text("/* nothing */\n")
    return source


def test_model_exchange_description_selects_the_me2_layer(tmp_path):
    source = me_only_source(tmp_path)
    assert build.layer_of(source) is build.ME2
    assert build.model_identifier(source) == "me_only"  # read from <ModelExchange>
    assert [p.name for p in build.source_files(source)][:3] == ["model.c", "me2.c", "me2.h"]


def test_missing_layer_is_a_clear_build_error(tmp_path, monkeypatch):
    source = me_only_source(tmp_path)
    package = tmp_path / "package"
    (package / "common").mkdir(parents=True)
    for name in ("slave.c", "slave.h"):
        shutil.copy(FMU_SOURCES / "common" / name, package / "common" / name)
    monkeypatch.setattr(build, "bundled_sources", lambda: package)
    with pytest.raises(BuildError, match=r"the shared FMI layer .*/common/me2\.c is missing"):
        build_fmu(source, tmp_path / "cache")


def test_fmi3_model_exchange_sources_get_the_fmi3_me_layer(tmp_path):
    from dse_runner.simulation import build

    assert build.layer_of(me_only_source(tmp_path, "3.0")) is build.ME3


def test_build_is_cached_by_source_hash(tmp_path):
    sources = tmp_path / "fmus"
    shutil.copytree(FMU_SOURCES, sources)
    cache = tmp_path / "cache"
    first = build_fmu(sources / "robotti_vehicle", cache)
    mtime = first.stat().st_mtime_ns
    assert build_fmu(sources / "robotti_vehicle", cache) == first
    assert first.stat().st_mtime_ns == mtime  # not rebuilt
    model = sources / "robotti_vehicle" / "model.c"
    model.write_text(model.read_text() + "\n/* an edit */\n")
    rebuilt = build_fmu(sources / "robotti_vehicle", cache)
    assert rebuilt != first and rebuilt.is_file()


def test_compile_error_is_reported(tmp_path):
    sources = tmp_path / "fmus"
    shutil.copytree(FMU_SOURCES, sources)
    model = sources / "robotti_vehicle" / "model.c"
    model.write_text(model.read_text().replace("static Bicycle bicycle_of", "static Bicycle oops bicycle_of"))
    with pytest.raises(BuildError, match=r"(?s)compiling robotti_vehicle failed:.*model\.c:\d+"):
        build_fmu(sources / "robotti_vehicle", tmp_path / "cache")


def test_source_folders_are_found():
    assert [p.name for p in find_source_dirs(FMU_SOURCES)] == [
        "path_controller",
        "replay_controller",
        "robotti_vehicle",
        "robotti_vehicle_effects",
    ]
