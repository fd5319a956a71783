"""Toolpath planning on exact grid folds, PATH.json round trips, motion parameters, the CLI."""
import copy
import hashlib
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from fabkit.cli import main as fabkit_main
from fabkit.errors import InputError
from fabkit.frames import middle_row_frames
from fabkit.io.fold import save_fold
from fold_fixtures import folded_grid_model
from robot import kinematics as K
from robot.cell import load_cell, parse_cell, pose_to_matrix
from robot.motion import (blend_overlaps, blend_radii, joint_speed_estimates, segment_times, trapezoid_time)
from robot.toolpath import (FORMAT, PlanningError, Toolpath, check_toolpath_kinematics, plan_panel, plan_toolpath,
                            tcp_targets, document_sha256)

CELLS = Path(__file__).resolve().parent.parent / "cells"
CELL_FILES = [CELLS / "ur5e_bench.toml", CELLS / "ur10e_fold_table.toml"]


@pytest.fixture(scope="module")
def frames60():
    return middle_row_frames(folded_grid_model(n_states=9, angles=[math.radians(60)] * 2, triangulate=True))


@pytest.fixture(scope="module", params=CELL_FILES, ids=lambda p: p.stem)
def planned(request, frames60):
    cell = load_cell(request.param)
    return cell, plan_panel(cell, frames60, source={"file": "grid.fold"})


def _assert_executable(cell, tp):
    chk = check_toolpath_kinematics(tp)
    assert chk["fk_pos_max"] <= 1e-9 and chk["fk_rot_max"] <= 1e-9
    assert chk["blend_overlaps"] == []
    W = tp.waypoints
    ops = [w["op"] for w in W]
    Q = tp.joints
    # no joint moves more than 5 deg between consecutive waypoints of the fold move
    for i in range(1, len(W)):
        if ops[i] in ("fold", "release"):
            assert np.abs(Q[i] - Q[i - 1]).max() <= math.radians(5) + 1e-12, i
    # one branch through every linear move
    lin = [i for i, w in enumerate(W) if w["move"] == "movel"] + [ops.index("approach")]
    signs = K.branch_signs(cell.model, Q[lin])
    assert (signs == signs[0]).all()
    # blends: 0 at stops and the end; never more than half of the shorter adjacent segment
    P = tp.poses[:, :3]
    r = np.array([w["r"] for w in W])
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    assert r[0] == 0 and r[-1] == 0
    for i, o in enumerate(ops):
        if o in ("home", "approach", "grip", "release", "retract"):
            assert r[i] == 0.0
        if 0 < i < len(W) - 1:
            assert r[i] <= 0.5 * min(seg[i - 1], seg[i]) + 1e-15
    # speeds within the cell's limits
    for w in W:
        if w["move"] == "movel":
            assert 0 < w["v"] <= cell.limits.tcp_speed and w["a"] <= cell.limits.tcp_accel
        else:
            assert 0 < w["v"] <= min(cell.limits.joint_speed) and w["a"] <= cell.limits.joint_accel
    assert tp.extra["checks"]["joint_speed_ratio"] <= 1.0


def test_planned_grid_fold_is_executable(planned):
    cell, res = planned
    tp = res.toolpath
    _assert_executable(cell, tp)
    ops = [w["op"] for w in tp.waypoints]
    assert ops[0] == "home" and ops[1] == "approach" and ops[2] == "grip" and ops[-1] == "home"
    assert ops.count("grip") == 1 and ops.count("release") == 1 and ops[-2] == "retract"
    assert [w["state"] for w in tp.waypoints if w["op"] == "release"] == [8]
    states = [w["state"] for w in tp.waypoints]
    assert states == sorted(states)
    assert res.cycle_time > 0 and math.isfinite(res.cycle_time)
    assert res.grip_face in (6, 8)  # an outer strip (the clamped middle strip does not move)


def test_waypoint_poses_follow_the_face_frames(planned, frames60):
    cell, res = planned
    tp = res.toolpath
    F = frames60.of_face(res.grip_face)
    # the grip waypoint's TCP sits on the face centroid with its z axis into the face
    w = next(w for w in tp.waypoints if w["op"] == "grip")
    T = cell.robot.base_pose @ pose_to_matrix(w["pose"])
    face_world = cell.fixture @ F[0]
    np.testing.assert_allclose(T[:3, 3], face_world[:3, 3], atol=1e-12)
    np.testing.assert_allclose(T[:3, 2], -face_world[:3, 2], atol=1e-12)
    rel = next(w for w in tp.waypoints if w["op"] == "release")
    T = cell.robot.base_pose @ pose_to_matrix(rel["pose"])
    np.testing.assert_allclose(T[:3, 3], (cell.fixture @ F[-1])[:3, 3], atol=1e-12)
    # approach is 8 cm in front of the face, along its front normal
    ap = next(w for w in tp.waypoints if w["op"] == "approach")
    T = cell.robot.base_pose @ pose_to_matrix(ap["pose"])
    np.testing.assert_allclose(T[:3, 3], face_world[:3, 3] + 0.08 * face_world[:3, 2], atol=1e-12)
    # automatic tool yaw keeps wrist 3 at its home angle at the approach
    assert abs(K.wrap_angle(np.array(ap["q"][5] - cell.robot.home[5]))) < 1e-9


def test_toolpath_json_round_trip(planned, tmp_path):
    _, res = planned
    tp = res.toolpath
    path = tmp_path / "p.json"
    tp.save(path)
    d = json.loads(path.read_text())
    assert d["format"] == FORMAT and d["sha256"] == tp.sha256
    # the hash covers the whole document but itself: robot, cell + cell file hash, TCP, grip, source, waypoints
    canonical = json.dumps({k: v for k, v in d.items() if k != "sha256"}, sort_keys=True, separators=(",", ":"))
    assert hashlib.sha256(canonical.encode()).hexdigest() == d["sha256"]
    assert d["cell_sha256"] == planned[0].sha256 == hashlib.sha256(Path(planned[0].source).read_bytes()).hexdigest()
    back = Toolpath.load(path)
    assert back.sha256 == tp.sha256 and back.waypoints == tp.waypoints and back.extra == tp.extra
    # floats survive exactly
    np.testing.assert_array_equal(back.joints, tp.joints)


@pytest.mark.parametrize("edit, words", [
    (lambda d: d["waypoints"][3]["q"].__setitem__(0, 0.1), "sha256 does not match"),
    (lambda d: d.__setitem__("format", "other/1"), "format is 'other/1'"),
    (lambda d: d.pop("tcp"), "tcp: missing"),
    (lambda d: d.__setitem__("robot", "ur3"), "robot: 'ur3'"),
    (lambda d: d["waypoints"][2].__setitem__("move", "movep"), "waypoints[2].move"),
    (lambda d: d["waypoints"][2].__setitem__("op", "dance"), "waypoints[2].op"),
    (lambda d: d["waypoints"][2].__setitem__("v", -1), "waypoints[2].v"),
    (lambda d: d["waypoints"][2].__setitem__("r", -1), "waypoints[2].r"),
    (lambda d: d["waypoints"][2].__setitem__("state", 1.5), "waypoints[2].state"),
    (lambda d: d["waypoints"][2]["pose"].pop(), "waypoints[2].pose"),
    (lambda d: d["waypoints"][2].pop("q"), "waypoints[2].q: missing"),
    (lambda d: d.__setitem__("waypoints", []), "waypoints: expected a non-empty list"),
    (lambda d: d.__setitem__("source", "x.fold"), "source: expected an object"),
    (lambda d: d.__setitem__("cell", 3), "cell: expected a string"),
    (lambda d: d.__setitem__("format", "fabkit.toolpath/1"), "re-plan it with `fabkit toolpath`"),
    (lambda d: d.pop("cell_sha256"), "cell_sha256: missing"),
    (lambda d: d["waypoints"][2]["pose"].__setitem__(0, 1e300), "waypoints[2].pose"),
    (lambda d: d["waypoints"][2]["q"].__setitem__(0, 1e30), "waypoints[2].q"),
    (lambda d: d["tcp"].__setitem__(2, d["tcp"][2] - 0.1), "sha256 does not match"),
    (lambda d: d["grip"].__setitem__("output", 1 - d["grip"]["output"]), "sha256 does not match"),
    (lambda d: d.__setitem__("cell_sha256", "0" * 64), "sha256 does not match"),
    (lambda d: d["source"].__setitem__("sha256", "0" * 64), "sha256 does not match"),
])
def test_toolpath_validation(planned, edit, words):
    d = copy.deepcopy(planned[1].toolpath.to_json())
    edit(d)
    with pytest.raises(InputError) as info:
        Toolpath.from_json(d, source="p.json")
    assert words in str(info.value) and str(info.value).startswith("p.json: ")


def test_toolpath_load_errors(tmp_path):
    with pytest.raises(InputError, match="not found"):
        Toolpath.load(tmp_path / "none.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    with pytest.raises(InputError, match="not a JSON toolpath"):
        Toolpath.load(bad)


def test_sha256_is_over_the_canonical_document():
    doc = {"format": FORMAT, "tcp": [0, 0, 0.13, 0, 0, 0], "waypoints": [{"pose": [0.1, 0, 0, 0, 0, 0], "v": 1.0}],
           "sha256": "ignored"}
    text = '{"format":"fabkit.toolpath/2","tcp":[0,0,0.13,0,0,0],"waypoints":[{"pose":[0.1,0,0,0,0,0],"v":1.0}]}'
    assert document_sha256(doc) == hashlib.sha256(text.encode()).hexdigest()


def test_waypoints_are_immutable(planned):
    import dataclasses

    tp = planned[1].toolpath
    w = tp.waypoints[3]
    with pytest.raises(dataclasses.FrozenInstanceError):
        w.v = 3.0
    with pytest.raises(TypeError):
        w.q[0] = 1.0  # tuples
    with pytest.raises(TypeError):
        w["v"] = 3.0
    assert w["q"] == w.q and isinstance(tp.waypoints, tuple)
    before = tp.sha256
    out = tp.extra["grip"]["output"]
    tp.extra["grip"]["output"] = 1 - out  # a dict can be changed in memory, but the hash follows it
    assert tp.sha256 != before
    tp.extra["grip"]["output"] = out
    assert tp.sha256 == before


def _cell_with(path, **changes):
    data = tomllib.loads(Path(path).read_text())
    for dotted, value in changes.items():
        d = data
        keys = dotted.split(".")
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value
    return parse_cell(data, str(path))


def test_unreachable_fixture_names_the_waypoint(frames60):
    cell = _cell_with(CELL_FILES[0], **{"fixture.pose": [3.0, 0.0, 0.9, 0.0, 0.0, 0.0]})
    with pytest.raises(PlanningError) as info:
        plan_panel(cell, frames60)
    e = info.value
    assert e.kind == "unreachable" and e.waypoint == 1 and e.op == "approach"
    assert str(e).startswith("waypoint 1 (approach, fold state 0): unreachable")


def test_path_over_the_base_axis_is_refused():
    """A straight line with the tool down passing over the base: every branch meets the shoulder
    singularity on the way (the wrist centre crosses the base axis)."""
    cell = load_cell(CELL_FILES[0])
    S = 21
    Tb = np.repeat(np.eye(4)[None], S, axis=0)
    Tb[:, 0, 3] = np.linspace(-0.35, 0.35, S)
    Tb[:, 1, 3] = -0.13
    Tb[:, 2, 3] = 0.35
    F = np.linalg.inv(cell.panel_to_base) @ Tb
    with pytest.raises(PlanningError) as info:
        plan_toolpath(cell, F)
    e = info.value
    assert e.kind == "singular" and "shoulder singularity" in e.detail
    assert str(e).startswith(f"waypoint {e.waypoint} (fold, fold state {e.state}): singular") and 0 < e.state < S - 1


def test_grip_face_must_be_in_the_middle_row(frames60):
    cell = load_cell(CELL_FILES[0])
    with pytest.raises(InputError, match="face 3 is not a middle-row face"):
        plan_panel(cell, frames60, grip_face=3)
    res = plan_panel(cell, frames60, grip_face=6)
    assert res.grip_face == 6 and res.toolpath.source["grip_face"] == 6


def test_tcp_targets_compose_fixture_frame_and_grip_offset():
    cell = load_cell(CELL_FILES[1])
    F = np.eye(4)[None]
    tg = tcp_targets(cell, F)
    T_world = cell.robot.base_pose @ tg["grip"][0]
    np.testing.assert_allclose(T_world[:3, 3], cell.fixture[:3, 3], atol=1e-12)
    np.testing.assert_allclose(T_world[:3, 2], -cell.fixture[:3, 2], atol=1e-12)
    np.testing.assert_allclose(T_world[:3, 0], cell.fixture[:3, 0], atol=1e-12)


# ---- motion ------------------------------------------------------------------------------------

def test_trapezoid_time_known_values():
    assert trapezoid_time(1.0, 0.5, 1.0) == pytest.approx(2.5)       # 1/0.5 + 0.5/1
    assert trapezoid_time(0.01, 1.0, 1.0) == pytest.approx(0.2)      # triangle: 2 sqrt(d/a)
    assert trapezoid_time(0.25, 0.5, 1.0) == pytest.approx(1.0)      # exactly v^2/a: both formulas agree


def test_blend_radii_and_overlaps():
    P = np.array([[0, 0, 0], [0.1, 0, 0], [0.11, 0, 0], [0.3, 0, 0], [0.5, 0, 0]], float)
    r = blend_radii(P, np.zeros(5, bool), r_max=0.05)
    np.testing.assert_allclose(r, [0, 0.005, 0.005, 0.05, 0])
    assert blend_overlaps(P, r).tolist() == []
    stops = np.array([0, 0, 0, 1, 0], bool)
    assert blend_radii(P, stops, 0.05)[3] == 0
    assert blend_overlaps(P, np.array([0, 0.06, 0.0, 0.0, 0])).tolist() == [1]


def test_segment_times_runs_and_stops():
    P = np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]], float)
    R = np.repeat(np.eye(3)[None], 3, axis=0)
    Q = np.zeros((3, 6))
    moves = np.array(["movel"] * 3)
    v, a = np.full(3, 0.1), np.full(3, 1.0)
    stop = segment_times(moves, P, R, Q, v, a, np.zeros(3))
    blended = segment_times(moves, P, R, Q, v, a, np.array([0, 0.01, 0]))
    np.testing.assert_allclose(stop, [trapezoid_time(0.1, 0.1, 1.0)] * 2)
    # one run of 0.2 m: cruise 2 s plus half the ramp time at each end
    assert blended.sum() == pytest.approx(0.2 / 0.1 + 0.1 / 1.0)
    assert blended.sum() < stop.sum()
    qd = joint_speed_estimates(np.array([[0.0] * 6, [0.5] * 6]), np.array([2.0]))
    np.testing.assert_allclose(qd, [[0.25] * 6])


# ---- CLI ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def seq_file(tmp_path_factory):
    p = tmp_path_factory.mktemp("seq") / "grid.fold"
    save_fold(folded_grid_model(n_states=6, angles=[math.radians(45)] * 2, triangulate=True), p)
    return p


def test_cli_writes_path_script_and_report(seq_file, tmp_path, capsys):
    out, script, report = tmp_path / "p.json", tmp_path / "f.script", tmp_path / "r.json"
    # the grip face given: no candidate is checked (the grid's programs leave a crease free, so the
    # check would refuse every one: `test_cli_exits_1_when_the_check_refuses_every_candidate`)
    rc = fabkit_main(["toolpath", str(seq_file), "--cell", str(CELL_FILES[1]), "-o", str(out),
                      "--script", str(script), "--report", str(report), "--grip-face", "6"])
    assert rc == 0, capsys.readouterr()
    tp = Toolpath.load(out)
    r = json.loads(report.read_text())
    assert r["ok"] and r["toolpath_sha256"] == tp.sha256 and r["max_fold_joint_step_deg"] <= 5.0
    assert tp.source["file"] == "grid.fold"
    assert tp.source["sha256"] == hashlib.sha256(seq_file.read_bytes()).hexdigest()
    text = script.read_text()
    assert text.splitlines()[2] == f"  # toolpath sha256: {tp.sha256}"
    assert "set_standard_digital_out(1, True)" in text  # the ur10e cell's gripper output
    assert "grip face" in capsys.readouterr().out


def test_cli_exits_1_when_the_check_refuses_every_candidate(seq_file, tmp_path, capsys):
    """Every candidate that plans leaves a crease of the grid folded by nothing held: PATH.json is the first that
    planned, kept for `fabkit check`, no URScript, the report not ok, exit 1 with one line."""
    out, script, report = tmp_path / "p.json", tmp_path / "f.script", tmp_path / "r.json"
    rc = fabkit_main(["toolpath", str(seq_file), "--cell", str(CELL_FILES[1]), "-o", str(out),
                      "--script", str(script), "--report", str(report)])
    cap = capsys.readouterr()
    assert rc == 1 and cap.err.count("\n") == 1, cap
    assert "FAILED: the check refuses every grip candidate that planned (tried 6, 8)" in cap.err
    assert "holds: fold states 0-5" in cap.err and "is folded by nothing held" in cap.err
    assert "no URScript" in cap.err
    assert out.exists() and not script.exists()
    r = json.loads(report.read_text())
    assert r["ok"] is False and "is folded by nothing held" in r["refused_by_check"]
    assert r["toolpath_sha256"] == Toolpath.load(out).sha256
    check = tmp_path / "CHECK.json"
    assert fabkit_main(["check", str(out), "--cell", str(CELL_FILES[1]), "--fold", str(seq_file), "-o", str(check),
                        "-q"]) == 1
    assert json.loads(check.read_text())["problems"][0]["kind"] == "holds"


def test_cli_unreachable_exits_1_and_writes_nothing(seq_file, tmp_path, capsys):
    text = CELL_FILES[0].read_text().replace("pose = [0.75, -0.25, 1.10, 0.0, 0.0, 1.5707963267948966]",
                                             "pose = [2.75, -0.25, 1.10, 0.0, 0.0, 1.5707963267948966]")
    text = text.replace("pose = [0.56, -0.03, 1.10,", "pose = [2.56, -0.03, 1.10,")   # the clamp goes with it
    assert "2.75" in text and "2.56" in text
    far = tmp_path / "far.toml"
    far.write_text(text)
    out, report = tmp_path / "p.json", tmp_path / "r.json"
    rc = fabkit_main(["toolpath", str(seq_file), "--cell", str(far), "-o", str(out), "--report", str(report)])
    err = capsys.readouterr().err
    assert rc == 1 and "waypoint 1 (approach, fold state 0): unreachable" in err
    assert not out.exists()
    r = json.loads(report.read_text())
    assert not r["ok"] and r["problems"][0]["kind"] == "unreachable"


@pytest.mark.parametrize("args, words", [
    (["--approach", "-1"], "--approach"),
    (["--grip-face", "0"], "--grip-face: face 0 is not a middle-row face"),
    (["--progress-register", "99"], "--progress-register"),
])
def test_cli_bad_arguments_exit_2(seq_file, tmp_path, capsys, args, words):
    rc = fabkit_main(["toolpath", str(seq_file), "--cell", str(CELL_FILES[0]), "-o", str(tmp_path / "p.json")] + args)
    assert rc == 2 and words in capsys.readouterr().err


def test_cli_bad_cell_exit_2(seq_file, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(CELL_FILES[0].read_text().replace('model = "ur5e"', 'model = "ur99"'))
    rc = fabkit_main(["toolpath", str(seq_file), "--cell", str(bad), "-o", str(tmp_path / "p.json")])
    err = capsys.readouterr().err
    assert rc == 2 and f"{bad}: robot.model" in err and len(err.strip().splitlines()) == 1


def test_cli_untagged_file_grips_an_inferred_middle_row_face(tmp_path, capsys):
    from fabkit.fold import FoldModel

    model = folded_grid_model(n_states=4, angles=[math.radians(30)] * 2)
    untagged = FoldModel.from_mesh(model.mesh().with_vertices(model.vertices_coords), frames=model.frames)
    object.__setattr__(untagged, "faces_data", {})
    seq = tmp_path / "untagged.fold"
    save_fold(untagged, seq)
    out = tmp_path / "p.json"
    rc = fabkit_main(["toolpath", str(seq), "--cell", str(CELL_FILES[0]), "-o", str(out), "-q"])
    # the middle column's moving faces; the grid is not held by one grip, so the check refuses it (exit 1)
    assert rc == 1 and Toolpath.load(out).source["grip_face"] in (6, 8)
    assert "FAILED: the check refuses every grip candidate" in capsys.readouterr().err
    rc = fabkit_main(["toolpath", str(seq), "--cell", str(CELL_FILES[0]), "-o", str(out), "--grip-face", "8", "-q"])
    assert rc == 0 and Toolpath.load(out).source["grip_face"] == 8
    out.unlink()
    rc = fabkit_main(["toolpath", str(seq), "--cell", str(CELL_FILES[0]), "-o", str(out), "--grip-face", "7"])
    assert rc == 2 and "folds nothing" in capsys.readouterr().err and not out.exists()


def test_one_state_is_not_a_fold():
    cell = load_cell(CELL_FILES[0])
    with pytest.raises(InputError, match="at least 2 fold states"):
        plan_toolpath(cell, np.eye(4)[None])
