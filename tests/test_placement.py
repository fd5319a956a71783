"""The clamp where the panel is clamped, and the cup's footprint on one planar region."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from holds_panels import trifold_pair, trifold_sequence

from fabkit.errors import InputError
from fabkit.grip_footprint import grip_candidates
from fabkit.mesh import PolyMesh
from fabkit.placement import check_clamp_footprint, choose_clamp_face, clamped_face_frame, place_on_clamp
from robot.cell import load_cell, parse_cell

ROOT = Path(__file__).resolve().parent.parent
JAW = np.array([[-0.012, -0.008], [0.012, -0.008], [0.012, 0.008], [-0.012, 0.008]])


def _permuted(mesh: PolyMesh, seed: int) -> tuple[PolyMesh, np.ndarray, np.ndarray]:
    """Vertices and faces renumbered, each face's vertex list rotated. Returns (mesh, vertex map old->new,
    face order new->old)."""
    rng = np.random.default_rng(seed)
    perm = rng.permutation(mesh.n_vertices)          # new vertex i = old perm[i]
    inv = np.argsort(perm)
    forder = rng.permutation(mesh.n_faces)
    faces = []
    for f in forder:
        ring = [int(inv[v]) for v in mesh.face(int(f))]
        k = int(rng.integers(len(ring)))
        faces.append(ring[k:] + ring[:k])
    fd = {k: np.asarray(v)[forder] for k, v in mesh.face_data.items()}
    return PolyMesh(mesh.vertices[perm], faces, face_data=fd), inv, forder


def test_face_frame_known_answer():
    th = 0.3
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    rect = np.array([[-0.05, -0.01], [0.05, -0.01], [0.05, 0.01], [-0.05, 0.01]]) @ R.T + [0.2, 0.1]
    V = np.column_stack([rect, np.zeros(4)])
    T = clamped_face_frame(V, [0, 1, 2, 3], panel_centroid=[1.0, 1.0])
    np.testing.assert_allclose(T[:2, 3], [0.2, 0.1], atol=1e-15)
    np.testing.assert_allclose(abs(T[:2, 0] @ R[:, 0]), 1.0, atol=1e-12)   # long axis
    assert T[:2, 0] @ (np.array([1.0, 1.0]) - [0.2, 0.1]) > 0                # toward the panel centroid
    np.testing.assert_allclose(T[:3, 2], [0, 0, 1])
    # any starting vertex gives the same frame
    np.testing.assert_allclose(clamped_face_frame(V, [2, 3, 0, 1], [1.0, 1.0]), T, atol=1e-14)


def test_the_demo_post_is_not_under_the_clamped_face_and_placement_fixes_it():
    flat, _ = trifold_pair()
    cell = load_cell(ROOT / "cells" / "ur5e_bench.toml")
    face = choose_clamp_face(flat, cell.clamp.footprint)
    assert face == trifold_sequence(12).fixed_face     # refold's clamped face
    ring = flat.face(face)
    old = check_clamp_footprint(flat.vertices, ring, face, cell.fixture, cell.clamp.pose, cell.clamp.footprint)
    assert not old.ok and old.outside_m > 0.02 and "leaves clamped face" in old.problems[0]
    fixture = place_on_clamp(flat.vertices, ring, cell.clamp.pose, flat.vertices.mean(0))
    new = check_clamp_footprint(flat.vertices, ring, face, fixture, cell.clamp.pose, cell.clamp.footprint)
    assert new.ok and new.outside_m == 0.0 and new.off_plane_m < 1e-12
    # 10 mm across the face's narrow side: the jaw leaves the face
    shifted = fixture.copy()
    shifted[:3, 3] += cell.clamp.pose[:3, :3] @ np.array([0.0, 0.010, 0.0])
    bad = check_clamp_footprint(flat.vertices, ring, face, shifted, cell.clamp.pose, cell.clamp.footprint)
    assert not bad.ok and bad.outside_area_m2 > 0
    lifted = fixture.copy()
    lifted[2, 3] += 0.002
    assert "off the plane" in check_clamp_footprint(flat.vertices, ring, face, lifted, cell.clamp.pose,
                                                    cell.clamp.footprint).problems[-1]


@pytest.mark.parametrize("seed", [1, 2])
def test_permuted_vertex_and_face_order_same_clamp_and_placement(seed):
    flat, _ = trifold_pair()
    clamp_pose = load_cell(ROOT / "cells" / "ur5e_bench.toml").clamp.pose
    face = choose_clamp_face(flat, JAW)
    fx = place_on_clamp(flat.vertices, flat.face(face), clamp_pose, flat.vertices.mean(0))
    pf, vmap, forder = _permuted(flat, seed)
    pface = choose_clamp_face(pf, JAW)
    assert forder[pface] == face
    pfx = place_on_clamp(pf.vertices, pf.face(pface), clamp_pose, pf.vertices.mean(0))
    np.testing.assert_allclose(pfx, fx, atol=1e-12)
    # untagged panel: geometry alone decides, the same way for both orders
    plain = PolyMesh(flat.vertices, flat.faces_list())
    pplain = PolyMesh(pf.vertices, pf.faces_list())
    assert forder[choose_clamp_face(pplain, JAW)] == choose_clamp_face(plain, JAW)


def test_no_face_holds_a_huge_jaw():
    flat, _ = trifold_pair()
    with pytest.raises(ValueError, match="no face holds"):
        choose_clamp_face(flat, JAW * 10)


def test_the_demo_grip_face_is_a_sliver_and_the_strip_region_holds_the_cup():
    seq = trifold_sequence(12)
    strip = np.asarray(seq.face_data["strip"])
    polys = np.asarray(seq.face_data["polygon"])
    wing = np.unique(polys[strip == 2])
    single = grip_candidates(seq, 0.035, max_bend=1e-9, faces=wing)   # one face at a time
    assert all(not c.ok for c in single) and 28 in [f for c in single for f in c.faces]
    c28 = next(c for c in single if 28 in c.faces)
    assert c28.inscribed_m < 0.012 and "70 mm cup does not fit" in c28.problem
    ranked = grip_candidates(seq, 0.035, faces=wing)
    assert ranked[0].ok and set(ranked[0].faces) == set(wing.tolist())
    assert ranked[0].inscribed_m > 0.035 and ranked[0].planarity_m < 0.5e-3
    every = grip_candidates(seq, 0.035)
    assert [c.ok for c in every] == [True, True, True]  # one region per strip (the rulings bend < 0.8 deg)
    with pytest.raises(ValueError):
        grip_candidates(seq, 0.0)


def _cell_doc():
    import tomllib

    return tomllib.loads((ROOT / "cells" / "ur5e_bench.toml").read_text())


@pytest.mark.parametrize("edit,message", [
    (lambda d: d["clamp"].__setitem__("footprint", [[0, 0], [1, 1]]), "clamp.footprint: expected a polygon"),
    (lambda d: d["clamp"].__setitem__("footprint", [[0, 0], [10, 0], [0, 10]]), "millimetres"),
    (lambda d: d["clamp"].__setitem__("footprint", [[0, 0], [0.01, 0], [0.02, 0]]), "no area"),
    (lambda d: d["clamp"].__setitem__("obstacle", "nope"), "clamp.obstacle"),
    (lambda d: d["clamp"].__setitem__("colour", 1), "clamp.colour: unknown key"),
    (lambda d: d["clamp"].pop("pose"), "clamp.pose: missing"),
    (lambda d: d["tool"].__setitem__("cup_radius", -0.01), "tool.cup_radius"),
])
def test_cell_clamp_errors_name_the_key(edit, message):
    d = _cell_doc()
    edit(d)
    with pytest.raises(InputError, match=message):
        parse_cell(d, "cells/x.toml")


def test_cell_without_clamp_still_loads():
    d = _cell_doc()
    d.pop("clamp")
    d["tool"].pop("cup_radius")
    cell = parse_cell(d, "x.toml")
    assert cell.clamp is None and cell.tool.cup_radius is None
