"""Jigs: a cell element that holds a wing. A one-arm program that folds one crease of a straight
letter fold leaves the other wing free and is refused; with the cell's jig holding that wing the
same program is proven held in every state, the jig's footprint lies on the face it holds, and
only that face may touch the jig's body."""
from __future__ import annotations

import functools
import json
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from refold_panels import letter_fold_pair

from fabkit.cli import main
from fabkit.errors import InputError
from robot.cell import load_cell, parse_cell
from robot.toolpath import Toolpath

ROOT = Path(__file__).resolve().parent.parent
JIG_CELL = str(ROOT / "cells" / "ur10e_jig.toml")


def first_phase_fold(path: Path) -> Path:
    """A 0.6 m x 0.2 m letter fold clamped on its middle strip, refolded crease 1 first, cut after
    that phase: crease 0 (a straight crease) stays flat, so nothing but a hold on strip 0 fixes it."""
    from fabkit.io.fold import save_fold
    from fabkit.refold import refold
    from fabkit.refold.export import to_fold_model

    flat, target = letter_fold_pair(np.radians(90), nx=6, ny=2, size=0.6)
    fcol = np.repeat(np.arange(6), 2)
    middle = ((flat.face_data["column"] == 1) & np.isin(fcol, [0, 2, 5])).astype(np.int64)
    flat.face_data["middle"] = target.face_data["middle"] = middle
    seq = refold(flat, target, frames=4, steps="crease1,crease0", fixed_face=5)
    model = to_fold_model(seq)
    first = int(np.flatnonzero(np.asarray(seq.step) == 1)[0])
    save_fold(replace(model, frames=model.frames[:first]), path)
    return path


@functools.lru_cache(maxsize=None)
def planned_jig_program() -> tuple[Path, Path]:
    """(FOLD file, PATH.json) of the first phase planned by `fabkit toolpath` in the jig cell (once
    per test process: the picture tests use it too)."""
    d = Path(tempfile.mkdtemp(prefix="fabkit_jig_"))
    fold = first_phase_fold(d / "phase1.fold")
    path = d / "path.json"
    assert main(["toolpath", str(fold), "--cell", JIG_CELL, "-o", str(path), "--approach", "0.1", "-q"]) == 0
    return fold, path


@pytest.fixture(scope="module")
def jig_program():
    return planned_jig_program()


def without_jigs(tp: Toolpath) -> Toolpath:
    holds = {k: v for k, v in tp.extra["holds"].items() if k != "jigs"}
    return Toolpath(tp.robot, tp.cell, tp.tcp, tp.source, tp.waypoints, {**tp.extra, "holds": holds}, tp.cell_sha256)


@pytest.fixture(scope="module")
def checked(jig_program):
    """The CHECK.json of the program without its jig rows ("free") and as planned ("jig")."""
    from sim.check import check_toolpath

    fold, path = jig_program
    cell = load_cell(JIG_CELL)
    return {name: check_toolpath(tp, cell, fold=fold)
            for name, tp in (("free", without_jigs(Toolpath.load(path))), ("jig", Toolpath.load(path)))}


def test_path_json_names_the_jig_and_the_face_it_holds(jig_program):
    _, path = jig_program
    doc = json.loads(path.read_text())
    row = doc["holds"]["jigs"]["wing_pad"]
    assert len(row) == len(doc["waypoints"]) and set(row) == {1}   # face 1 (strip 0) lies on the pad throughout
    assert doc["holds"]["clamped_faces"] == [5]


def test_the_program_without_the_jig_is_refused_naming_the_free_crease(checked):
    rep = checked["free"]
    holds = [p for p in rep.problems if p.kind == "holds"]
    assert holds and {p.subject for p in holds} >= {"crease 0"}
    assert "is folded by nothing held" in holds[0].detail
    # the face is not held, so it may not lie on the jig's body either
    assert "jig_checks" not in rep.holds


def test_the_same_program_with_the_jig_holds_in_every_state(jig_program, tmp_path):
    fold, path = jig_program
    out = tmp_path / "check.json"
    assert main(["check", str(path), "--cell", JIG_CELL, "-o", str(out), "-q"]) == 0
    rep = json.loads(out.read_text())
    assert rep["ok"] and rep["holds"]["ok"]
    states = rep["holds"]["states"]
    assert len(states) == 7 and all(s["ok"] and 1 in s["held_faces"] for s in states)
    assert all(s["nullity"] == 0 for s in states if not s["flat"])
    jig = rep["holds"]["jig_checks"]["wing_pad"]
    assert jig["ok"] and jig["spans"][0]["face"] == 1 and jig["spans"][0]["footprint_outside_m"] == 0.0
    # the held face rests on the jig's body (the pad top at the sheet's mid-plane: half the 1 mm sheet deep)
    rest = rep["panel_collisions"]["resting_on_jig"]
    assert [r["pair"] for r in rest] == [["face_1", "wing_pad_post"]]
    assert rest[0]["depth_m"] == pytest.approx(5e-4, abs=1e-6)


def test_a_jig_beside_the_face_it_claims_is_refused(jig_program):
    """Moved 70 mm along the panel the pad lies on face 3 (the next column): its farthest corner is
    40 mm off face 1, the face the program says the jig holds."""
    from robot.cell import Jig
    from sim.check import check_toolpath

    fold, path = jig_program
    cell = load_cell(JIG_CELL)
    jig = cell.jigs[0]
    moved = jig.pose.copy()
    moved[1, 3] += 0.07
    other = replace(cell, jigs=(Jig(jig.name, moved, jig.footprint, ""),))
    rep = check_toolpath(Toolpath.load(path), other, fold=fold)
    bad = [p for p in rep.problems if p.subject == "jig wing_pad"]
    assert len(bad) == 1 and "leaves face 1" in bad[0].detail and bad[0].value == pytest.approx(0.04, abs=1e-9)


def test_another_face_on_the_jig_body_is_a_collision(jig_program):
    """A jig row naming another face than the one on the pad: the footprint check fails, and face 1
    lying on the post is no longer exempt."""
    from sim.check import check_toolpath

    fold, path = jig_program
    tp = Toolpath.load(path)
    holds = dict(tp.extra["holds"])
    holds["jigs"] = {"wing_pad": [3 if f is not None else None for f in holds["jigs"]["wing_pad"]]}
    tp = Toolpath(tp.robot, tp.cell, tp.tcp, tp.source, tp.waypoints, {**tp.extra, "holds": holds}, tp.cell_sha256)
    rep = check_toolpath(tp, load_cell(JIG_CELL), fold=fold)
    kinds = {(p.kind, p.subject) for p in rep.problems}
    assert ("holds", "jig wing_pad") in kinds and ("panel_collision", "face_1 × wing_pad_post") in kinds


def test_jig_table_is_validated_naming_the_key():
    import tomllib

    data = tomllib.loads(Path(JIG_CELL).read_text())
    bad = json.loads(json.dumps(data))
    bad["jigs"][0]["obstacle"] = "nowhere"
    with pytest.raises(InputError, match=r"jigs\[0\]\.obstacle: 'nowhere' is not one of the cell's obstacles"):
        parse_cell(bad, "x.toml")
    bad = json.loads(json.dumps(data))
    bad["jigs"][0]["footprint"] = [[0, 0], [1, 0]]
    with pytest.raises(InputError, match=r"jigs\[0\]\.footprint: expected a polygon"):
        parse_cell(bad, "x.toml")
    bad = json.loads(json.dumps(data))
    bad["jigs"].append(dict(bad["jigs"][0]))
    with pytest.raises(InputError, match=r"jigs\[1\]\.name: 'wing_pad' is used twice"):
        parse_cell(bad, "x.toml")
    bad = json.loads(json.dumps(data))
    bad["jigs"][0]["colour"] = "red"
    with pytest.raises(InputError, match=r"jigs\[0\]\.colour: unknown key"):
        parse_cell(bad, "x.toml")


@pytest.mark.skipif(__import__("browser").chromium() is None, reason="Debian chromium not installed")
def test_report_html_says_what_folds_each_crease(checked, tmp_path):
    """The page as the browser built it: per crease the holds on each side, per state the faces held."""
    from browser import dump_dom, table_rows

    pages = {}
    for name, rep in checked.items():
        d = tmp_path / name
        d.mkdir()
        (d / "check.json").write_text(json.dumps(rep.to_json()))
        assert main(["report", str(d), "-q"]) == 0
        dom = dump_dom(d / "report.html")
        pages[name] = (table_rows(dom, "What folds each crease"), table_rows(dom, "Held faces per fold state"))
    creases, states = pages["free"]
    assert creases[0] == ["crease", "waypoints", "fold states", "one side", "other side", "verdict"]
    by_crease = {r[0]: r for r in creases[1:]}
    assert by_crease["0"][3] == "faces 0–3: nothing" and by_crease["0"][5] == "FREE: faces 0–3 held by nothing"
    assert by_crease["1"][5] == "folded 0.0° → 90.0° between clamp face 5 and arm a face 11"
    assert states[0] == ["fold state", "waypoints", "clamp", "arm a", "holds proven", "nullity", "sigma_min"]
    assert all(r[4].startswith("no: crease 0") for r in states[1:])
    creases, states = pages["jig"]
    by_crease = {r[0]: r for r in creases[1:]}
    assert by_crease["0"][3] == "faces 0–3: jig wing_pad face 1"
    assert by_crease["0"][5] == "held at 0.0° between jig wing_pad face 1 and clamp face 5 + arm a face 11"
    assert by_crease["1"][5] == "folded 0.0° → 90.0° between clamp face 5 + jig wing_pad face 1 and arm a face 11"
    assert states[0][2:5] == ["clamp", "arm a", "jig wing_pad"]
    assert len(states) == 8 and all(r[2:5] == ["5", "11", "1"] and r[5].startswith("yes") for r in states[1:])


def test_a_malformed_jig_row_is_refused_naming_the_key():
    from robot.holds_record import holds_of

    good = {"clamped_faces": [5], "arms": {"a": [None, 11, None]}}
    assert holds_of({"holds": {**good, "jigs": {"pad": [1, 1, None]}}}, 3)["jigs"] == {"pad": [1, 1, None]}
    with pytest.raises(ValueError, match=r"holds\.jigs\.pad: expected one entry per waypoint \(3\)"):
        holds_of({"holds": {**good, "jigs": {"pad": [1]}}}, 3)
    with pytest.raises(ValueError, match=r"holds\.jigs\.pad: expected face ids or null"):
        holds_of({"holds": {**good, "jigs": {"pad": [1, -2, None]}}}, 3)
    with pytest.raises(ValueError, match=r"holds\.jigs: expected"):
        holds_of({"holds": {**good, "jigs": [1, 2, 3]}}, 3)
