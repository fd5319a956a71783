"""Two-arm programs on cells/dual_ur10e.toml: planned in lockstep (PATH.json fabkit.toolpath/3),
checked with both arms in one model, holds proven with both grips and the clamp."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fabkit.errors import InputError
from robot.arms_toolpath import FORMAT, ArmsToolpath, load_toolpath
from robot.cell import load_cell
from robot.toolpath import Toolpath

ROOT = Path(__file__).resolve().parent.parent
DUAL = ROOT / "cells" / "dual_ur10e.toml"


def _trifold(folder: Path, fixed_face) -> Path:
    import fabkit.pipeline as fk

    flat = fk.unfold(fk.relax(fk.generate("trifold")))
    folds = fk.refold(flat, frames=6, fixed_face=fixed_face)
    assert folds.ok
    return folds.save(folder / "fold.fold")


def _plan(fold_file: Path):
    from fabkit.frames import planning_frames
    from fabkit.io.load import load_fold_model
    from fabkit.pipeline import fold_source
    from robot.plan_cell import plan_in_cell

    model, _ = load_fold_model(fold_file)
    frames = planning_frames(model, None, source=str(fold_file))
    return plan_in_cell(load_cell(DUAL), model, frames, source=fold_source(fold_file, frames.n_states))


@pytest.fixture(scope="module")
def middle(tmp_path_factory):
    """The tri-fold refolded with its middle strip clamped, planned and checked in the dual cell."""
    from sim.check import check_toolpath

    folder = tmp_path_factory.mktemp("dual")
    fold_file = _trifold(folder, fixed_face=4)
    res = _plan(fold_file)
    path = folder / "path.json"
    res.toolpath.save(path)
    report = check_toolpath(path, load_cell(DUAL))
    return folder, res, report


def test_each_arm_holds_one_wing_in_lockstep(middle):
    _, res, _ = middle
    atp = res.toolpath
    assert isinstance(atp, ArmsToolpath) and atp.to_json()["format"] == FORMAT == "fabkit.toolpath/3"
    assert atp.arm_names == ("a", "b")
    assert sorted(res.grips.values()) == [28, 36]          # the clamp on the middle strip, one arm per wing
    holds = atp.extra["holds"]
    assert holds["clamped_faces"] == [4]
    a, b = atp.arm("a"), atp.arm("b")
    assert len(a) == len(b) and [w.op for w in a.waypoints] == [w.op for w in b.waypoints]
    for name, tp in atp.arms:
        row = holds["arms"][name]
        assert [f is not None for f in row] == [w.op in ("fold", "release") for w in tp.waypoints]
        assert {f for f in row if f is not None} == {res.grips[name]}
        assert tp.extra["grip"]["face"] == res.grips[name]
    # a sync point at the grip and at every fold state; holding moves unblended, equal in time
    states = [w.state for w in a.waypoints]
    arrivals = [i for i in range(1, len(a)) if a.waypoints[i].op in ("fold", "release") and states[i] != states[i - 1]]
    grip = [i for i, w in enumerate(a.waypoints) if w.op == "grip"]
    assert list(atp.sync) == sorted(grip + arrivals)
    from robot.motion import toolpath_cycle_time

    ta, tb = toolpath_cycle_time(a).segments, toolpath_cycle_time(b).segments
    hold = np.array([w.op in ("fold", "release") for w in a.waypoints[1:]])
    np.testing.assert_allclose(ta[hold], tb[hold], atol=1e-9)
    assert all(w.r == 0 for w in a.waypoints if w.op in ("grip", "fold", "release"))
    assert max(w.v for w in a.waypoints + b.waypoints if w.op == "fold") <= 0.05 + 1e-12


def test_file_round_trip_and_refusals(middle, tmp_path):
    folder, res, _ = middle
    path = folder / "path.json"
    again = load_toolpath(path)
    assert isinstance(again, ArmsToolpath) and again.sha256 == res.toolpath.sha256
    d = json.loads(path.read_text())
    d["arms"][1]["waypoints"][5]["v"] *= 1.01                 # an edit the hash must catch
    bad = tmp_path / "edited.json"
    bad.write_text(json.dumps(d))
    with pytest.raises(InputError, match="sha256 does not match"):
        load_toolpath(bad)
    with pytest.raises(InputError, match="fabkit.toolpath/3.*expected 'fabkit.toolpath/2'"):
        Toolpath.load(path)                                   # a one-arm reader refuses it in one line
    d = json.loads(path.read_text())
    d["format"] = "fabkit.toolpath/9"
    bad.write_text(json.dumps(d))
    with pytest.raises(InputError, match="fabkit reads"):
        load_toolpath(bad)
    r = subprocess.run([sys.executable, "-m", "fabkit", "send", str(bad), "--check", str(bad), "--cell", str(DUAL),
                        "--host", "127.0.0.1"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "format" in r.stderr


def test_check_passes_with_both_grips_and_the_clamp(middle):
    _, res, report = middle
    assert report.ok, [p.detail for p in report.problems]
    d = report.to_json()
    assert d["toolpath_sha256"] == res.toolpath.sha256 and d["robot"] == "ur10e+ur10e"
    assert set(d["arms"]) == {"a", "b"} and all(a["ok"] for a in d["arms"].values())
    assert d["lockstep"]["max_mismatch_s"] < 1e-6 and d["lockstep"]["arm_arm_min_distance_m"] is None
    holds = d["holds"]
    assert holds["ok"] and holds["states"]
    assert all(s["ok"] and (s["flat"] or s["nullity"] == 0) for s in holds["states"])
    assert all(set(s["held_faces"]) == {4, 28, 36} for s in holds["states"])
    # states and the points between them are proven
    assert any(s["state"] % 1 for s in holds["states"])
    # each arm's cup on its grip face: the tri-fold's strips carry the 50 mm lip
    cup = holds["cup_footprint"]
    assert cup["enforced"] and cup["cup_mm"] == pytest.approx(50.0)
    assert [f["face"] for f in cup["faces"]] == [28, 36] and all(f["ok"] for f in cup["faces"])


def test_a_grip_the_cup_does_not_fit_is_refused_naming_the_arm(middle, tmp_path):
    """The same program in the dual cell with a 150 mm cup: wider than the strips, refused per arm."""
    from sim.check import check_toolpath

    folder, res, _ = middle
    text = DUAL.read_text()
    assert "cup_radius = 0.025 " in text
    big = tmp_path / "dual_big_cup.toml"
    big.write_text(text.replace("cup_radius = 0.025 ", "cup_radius = 0.075 "))
    report = check_toolpath(res.toolpath, load_cell(big), fold=folder / "fold.fold")
    cup = [p for p in report.problems if p.subject.startswith("cup × face_")]
    assert not report.ok and {p.subject for p in cup} == {"cup × face_28", "cup × face_36"}, report.problems
    assert all(p.kind == "holds" and p.detail.startswith("arm ") and "does not fit" in p.detail for p in cup)


def test_one_wing_left_free_is_refused(middle):
    """The same program with arm b's grip not recorded: the crease to its wing is folded by nothing held."""
    from sim.check import check_toolpath

    folder, res, _ = middle
    atp = res.toolpath
    holds = json.loads(json.dumps(atp.extra["holds"]))
    holds["arms"]["b"] = [None] * len(atp)
    forged = ArmsToolpath.build(atp.cell, atp.cell_sha256, atp.source, atp.arms, atp.sync,
                                {**atp.extra, "holds": holds})
    report = check_toolpath(forged, load_cell(DUAL), fold=folder / "fold.fold")
    kinds = {(p.kind, p.subject) for p in report.problems}
    assert not report.ok and any(k == "holds" and s.startswith("crease") for k, s in kinds), kinds


@pytest.mark.slow
def test_end_clamped_trifold_names_the_arms_that_touch(tmp_path):
    """Clamped at one end, the two grips sit on neighbouring strips: the arms' wrists meet and the
    check names the pair (both arms' parts)."""
    from sim.check import check_toolpath

    fold_file = _trifold(tmp_path, fixed_face=None)
    res = _plan(fold_file)
    report = check_toolpath(res.toolpath, load_cell(DUAL), fold=fold_file)
    arm_arm = [p for p in report.problems if p.detail.startswith("arm against arm")]
    assert not report.ok and arm_arm
    assert all(p.pair[1].startswith("b_") and not p.pair[0].startswith("b_") for p in arm_arm)


def test_interlock_reverifies_both_arms(middle):
    """The send interlock on a two-arm program: the check must be for this very program (every arm
    in its hash), every arm keeps the cell's limits, and the check run again passes."""
    from dataclasses import replace

    from robot.interlock import InterlockError, clear_for_send

    folder, res, report = middle
    cell = load_cell(DUAL)
    atp = res.toolpath
    cleared = clear_for_send(atp, report, cell, base_dir=folder)
    assert cleared.sha256 == atp.sha256 and isinstance(cleared.toolpath, ArmsToolpath) and cleared.recheck_s > 0
    # arm b asks for more than the cell's TCP speed, re-sealed with a fresh hash
    b = atp.arm("b")
    fast = tuple(replace(w, v=2.9) if w.op == "fold" else w for w in b.waypoints)
    b_fast = Toolpath(robot=b.robot, cell=b.cell, tcp=b.tcp, source=b.source, waypoints=fast, extra=b.extra,
                      cell_sha256=b.cell_sha256)
    forged = ArmsToolpath.build(atp.cell, atp.cell_sha256, atp.source, [("a", atp.arm("a")), ("b", b_fast)],
                                atp.sync, atp.extra)
    with pytest.raises(InterlockError, match="does not match the toolpath"):
        clear_for_send(forged, report, cell, base_dir=folder)
    forged_check = {**report.to_json(), "toolpath_sha256": forged.sha256}
    with pytest.raises(InterlockError, match="arm b: waypoint .*TCP speed 2.9 m/s over the cell limit"):
        clear_for_send(forged, forged_check, cell, base_dir=folder)


def test_cli_plans_and_checks_a_two_arm_program(middle, tmp_path):
    """`fabkit toolpath` and `fabkit check` on the dual cell: the same program as the library's;
    `--script` writes one URScript program per arm."""
    folder, res, _ = middle
    fold = folder / "fold.fold"
    run = [sys.executable, "-m", "fabkit"]
    r = subprocess.run(run + ["toolpath", str(fold), "--cell", str(DUAL), "-o", str(tmp_path / "p.json"),
                              "--grip-face", "28"],  # the pair is found from it; no checks while choosing
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "grip face (28, 36)" in r.stdout or "grip face (36, 28)" in r.stdout
    d = json.loads((tmp_path / "p.json").read_text())
    assert d["format"] == FORMAT and [a["name"] for a in d["arms"]] == ["a", "b"]
    ref = res.toolpath.to_json()
    for key in ("arms", "sync", "holds", "placement"):
        assert d[key] == ref[key], key
    r = subprocess.run(run + ["check", str(tmp_path / "p.json"), "--cell", str(DUAL), "-o", str(tmp_path / "c.json"),
                              "--fold", str(fold)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "check: ok" in r.stdout, r.stdout + r.stderr
    r = subprocess.run(run + ["toolpath", str(fold), "--cell", str(DUAL), "-o", str(tmp_path / "q.json"),
                              "--grip-face", "28", "--script", str(tmp_path / "q.script"), "--handshake-timeout", "4.5"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr  # one program per arm (robot.arms_urscript), nothing at q.script itself
    from robot.arms_urscript import write_arm_urscripts

    written = {arm: (tmp_path / f"q_{arm}.script").read_text() for arm in ("a", "b")}
    assert written == write_arm_urscripts(load_toolpath(tmp_path / "q.json"), timeout_s=4.5)
    assert not (tmp_path / "q.script").exists() and "if fabkit_waited > 4.5:" in written["a"]
    assert "q_a.script: URScript program of arm a" in r.stdout


def test_renders_draw_both_arms(middle, tmp_path):
    """The check's configurations of a two-arm program hold both arms at the common moments; the
    PNG draws the model with both."""
    from sim.check import run_toolpath_check
    from sim.render_check import render_waypoint

    folder, res, _ = middle
    cell = load_cell(DUAL)
    run = run_toolpath_check(folder / "path.json", cell)
    assert run.dense.q.shape[1] == 12
    atp = res.toolpath
    on = np.flatnonzero(run.dense.at_waypoint)
    np.testing.assert_allclose(run.dense.q[on[-1], :6], atp.arm("a").waypoints[-1].q, atol=1e-9)
    # the last moment is the slower arm's arrival; the other waits on its last waypoint
    np.testing.assert_allclose(run.dense.q[-1, :6], atp.arm("a").waypoints[-1].q, atol=1e-9)
    np.testing.assert_allclose(run.dense.q[-1, 6:], atp.arm("b").waypoints[-1].q, atol=1e-9)
    out = render_waypoint(run, cell, tmp_path / "both.png", size=(160, 120))
    assert (tmp_path / "both.png").stat().st_size > 0 and out["waypoint"] > 0


def test_a_panel_two_arms_cannot_hold_is_a_planning_failure(tmp_path):
    """One crease: the clamp takes one strip, only one middle-row face moves; no pair of faces."""
    import fabkit.pipeline as fk
    from robot.planner import PlanningError

    flat = fk.unfold(fk.relax(fk.generate("reflect", creases=1)))
    folds = fk.refold(flat, frames=3)
    fold_file = folds.save(tmp_path / "one.fold")
    with pytest.raises(PlanningError, match="holds: no two middle-row faces hold the panel"):
        _plan(fold_file)


def test_a_one_arm_program_goes_to_one_controller(tmp_path):
    from robot.sender import SendError, SendSettings, send_toolpath
    from tests._ursim import CELL, check_report, demo_toolpath

    tp = demo_toolpath(n_fold=6)
    with pytest.raises(SendError, match="one-arm program goes to one controller, got 2"):
        send_toolpath(tp, check_report(tp), load_cell(CELL), SendSettings(host="127.0.0.1", hosts=("127.0.0.2",)))


def test_permuted_vertex_and_face_order_give_the_same_program(tmp_path):
    """The tri-fold as a plain OBJ (no tags), and the same with its vertices and faces renumbered and
    each face's corners rotated, refolded and planned on the dual cell as a user would (`fabkit refold` with its
    clamp face the demo picks, `fabkit.placement.choose_clamp_face`; `fabkit toolpath`): the same
    clamped face, the same grip face per arm and the same program (every arm's joints and poses
    within 1e-9), up to the face permutation."""
    from holds_panels import trifold_pair

    from fabkit.cli import main
    from fabkit.io.obj import save_obj
    from fabkit.mesh import PolyMesh
    from fabkit.placement import choose_clamp_face

    flat, target = trifold_pair()
    rng = np.random.default_rng(11)
    new_of_old = rng.permutation(flat.n_vertices)
    order = rng.permutation(flat.n_faces)  # new face i is old face order[i]
    rings = []
    for f in order:
        ring = [int(new_of_old[v]) for v in flat.face(int(f))]
        k = int(rng.integers(len(ring)))
        rings.append(ring[k:] + ring[:k])

    def renumbered(mesh):
        V = np.empty_like(mesh.vertices)
        V[new_of_old] = mesh.vertices
        return PolyMesh(V, rings)

    def plain(mesh):
        return PolyMesh(mesh.vertices, mesh.faces_list())

    programs = {}
    for name, (f, t) in {"plain": (plain(flat), plain(target)),
                         "permuted": (renumbered(flat), renumbered(target))}.items():
        d = tmp_path / name
        d.mkdir()
        save_obj(f, d / "flat.obj")
        save_obj(t, d / "target.obj")
        assert main(["refold", str(d / "flat.obj"), str(d / "target.obj"), "-o", str(d / "s.fold"), "--frames",
                     "3", "--fixed-face", str(choose_clamp_face(f)), "-q"]) == 0
        assert main(["toolpath", str(d / "s.fold"), "--cell", str(DUAL), "-o", str(d / "p.json"), "-q"]) == 0
        programs[name] = load_toolpath(d / "p.json")
    ref, got = programs["plain"], programs["permuted"]
    old = lambda faces: [int(order[f]) if f is not None else None for f in faces]  # noqa: E731
    assert ref.arm_names == got.arm_names == ("a", "b") and ref.sync == got.sync
    hr, hg = ref.extra["holds"], got.extra["holds"]
    assert old(hg["clamped_faces"]) == hr["clamped_faces"]
    for arm in ref.arm_names:
        a, b = ref.arm(arm), got.arm(arm)
        assert old([b.extra["grip"]["face"]]) == [a.extra["grip"]["face"]]
        assert old(hg["arms"][arm]) == hr["arms"][arm]
        assert [w.op for w in a.waypoints] == [w.op for w in b.waypoints]
        np.testing.assert_allclose([w.q for w in b.waypoints], [w.q for w in a.waypoints], atol=1e-9, rtol=0)
        np.testing.assert_allclose([w.pose for w in b.waypoints], [w.pose for w in a.waypoints], atol=1e-9, rtol=0)
