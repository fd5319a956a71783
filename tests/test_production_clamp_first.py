"""A production set-up whose clamp footprint leaves the clamped face is refused before it is planned,
with the problem the full check names for it (the same verdict, without the plan and the check)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from vault_panels import first_vault_panel

from fabkit.panels.production import ProductionOptions, program_task, refold_and_program, stock

ROOT = Path(__file__).resolve().parents[1]
CELL = ROOT / "cells" / "ur5e_bench.toml"
JAW = "footprint = [[-0.012, -0.008], [0.012, -0.008], [0.012, 0.008], [-0.012, 0.008]]"


@pytest.fixture(scope="module")
def task():
    from sim.production import program_panel

    panel, geometry = first_vault_panel()
    return program_task(panel, geometry, ProductionOptions(), CELL.read_text(), CELL.name, stock(), program_panel)


@pytest.fixture(scope="module")
def panel(task):
    res = refold_and_program(task)
    assert res["stage"] is None, res["reason"]
    return res


@pytest.mark.slow
def test_a_jaw_off_the_face_is_refused_before_planning_as_the_check_refuses_it(panel, monkeypatch):
    import sim.production as production

    text = CELL.read_text()
    assert JAW in text
    wide = text.replace(JAW, "footprint = [[-0.06, -0.04], [0.06, -0.04], [0.06, 0.04], [-0.06, 0.04]]")
    args = (panel["fold"], "p_refold.fold", wide, CELL.name, 1.0e-3)
    first = production.program_panel(*args, grip_face=panel["grip_face"])
    assert first["stage"] == "check" and first["toolpath"] is None and first["check"] is None
    assert "leaves clamped face" in first["unclampable"] and first["unclampable"] in first["reason"]
    # without the clamp check first: planned and checked in full, and the check names the same problem
    monkeypatch.setattr(production, "clamp_refusal", lambda *a: None)
    full = production.program_panel(*args, grip_face=panel["grip_face"])
    assert full["stage"] == "check" and full["check"] is not None
    details = [q["detail"] for q in full["check"]["problems"] if q["kind"] == "holds"]
    assert first["unclampable"] in details


@pytest.mark.slow
def test_the_bench_jaw_on_the_panel_is_not_refused(panel, tmp_path):
    from sim.production import clamp_refusal

    path = tmp_path / "p_refold.fold"
    path.write_text(panel["fold"])
    from robot.cell import load_cell

    assert clamp_refusal(path, load_cell(CELL)) is None
    assert panel["check"]["ok"] and not any("clamp" in q["detail"] for q in panel["check"]["problems"])


def _permuted_task(task: dict, seed: int):
    """The task with its vertices renumbered, its faces reordered and each face's ring rotated.
    Returns (task, vertex map old -> new, face order new -> old)."""
    rng = np.random.default_rng(seed)
    n = len(task["uv"])
    perm = rng.permutation(n)                       # new vertex i = old perm[i]
    inv = np.argsort(perm)
    faces = np.asarray(task["faces"])
    forder = rng.permutation(len(faces))
    rows = []
    for f in forder:
        ring = inv[faces[f]]
        rows.append(np.roll(ring, int(rng.integers(len(ring)))))
    out = {**task, "uv": np.asarray(task["uv"])[perm], "relaxed": np.asarray(task["relaxed"])[perm],
           "faces": np.array(rows), "face_data": {k: np.asarray(v)[forder] for k, v in task["face_data"].items()}}
    return out, inv, forder


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_the_jaw_pose_on_the_clamp_region_is_the_same_for_a_permuted_panel(task, seed, tmp_path):
    """A 24 x 50 mm jaw on this vault's 45 mm wide clamped face lies on its neighbours too (the clamp
    region): the same pose, to round-off, whatever the vertex and face order."""
    import dataclasses

    from fabkit.io.fold import load_fold
    from fabkit.panels.production_refold import _refold, panel_setups
    from robot.cell import load_cell
    from robot.panel_placement import placement_for

    cell = load_cell(CELL)
    wide = np.array([[-0.012, -0.025], [0.012, -0.025], [0.012, 0.025], [-0.012, 0.025]])
    cell = dataclasses.replace(cell, clamp=dataclasses.replace(cell.clamp, footprint=wide))
    got = []
    for t, inv, forder in ((task, None, None), _permuted_task(task, seed)):
        setup = panel_setups(t)[0]
        _, text, why = _refold(t, setup)
        assert text is not None, why
        path = tmp_path / f"p{len(got)}.fold"
        path.write_text(text)
        pl = placement_for(cell, load_fold(path))
        back = (lambda f: int(f)) if forder is None else (lambda f, o=forder: int(o[f]))
        got.append((back(pl["clamped_face"]), sorted(back(f) for f in pl["jaw"]["faces"]), pl))
    (f0, j0, p0), (f1, j1, p1) = got
    assert f0 == f1 and j0 == j1 and len(j0) > 1                  # the jaw shares the face with its neighbours
    assert p0["jaw"]["yaw_deg"] == pytest.approx(p1["jaw"]["yaw_deg"], abs=1e-6) and p0["jaw"]["slack_mm"] > 0
    # the panel frame is the flat pattern turned to the set-up (the same for both), so the fixtures agree
    np.testing.assert_allclose(p0["fixture"], p1["fixture"], atol=1e-9)


@pytest.mark.slow
def test_the_check_refuses_a_jaw_whose_centre_is_off_the_clamped_face(task, tmp_path):
    """The jaw moved onto a neighbour of the region: its centre leaves the clamped face (the states
    are in that face's frame) and the check names it."""
    import dataclasses

    from shapely.geometry import Polygon

    from fabkit.io.fold import load_fold
    from fabkit.panels.production_refold import _refold, panel_setups
    from robot.cell import load_cell, pose_to_matrix
    from robot.panel_placement import clamped_face_ring, footprint_check, placed_cell, placement_for

    cell = load_cell(CELL)
    wide = np.array([[-0.012, -0.025], [0.012, -0.025], [0.012, 0.025], [-0.012, 0.025]])
    cell = dataclasses.replace(cell, clamp=dataclasses.replace(cell.clamp, footprint=wide))
    setup = panel_setups(task)[0]
    _, text, _ = _refold(task, setup)
    (tmp_path / "p.fold").write_text(text)
    model = load_fold(tmp_path / "p.fold")
    pl = placement_for(cell, model)
    face = pl["clamped_face"]
    assert footprint_check(model, placed_cell(cell, pl), [face]).ok
    fx = pose_to_matrix(pl["fixture"])
    centre = (np.linalg.inv(fx) @ cell.clamp.pose @ [0, 0, 0, 1.0])[:2]
    other = next(f for f in pl["jaw"]["faces"] if f != face)
    target = np.asarray(Polygon(clamped_face_ring(model, other)).representative_point().coords[0])
    shift = np.eye(4)
    shift[:2, 3] = centre - target                       # the neighbour's point comes under the jaw's centre
    moved = dataclasses.replace(cell, fixture=fx @ shift)
    res = footprint_check(model, moved, [face])
    assert not res.ok and any(f"mm off clamped face {face}" in p for p in res.problems), res.problems
