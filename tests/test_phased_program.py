"""One-arm programs in phases (`robot.phased_planner`): grip, fold, release, transfer, regrip, fold on.

A plain one-crease 60 deg panel (no tags) in the UR5e bench cell, planned as two phases on the same
face with a release and regrip at fold state 2: PATH.json names the phases, the holds name the
phase's face on every move that carries the panel, `fabkit check` proves the holds per phase and
checks the transfer moves like any other, a record that names the wrong face is refused, and a
dry run on the controller stand-in switches the gripper on and off once per phase. One phase is
exactly the program `plan_toolpath` plans.
"""
import json
from pathlib import Path

import numpy as np
import pytest

from fabkit.cli import main
from fabkit.io.obj import save_obj
from structure_panels import plain, reflect_tagged, shuffled

CELL = str(Path(__file__).resolve().parent.parent / "cells" / "ur5e_bench.toml")


def _make_panel(d, mesh):
    """(seq.fold, placed cell, frames, clamped faces, placement) of `mesh` through relax, unfold, refold."""
    from fabkit.frames import planning_frames
    from fabkit.io.load import load_fold_model
    from robot.cell import load_cell
    from robot.holds_record import clamped_faces_of
    from robot.panel_placement import placed_cell, placement_for

    save_obj(mesh, d / "panel.obj")
    assert main(["relax", str(d / "panel.obj"), "-o", str(d / "rel.obj"), "-q"]) == 0
    assert main(["unfold", str(d / "rel.obj"), "-o", str(d / "flat.obj"), "-q"]) == 0
    assert main(["refold", str(d / "flat.obj"), str(d / "rel.obj"), "-o", str(d / "seq.fold"), "--frames", "5",
                 "-q"]) == 0
    cell = load_cell(CELL)
    model, _ = load_fold_model(d / "seq.fold", None)
    placement = placement_for(cell, model)
    return d / "seq.fold", placed_cell(cell, placement), planning_frames(model, None), clamped_faces_of(model), placement


@pytest.fixture(scope="module")
def panel(tmp_path_factory):
    """A plain one-crease 60 deg panel (no tags), `_make_panel`."""
    return _make_panel(tmp_path_factory.mktemp("phased"), plain(reflect_tagged(1, 60.0)))


def _plan(panel, specs):
    from fabkit.toolpath_stage import fold_source
    from robot.grip_choice import grip_order
    from robot.phased_planner import PhaseSpec, plan_phases
    from robot.planner import PlanOptions

    fold, cell, frames, clamped, placement = panel
    face = grip_order(frames)[0]
    return plan_phases(cell, frames, [PhaseSpec(face, *s) for s in specs], options=PlanOptions(),
                       source={**fold_source(fold, frames.n_states), "grip_face": face}, clamped_faces=clamped,
                       placement=placement), face


def test_one_phase_is_the_single_grip_program(panel):
    from robot.planner import PlanOptions, plan_toolpath

    res, face = _plan(panel, [("front", 0, panel[2].n_states - 1)])
    fold, cell, frames, clamped, placement = panel
    plain_res = plan_toolpath(cell, frames.of_face(face), options=PlanOptions(), grip_face=face,
                              clamped_faces=clamped, placement=placement, source=res.toolpath.source)
    assert json.dumps(res.toolpath.to_json()) == json.dumps(plain_res.toolpath.to_json())
    assert "phases" not in res.toolpath.extra


@pytest.mark.slow
def test_a_regrip_program_is_checked_per_phase_and_sent(panel, tmp_path):
    from _ursim import StandIn

    fold = panel[0]
    last = panel[2].n_states - 1
    res, face = _plan(panel, [("front", 0, 2), ("front", 2, last)])
    tp = res.toolpath
    ph = tp.extra["phases"]
    assert [(p["face"], p["side"], p["states"]) for p in ph] == [(face, "front", [0, 2]), (face, "front", [2, last])]
    ops = [w.op for w in tp.waypoints]
    assert ops.count("grip") == 2 and ops.count("release") == 2
    transfer = tp.waypoints[ph[0]["waypoints"][1] + 1:ph[1]["waypoints"][0]]
    assert [w.move for w in transfer] == ["movej"] * len(transfer) and {w.state for w in transfer} == {2}
    row = tp.extra["holds"]["arms"]["a"]
    assert all((row[i] == face) == (op in ("fold", "release")) for i, op in enumerate(ops))
    path = tmp_path / "path.json"
    tp.save(path)
    (tmp_path / fold.name).write_bytes(fold.read_bytes())
    check = tmp_path / "check.json"
    assert main(["check", str(path), "--cell", CELL, "-o", str(check), "-q"]) == 0
    rep = json.loads(check.read_text())
    assert rep["ok"] and rep["phases"]["ok"] and rep["phases"]["count"] == 2
    for entry in rep["phases"]["phases"]:
        assert entry["holds_proven"] and entry["hold_states"] > 0 and entry["problems"] == 0
        assert entry["grips"] == 1 and entry["releases"] == 1
    assert rep["phases"]["phases"][0]["transfer"]["problems"] == 0

    # a holds record naming another face in phase 1 is refused, naming the phase
    doc = json.loads(path.read_text())
    other = next(f for f in panel[3])    # the clamped face
    i = ph[1]["waypoints"][1] - 1
    doc["holds"]["arms"]["a"][i] = other
    from robot.toolpath import document_sha256

    doc["sha256"] = document_sha256(doc)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    assert main(["check", str(bad), "--cell", CELL, "-o", str(tmp_path / "bad_check.json"), "-q"]) == 1
    problems = json.loads((tmp_path / "bad_check.json").read_text())["problems"]
    assert any(p["kind"] == "holds" and p["subject"] == "phase 1" for p in problems)

    standin = StandIn("--cell", CELL, log=tmp_path / "ursim.log")
    try:
        log = tmp_path / "send.log"
        rc = main(["send", str(path), "--check", str(check), "--cell", CELL, "--host", standin.host, "--power-on",
                   "--log", str(log), "--report", str(tmp_path / "send.json"), "-q"])
        sent = json.loads((tmp_path / "send.json").read_text())
        assert rc == 0 and sent["ok"] and sent["last_completed"] == len(tp) - 1, sent
    finally:
        standin.stop()
    switches = [e["on"] for e in map(json.loads, log.read_text().splitlines()) if e.get("step") == "gripper"]
    assert switches[-4:] == [True, False, True, False], switches   # confirmed by the receive stream


def test_resume_inside_a_later_phase_knows_the_gripper(panel):
    from robot.send_tool import ToolControl

    res, _ = _plan(panel, [("front", 0, 2), ("front", 2, panel[2].n_states - 1)])
    tp = res.toolpath
    ph = tp.extra["phases"]
    tool = ToolControl(tp, None, None, None, RuntimeError, 0.01)
    holding = [k for k in range(len(tp)) if tool.holding_at(k)]
    fold_moves = [k for k, w in enumerate(tp.waypoints) if w.op in ("fold", "release")]
    assert holding == fold_moves                       # closed on every fold move of both phases
    transfer = range(ph[0]["waypoints"][1] + 1, ph[1]["waypoints"][0] + 2)  # up to phase 1's grip: open
    assert not any(tool.holding_at(k) for k in transfer)


def test_permuted_panel_gets_the_same_phases(panel, tmp_path):
    """Vertex and face order permuted: the same regrip split, grip face (up to the permutation),
    phases and joints."""
    from robot.grip_choice import grip_order
    from robot.regrip_choice import regrip_splits

    mesh, _, order = shuffled(plain(reflect_tagged(1, 60.0)), seed=5)
    other = _make_panel(tmp_path, mesh)
    new_of_old = np.argsort(order)
    runs = []
    for p in (panel, other):
        face = grip_order(p[2])[0]
        k = regrip_splits(p[2], face)[0]
        res, _ = _plan(p, [("front", 0, k), ("front", k, p[2].n_states - 1)])
        runs.append((face, k, res.toolpath))
    (f0, k0, a), (f1, k1, b) = runs
    assert f1 == int(new_of_old[f0]) and k0 == k1
    assert [(p["side"], p["states"], p["waypoints"]) for p in a.extra["phases"]] == \
        [(p["side"], p["states"], p["waypoints"]) for p in b.extra["phases"]]
    assert [p["face"] for p in b.extra["phases"]] == [int(new_of_old[p["face"]]) for p in a.extra["phases"]]
    assert [w.op for w in a.waypoints] == [w.op for w in b.waypoints]
    assert np.abs(a.joints - b.joints).max() <= 1e-6


@pytest.mark.slow
def test_the_chosen_regrip_is_the_same_for_a_permuted_panel(tmp_path):
    """The one-crease 175 deg panel on the UR5e bench, as made and with vertex and face order
    permuted: no single grip passes, and the regrip alternatives compared (faces, splits, approach
    distances, scored by phases and cycle time) choose the same phases, grip face (up to the
    permutation) and joints."""
    from fabkit.toolpath_stage import plan_fold_file

    mesh = plain(reflect_tagged(1, 175.0))
    permuted, _, order = shuffled(mesh, seed=3)
    new_of_old = np.argsort(order)
    runs = []
    for name, m in (("made", mesh), ("permuted", permuted)):
        d = tmp_path / name
        d.mkdir()
        fold = _make_panel(d, m)[0]
        prog = plan_fold_file(fold, CELL)
        runs.append((prog.toolpath, [t for _, t in prog.plan.tried if t.startswith("regrip")]))
    (a, tried_a), (b, tried_b) = runs
    pa, pb = a.extra["phases"], b.extra["phases"]
    assert [p["side"] for p in pa] == ["front", "back"]
    assert [(p["side"], p["states"], p["waypoints"]) for p in pa] == [(p["side"], p["states"], p["waypoints"]) for p in pb]
    assert [p["face"] for p in pb] == [int(new_of_old[p["face"]]) for p in pa]
    assert np.abs(a.joints - b.joints).max() <= 1e-6
    assert len(tried_a) == len(tried_b) >= 5      # the alternatives not chosen, each named with its score
    assert all("2 phases, cycle" in t for t in tried_a)
