"""INTO-CPS's result files as its users' scripts read them: ranking.json with json.load, dseResults.csv
with csv.DictReader, results.html as a page, graphs/pareto.png as an image (issue 15)."""

from __future__ import annotations

import csv
import json
import xml.etree.ElementTree as ET
from collections import OrderedDict

import pandas as pd
import pytest

from dse_runner.interfaces.intocps.results import write_results

# Listed as a DSE config might list them: not in id order, so every sorted order below is a real check.
PARAMETERS = {"tank.area": "{tank}.tank.area", "ctrl.gain": "{ctrl}.ctrl.gain"}
FIXED = {"{plant}.plant.mass": 3000}
OBJECTIVES = ["time", "energy"]  # not alphabetical either

# (time, energy), both minimised: A, B, C and D (B's twin) are non-dominated; E is dominated by B and D;
# F only by E and those before it. simDirs are gain_area (ids sorted: {ctrl} before {tank}).
POINTS = pd.DataFrame(
    {
        "tank.area": [2.0, 1.5, 1.0, 0.5, 2.5, 3.0],
        "ctrl.gain": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
        "time": [1.0, 2.0, 3.0, 2.0, 3.0, 4.0],
        "energy": [5.0, 3.0, 1.0, 3.0, 4.0, 5.0],
    },
    index=list("ABCDEF"),
)
DIR = {"A": "0.1_2.0", "B": "0.2_1.5", "C": "0.3_1.0", "D": "0.4_0.5", "E": "0.5_2.5", "F": "0.6_3.0"}


def dirs(letters: str) -> list[str]:
    return [DIR[k] for k in letters]


def write(folder, pareto, **kwargs):
    return write_results(folder, POINTS, PARAMETERS, OBJECTIVES, pareto, fixed=FIXED, **kwargs)


def fronts(paths) -> dict[str, list[str]]:
    return json.loads(paths["ranking"].read_text())["pareto"]


def csv_rows(paths) -> list[list[str]]:
    with paths["csv"].open(newline="") as file:
        return list(csv.reader(file))


def test_ranking_json_and_csv_of_two_minimised_objectives(tmp_path):
    paths = write(tmp_path / "2017_07_05_14.03.22", [("time", "min"), ("energy", "min")])
    assert set(paths) == {"csv", "html", "ranking", "graph"} and all(p.is_file() for p in paths.values())

    with paths["ranking"].open() as file:
        ranking = json.load(file)
    # Within a front, best time first; B and D tie, and keep the order they came in.
    assert ranking == {
        "pareto": {"1": dirs("ABDC"), "2": dirs("E"), "3": dirs("F")},
        "simulations": dirs("ABCDEF"),
        "unrankable": [],
    }
    assert paths["ranking"].read_text() == json.dumps(ranking, sort_keys=True, indent=4)

    text = paths["csv"].read_text()
    assert "\r" not in text and text.endswith("\n")
    with paths["csv"].open(newline="") as file:
        reader = csv.DictReader(file)
        rows = list(reader)
    # Objectives alphabetical, then every mm parameter (the fixed one too) by sorted id, trimmed.
    assert reader.fieldnames == ["Rank", "energy", "time", "ctrl.gain", "plant.mass", "tank.area"]
    assert [r["Rank"] for r in rows] == ["1", "1", "1", "1", "2", "3"]
    assert [r["ctrl.gain"] for r in rows] == ["0.1", "0.2", "0.4", "0.3", "0.5", "0.6"]
    assert rows[0] == {
        "Rank": "1",
        "energy": "5.0",
        "time": "1.0",
        "ctrl.gain": "0.1",
        "plant.mass": "3000",
        "tank.area": "2.0",
    }


def test_maximising_both_objectives_turns_the_fronts_round(tmp_path):
    paths = write(tmp_path, [("time", "max"), ("energy", "max")])
    # F beats everything; then E and A (best time first); then C, B and D.
    assert fronts(paths) == {"1": dirs("F"), "2": dirs("EA"), "3": dirs("CBD")}
    assert [r[0] for r in csv_rows(paths)[1:]] == ["1", "2", "2", "3", "3", "3"]


def test_the_html_table_is_the_csv(tmp_path):
    fixed = {**FIXED, "{plant}.plant.label": "heavy <A&B>"}  # a String parameter: text to escape
    paths = write_results(
        tmp_path, POINTS, PARAMETERS, OBJECTIVES, [("time", "min"), ("energy", "min")], fixed
    )
    text = paths["html"].read_text()
    assert text.startswith('<!DOCTYPE html PUBLIC "-//W3C//DTD XHTML 1.0 Strict//EN"')
    page = ET.fromstring(text)  # well-formed XHTML, so every row is closed
    ns = {"h": "http://www.w3.org/1999/xhtml"}
    assert page.findtext("h:head/h:title", namespaces=ns) == "DSE Results Page"
    assert page.find("h:head/h:style", ns).text.strip()
    assert page.findtext("h:body/h:h1", namespaces=ns) == "pareto"
    assert page.find(".//h:img", ns).get("src") == "graphs/pareto.png"
    table = [[cell.text for cell in tr] for tr in page.iterfind(".//h:table/h:tr", ns)]
    assert table == csv_rows(paths) and len(table) == 1 + len(POINTS)
    assert table[0][4] == "plant.label" and table[1][4] == "heavy <A&B>"
    assert [cell.tag for cell in page.find(".//h:table/h:tr", ns)] == [f"{{{ns['h']}}}th"] * 7


def test_the_graph_is_a_png(tmp_path):
    paths = write(tmp_path, [("time", "min"), ("energy", "min")])
    assert paths["graph"] == tmp_path / "graphs" / "pareto.png"
    data = paths["graph"].read_bytes()
    assert data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) > 1000


def test_unrankable_designs_are_only_in_ranking_json(tmp_path):
    failed = pd.DataFrame({"tank.area": [9.0, 8.0], "ctrl.gain": [0.9, 0.8]})
    paths = write(tmp_path, [("time", "min"), ("energy", "min")], unrankable=failed)
    ranking = json.loads(paths["ranking"].read_text())
    assert ranking["unrankable"] == ["0.9_9.0", "0.8_8.0"]
    # As in INTO-CPS, "simulations" lists every design run, the failed ones too; no front has them.
    assert ranking["simulations"] == dirs("ABCDEF") + ["0.9_9.0", "0.8_8.0"]
    assert [d for front in ranking["pareto"].values() for d in front] == dirs("ABDC") + dirs("EF")
    assert len(csv_rows(paths)) == 1 + len(POINTS)
    page = paths["html"].read_text()
    assert "0.9" not in page and "9.0" not in page and "0.9" not in paths["csv"].read_text()


def test_one_pareto_objective_ranks_by_its_values(tmp_path):
    paths = write(tmp_path, [("energy", "min")])
    assert fronts(paths) == {"1": dirs("C"), "2": dirs("BD"), "3": dirs("E"), "4": dirs("AF")}
    assert paths["graph"].read_bytes().startswith(b"\x89PNG")


def test_no_pareto_objective_ranks_by_the_first_objective_minimised(tmp_path):
    paths = write(tmp_path, [])
    assert fronts(paths) == {"1": dirs("A"), "2": dirs("BD"), "3": dirs("CE"), "4": dirs("F")}
    assert csv_rows(paths)[0] == ["Rank", "energy", "time", "ctrl.gain", "plant.mass", "tank.area"]
    assert paths["graph"].read_bytes().startswith(b"\x89PNG")


def test_ranks_past_nine_stay_in_numeric_order(tmp_path):
    points = pd.DataFrame({"ctrl.gain": [float(i) for i in range(11, 0, -1)], "cost": range(11, 0, -1)})
    paths = write_results(tmp_path, points, {"ctrl.gain": "{c}.ctrl.gain"}, ["cost"], [("cost", "min")])
    with paths["ranking"].open() as file:
        ranks = json.load(file, object_pairs_hook=OrderedDict)["pareto"]
    assert list(ranks) == [str(n) for n in range(1, 12)] and ranks["1"] == ["1.0"] and ranks["11"] == ["11.0"]
    assert [r[0] for r in csv_rows(paths)[1:]] == [str(n) for n in range(1, 12)]


def test_a_nan_objective_is_refused_before_anything_is_written(tmp_path):
    points = POINTS.assign(energy=[5.0, None, 1.0, 3.0, 4.0, 5.0])
    with pytest.raises(ValueError, match="'energy'"):
        write_results(tmp_path / "out", points, PARAMETERS, OBJECTIVES, [("time", "min"), ("energy", "min")])
    assert not (tmp_path / "out").exists()
