"""Gripping from the back side: the cup's approach axis along +normal, its standoff measured behind
the design surface (the sheet's thickness), the side recorded inside PATH.json's hash, every face
tried on the front side before the back."""
import math

import numpy as np
import pytest

from fabkit.frames import middle_row_frames
from fabkit.sheet import back_face_offset, front_face_offset, sheet_of
from fold_fixtures import folded_grid_model
from robot.cell import load_cell, pose_to_matrix
from robot.grip_choice import grip_variants
from robot.toolpath import PlanOptions, plan_panel, tcp_targets
from pathlib import Path

CELL = Path(__file__).resolve().parent.parent / "cells" / "ur5e_bench.toml"


@pytest.fixture(scope="module")
def frames():
    return middle_row_frames(folded_grid_model(n_states=5, angles=[math.radians(60)] * 2, triangulate=True))


def test_back_side_tcp_is_behind_the_face_and_points_along_the_normal(frames):
    cell = load_cell(CELL)
    F = frames.of_face(int(frames.faces[-1]))
    front = tcp_targets(cell, F, PlanOptions(grip_standoff=0.001))
    back = tcp_targets(cell, F, PlanOptions(grip_standoff=0.002, grip_side="back"))
    Fb = cell.panel_to_base @ F
    n = Fb[:, :3, 2]                                           # front normal of the face, per state
    c = Fb[:, :3, 3]
    np.testing.assert_allclose(np.einsum("sk,sk->s", front["grip"][:, :3, 2], n), -1.0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("sk,sk->s", back["grip"][:, :3, 2], n), 1.0, atol=1e-12)
    np.testing.assert_allclose(front["grip"][:, :3, 3], c + 0.001 * n, atol=1e-12)
    np.testing.assert_allclose(back["grip"][:, :3, 3], c - 0.002 * n, atol=1e-12)
    np.testing.assert_allclose(back["approach"][:3, 3], c[0] - (0.002 + 0.08) * n[0], atol=1e-12)


def test_sheet_standoffs_by_design_surface():
    spec = sheet_of("5052-H32", "2mm")
    got = [(front_face_offset(spec, s), back_face_offset(spec, s)) for s in ("top", "mid", "bottom")]
    np.testing.assert_allclose(got, [(0.0, 0.002), (0.001, 0.001), (0.002, 0.0)], rtol=0, atol=1e-15)


def test_front_first_then_back_and_the_side_is_in_the_hash(frames):
    cell = load_cell(CELL)
    opts = PlanOptions()
    variants = grip_variants(opts, back_standoff=0.001)
    assert [(v.grip_side, v.approach_distance) for v in variants] == [
        ("front", pytest.approx(0.048)), ("front", pytest.approx(0.128)), ("back", 0.08)]
    assert all(v.grip_standoff == 0.001 for v in variants if v.grip_side == "back")
    seen = []

    def accept(res):  # refuses every front-side program, as the checker does for a 175 deg valley
        side = res.toolpath.extra["grip"].get("side", "front")
        seen.append(side)
        return None if side == "back" else "front refused"

    res = plan_panel(cell, frames, options=opts, variants=variants, accept=accept, source={"file": "grid.fold"})
    n_front = seen.index("back")
    assert set(seen[:n_front]) == {"front"} and n_front >= len(frames.faces) - 1  # every face's front first
    tp = res.toolpath
    assert tp.extra["grip"]["side"] == "back"
    doc = tp.to_json()
    del doc["grip"]["side"]
    from robot.toolpath import document_sha256

    assert document_sha256(doc) != tp.sha256                   # the side is inside the hash
    # the planned grip pose is the back-side TCP target
    w = next(w for w in tp.waypoints if w.op == "grip")
    F = frames.of_face(res.grip_face)
    tgt = tcp_targets(cell, F, PlanOptions(grip_side="back", grip_standoff=0.001))["grip"][0]
    n = (cell.panel_to_base @ F[0])[:3, 2]
    T = pose_to_matrix(w.pose)
    assert T[:3, 2] @ n == pytest.approx(1.0, abs=1e-9) and np.allclose(T[:3, 3], tgt[:3, 3], atol=1e-9)
    # the front side alone (accept passes): the program without back variants is the same program
    plain = plan_panel(cell, frames, options=opts, source={"file": "grid.fold"})
    both = plan_panel(cell, frames, options=opts, variants=grip_variants(opts, sides=("front",)),
                      source={"file": "grid.fold"})
    assert plain.toolpath.sha256 == both.toolpath.sha256 and "side" not in plain.toolpath.extra["grip"]


def test_the_grip_side_setting_chooses_the_side_for_cli_and_api(tmp_path):
    """`fabkit toolpath --grip-side` / `PlanSettings.grip_side`: back plans the back side only (the
    standoff behind the face), front never tries the back, anything else is refused naming the option."""
    import json

    from fabkit.errors import InputError
    from fabkit.io import save_fold
    from fabkit.toolpath_stage import PlanSettings, plan_fold_file

    fold = tmp_path / "grid.fold"
    save_fold(folded_grid_model(n_states=4, angles=[math.radians(60)] * 2), fold)
    with pytest.raises(InputError, match="sideways") as err:
        PlanSettings(grip_side="sideways").check()
    assert err.value.source == "--grip-side"
    back = plan_fold_file(fold, CELL, PlanSettings(grip_side="back"))
    front = plan_fold_file(fold, CELL, PlanSettings(grip_side="front"))
    assert back.ok and back.toolpath.extra["grip"]["side"] == "back"
    assert front.ok and "side" not in front.toolpath.extra["grip"]
    assert all(t[1] is None or "back" not in str(t[1]) for t in front.plan.tried)
    out = tmp_path / "path.json"
    from fabkit.cli import main

    # the back grip of this grid meets the arm: the check refuses it, the CLI exits 1 and keeps the
    # program for `fabkit check`, the same the API returns
    assert "collision" in back.refused_by_check
    assert main(["toolpath", str(fold), "--cell", str(CELL), "-o", str(out), "--grip-side", "back", "-q"]) == 1
    assert json.loads(out.read_text())["sha256"] == back.toolpath.sha256
