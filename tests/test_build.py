"""FMUs built from our C sources: valid, self-contained, cached by source hash."""

from __future__ import annotations

import shutil
import zipfile

import pytest
from conftest import FMU_SOURCES
from fmpy.validation import validate_fmu

from dse_runner.build import BuildError, build_fmu, find_source_dirs


@pytest.mark.parametrize("name", ["robotti_vehicle", "replay_controller"])
def test_built_fmu_is_valid_and_carries_its_sources(name):
    path = build_fmu(FMU_SOURCES / name)
    assert validate_fmu(str(path)) == []
    with zipfile.ZipFile(path) as fmu:
        names = set(fmu.namelist())
    assert {"modelDescription.xml", f"binaries/linux64/{name}.so", "sources/model.c",
            "sources/slave.c", "sources/slave.h"} <= names


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
    assert [p.name for p in find_source_dirs(FMU_SOURCES)] == ["replay_controller", "robotti_vehicle", "robotti_vehicle_effects"]
