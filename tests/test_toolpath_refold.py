"""Acceptance: refolded reflect (one and two creases) and trifold panels are executable in both cells.

The panels go through the real pipeline (generate -> relax (trifold) -> unfold -> refold); every
waypoint's joint solution reproduces its pose by FK to 1e-9, no joint moves more than 5 deg between
waypoints of the fold move, one branch is kept, blends never overlap, and the fold stays clear of
singularities and joint-speed limits.
"""
import math
from pathlib import Path

import numpy as np
import pytest

from fabkit.cli import main as fabkit_main
from fabkit.frames import middle_row_frames
from fabkit.io.fold import load_fold
from robot import kinematics as K
from robot.cell import load_cell, pose_to_matrix
from robot.motion import blend_overlaps
from robot.toolpath import check_toolpath_kinematics, plan_panel

CELLS = Path(__file__).resolve().parent.parent / "cells"


@pytest.fixture(scope="module", params=["reflect", "reflect2", "trifold"])
def refolded(request, tmp_path_factory):
    """generate -> relax (trifold) -> unfold -> refold through the fabkit commands; the FOLD file."""
    name = request.param
    d = tmp_path_factory.mktemp(name)
    src = d / "panel.obj"
    extra = ["--creases", "2"] if name == "reflect2" else []
    assert fabkit_main(["generate", name.rstrip("2"), "-o", str(src), "-q", *extra]) == 0
    if name == "trifold":  # the generated trifold is not developable until relaxed
        relaxed = d / "relaxed.obj"
        assert fabkit_main(["relax", str(src), "-o", str(relaxed), "-q"]) == 0
        src = relaxed
    flat = d / "flat.obj"
    assert fabkit_main(["unfold", str(src), "-o", str(flat), "-q"]) == 0
    seq = d / "seq.fold"
    assert fabkit_main(["refold", str(flat), str(src), "-o", str(seq), "-q"]) == 0
    return name, seq, load_fold(seq)


@pytest.mark.parametrize("cell_file", ["ur5e_bench.toml", "ur10e_fold_table.toml"])
def test_refolded_panel_is_executable(refolded, cell_file):
    name, seq, model = refolded
    cell = load_cell(CELLS / cell_file)
    frames = middle_row_frames(model)
    res = plan_panel(cell, frames, source={"file": f"{name}.fold"})
    tp = res.toolpath
    chk = check_toolpath_kinematics(tp)
    assert chk["fk_pos_max"] <= 1e-9 and chk["fk_rot_max"] <= 1e-9, chk
    # independent FK per waypoint
    for w in tp.waypoints:
        dp, dr = K.pose_error(K.fk_tcp(cell.model, w["q"], cell.tool.tcp), pose_to_matrix(w["pose"]))
        assert dp <= 1e-9 and dr <= 1e-9
    ops = [w["op"] for w in tp.waypoints]
    Q = tp.joints
    fold_steps = [np.abs(Q[i] - Q[i - 1]).max() for i in range(1, len(ops)) if ops[i] in ("fold", "release")]
    assert len(fold_steps) >= model.n_frames - 1
    assert max(fold_steps) <= math.radians(5.0) + 1e-12
    lin = [i for i, w in enumerate(tp.waypoints) if w["move"] == "movel"]
    assert (K.branch_signs(cell.model, Q[lin]) == K.branch_signs(cell.model, Q[lin[0]])).all()
    r = np.array([w["r"] for w in tp.waypoints])
    assert chk["blend_overlaps"] == [] and blend_overlaps(tp.poses[:, :3], r).size == 0
    seg = np.linalg.norm(np.diff(tp.poses[:, :3], axis=0), axis=1)
    assert np.all(r[1:-1] <= 0.5 * np.minimum(seg[:-1], seg[1:]) + 1e-15) and r[-1] == 0
    # comfortably reachable: away from every singularity, joints well inside their speed limits
    assert res.min_singularity["elbow"] > 0.3 and res.min_singularity["wrist"] > 0.3
    assert res.min_singularity["shoulder_m"] > 0.1
    assert res.joint_speed_ratio < 0.5
    # the TCP stays above the table top and in front of the robot
    world = np.array([cell.robot.base_pose @ pose_to_matrix(p) for p in tp.poses])
    table = next(o for o in cell.obstacles if o.name in ("bench", "fold_table"))
    assert world[:, 2, 3].min() > table.pose[2, 3] + table.size[2] + 0.1


def test_toolpath_command_on_the_refold_file(refolded, tmp_path, capsys):
    name, seq, _ = refolded
    out, script = tmp_path / "path.json", tmp_path / "fold.script"
    rc = fabkit_main(["toolpath", str(seq), "--cell", str(CELLS / "ur10e_fold_table.toml"), "-o", str(out),
                      "--script", str(script), "-q"])
    assert rc == 0, capsys.readouterr().err
    from robot.toolpath import Toolpath

    tp = Toolpath.load(out)
    assert tp.source["file"] == "seq.fold" and tp.sha256 in script.read_text()
