"""Holds in PATH.json and the check: the planner records what each arm holds at every waypoint and
the clamped faces; `fabkit check` proves the holds in every state the panel moves through and
refuses a program that leaves a crease free, naming it."""
from __future__ import annotations

import json

import pytest
from refold_panels import reflect_pair

import fabkit.pipeline as fk
from fabkit.cli import main
from fabkit.io.obj import save_obj
from robot.toolpath import Toolpath

from pathlib import Path

CELL = str(Path(__file__).resolve().parent.parent / "cells" / "ur5e_bench.toml")


@pytest.fixture(scope="module")
def trifold_flat():
    return fk.unfold(fk.relax(fk.generate("trifold")))


@pytest.fixture(scope="module")
def trifold_program(tmp_path_factory, trifold_flat):
    """The old demo program: the tri-fold clamped on its middle strip, one grip on a wing."""
    import numpy as np

    data = trifold_flat.mesh.face_data
    middle = int(np.flatnonzero((np.asarray(data["middle"]) != 0) & (np.asarray(data["strip"]) == 1))[0])
    folds = fk.refold(trifold_flat, frames=8, fixed_face=middle)
    prog = fk.plan(folds, CELL, workdir=tmp_path_factory.mktemp("tri"))
    assert prog.ok, prog.problems
    return prog


@pytest.fixture(scope="module")
def default_trifold(tmp_path_factory, trifold_flat):
    """The default program: the clamp on one end of the row, the grip on the other."""
    prog = fk.plan(fk.refold(trifold_flat, frames=8), CELL, workdir=tmp_path_factory.mktemp("tri_default"))
    assert prog.ok, prog.problems
    return prog


def test_path_json_records_the_holds_per_waypoint(trifold_program):
    doc = json.loads(trifold_program.path_file.read_text())
    holds = doc["holds"]
    fixed = trifold_program.details  # the clamped face is the FOLD file's fixed face
    from fabkit.io.fold import load_fold
    clamped = load_fold(trifold_program.fold_file).file_data["fabkit:fixed_face"]
    assert holds["clamped_faces"] == [clamped] and fixed["states"] == 8
    row = holds["arms"]["a"]
    assert len(row) == len(doc["waypoints"])
    grip = doc["grip"]["face"]
    for w, face in zip(doc["waypoints"], row):
        assert face == (grip if w["op"] in ("fold", "release") else None)
    # the record is inside the whole-document hash: editing it is refused
    doc["holds"]["arms"]["a"] = [None] * len(row)
    with pytest.raises(Exception, match="sha256 does not match"):
        Toolpath.from_json(doc)


def test_check_refuses_the_one_grip_trifold_naming_the_free_crease(trifold_program, tmp_path):
    out = tmp_path / "check.json"
    rc = main(["check", str(trifold_program.path_file), "--cell", CELL, "-o", str(out), "-q"])
    assert rc == 1
    rep = json.loads(out.read_text())
    assert not rep["ok"] and not rep["holds"]["ok"]
    holds = [p for p in rep["problems"] if p["kind"] == "holds"]
    assert len(holds) == 1
    assert holds[0]["subject"] in ("crease 0", "crease 1")
    assert "is folded by nothing held" in holds[0]["detail"] and "fold states 0-7" in holds[0]["detail"]
    # per state: every state of the fold (and one point between each) is reported, none holds
    states = rep["holds"]["states"]
    assert [s["state"] for s in states] == [k / 2 for k in range(15)]
    assert all(not s["ok"] and s["unheld_creases"] for s in states)


def test_the_default_trifold_program_holds_every_crease_in_every_state(default_trifold):
    check = fk.check(default_trifold)
    assert check.ok, check.problems
    rep = json.loads(check.check_file.read_text())
    states = rep["holds"]["states"]
    assert [s["state"] for s in states] == [k / 2 for k in range(15)]
    assert all(s["ok"] and s["unheld_creases"] == [] for s in states)
    folded = [s for s in states if not s["flat"]]
    assert folded and all(s["nullity"] == 0 and s["sigma_min"] > 1e-4 for s in folded)
    # clamp on strip 0, grip on strip 2: both ends of the row
    from fabkit.io.fold import load_fold
    model = load_fold(default_trifold.fold_file)
    strip = dict(zip(model.faces_data["polygon"], model.faces_data["strip"]))
    assert strip[rep["holds"]["clamped_faces"][0]] == 0 and strip[default_trifold.toolpath.grip["face"]] == 2
    # the panel is placed with its clamped face on the cell's clamp, and the panel hits nothing
    assert default_trifold.toolpath.extra["placement"]["clamped_face"] == rep["holds"]["clamped_faces"][0]
    assert rep["panel_collisions"]["ok"] and rep["panel_collisions"]["samples"] > 8


def test_two_crease_reflect_panel_is_held_in_every_state(tmp_path):
    from structure_panels import reflect_tagged

    save_obj(reflect_tagged(2, 60.0), tmp_path / "p.obj")
    folds = fk.refold(fk.unfold(fk.relax(fk.load(tmp_path / "p.obj"))), frames=5)
    check = fk.check(fk.plan(folds, CELL, workdir=tmp_path))
    assert check.ok, check.problems
    states = check.report.holds["states"]
    assert len(states) == 9 and all(s["ok"] for s in states)


def test_one_crease_panel_is_held_in_every_state(tmp_path):
    flat, target = reflect_pair(1, columns=8, rows=2)
    f, t = tmp_path / "flat.obj", tmp_path / "target.obj"
    save_obj(flat, f)
    save_obj(target, t)
    seq, path, check = tmp_path / "s.fold", tmp_path / "p.json", tmp_path / "c.json"
    assert main(["refold", str(f), str(t), "-o", str(seq), "--frames", "5", "-q"]) == 0
    assert main(["toolpath", str(seq), "--cell", CELL, "-o", str(path), "-q"]) == 0
    main(["check", str(path), "--cell", CELL, "-o", str(check), "-q"])
    rep = json.loads(check.read_text())
    assert rep["holds"]["ok"] and not [p for p in rep["problems"] if p["kind"] == "holds"]
    assert len(rep["holds"]["states"]) == 9
    folded = [s for s in rep["holds"]["states"] if not s["flat"]]
    assert folded and all(s["nullity"] == 0 and s["sigma_min"] > 1e-4 for s in folded)


def test_toolpath_without_a_holds_record_gets_it_derived(trifold_program):
    from robot.cell import load_cell
    from sim.check import check_toolpath

    tp = Toolpath.load(trifold_program.path_file)
    extra = {k: v for k, v in tp.extra.items() if k != "holds"}
    old = Toolpath(tp.robot, tp.cell, tp.tcp, tp.source, tp.waypoints, extra, tp.cell_sha256)
    rep = check_toolpath(old, load_cell(CELL), fold=trifold_program.fold_file)
    assert not rep.holds["recorded"] and any("records no holds" in n for n in rep.notes)
    assert [p.kind for p in rep.problems if p.kind == "holds"] == ["holds"]


def test_permuted_vertices_and_faces_give_the_same_clamp_and_grip_faces():
    """The clamp (one end of the row) and the grip candidates come from geometry, not from order."""
    import numpy as np
    from structure_panels import plain, reflect_tagged, shuffled

    from fabkit.structure import panel_structure

    mesh = plain(reflect_tagged(2, 60.0))
    ref = panel_structure(mesh)
    for seed in range(3):
        perm, _, _ = shuffled(mesh, seed=seed)
        s = panel_structure(perm)
        assert np.allclose(perm.face_centroids[s.clamp_face], mesh.face_centroids[ref.clamp_face], atol=1e-12)
        assert np.allclose(perm.face_centroids[s.grip_faces], mesh.face_centroids[ref.grip_faces], atol=1e-12)
