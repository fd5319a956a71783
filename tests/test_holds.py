"""Holds: do the clamp and grippers fix the panel? Known answers on the demo tri-fold, a two-crease
reflect panel and a straight-crease letter fold."""
from __future__ import annotations

import numpy as np
import pytest
from holds_panels import letter_pair, reflect_two_crease_pair, trifold_pair, trifold_sequence

from fabkit.holds import HoldModel, crease_rows, hold_analysis, hold_matrix, holds_along
from fabkit.refold import refold


def _middle_faces(flat):
    mid = np.flatnonzero(np.asarray(flat.face_data["middle"]) != 0)
    strip = np.asarray(flat.face_data["strip"])[mid]
    return {int(s): int(f) for s, f in zip(strip, mid)}


@pytest.fixture(scope="module")
def trifold():
    flat, _ = trifold_pair()
    seq = trifold_sequence(12)
    return flat, seq, HoldModel.from_sequence(seq)


def test_demo_program_leaves_the_other_wing_free(trifold):
    """Clamp the middle strip's face, grip one outer strip (the demo's program): crease 0 is free."""
    flat, seq, model = trifold
    mids = _middle_faces(flat)
    assert seq.fixed_face == mids[1]
    for s in range(seq.n_states):
        r = hold_analysis(model, seq.angles[s], [mids[1], mids[2]])
        assert not r.ok
        assert r.unheld_creases == (0,)
        assert "crease 0" in r.problems[0] and "folded by nothing held" in r.problems[0]
        if s > 0:  # first-order rigid all the same: the wing hangs on the rigid-fold coupling alone
            assert r.nullity == 0 and r.sigma_min < 0.01


def test_trifold_with_both_wings_held_is_determined(trifold):
    flat, seq, model = trifold
    mids = _middle_faces(flat)
    reports = holds_along(model, seq.angles, [mids[1], mids[0], mids[2]], between=1)
    assert len(reports) == 2 * seq.n_states - 1
    for s, r in reports:
        assert r.ok, (s, r.problems)
        assert r.unheld_creases == ()
        if s > 0:
            assert r.nullity == 0 and r.sigma_min > 0.01  # 1e6 x the 1e-8 tolerance


def test_clamp_alone_names_both_creases_and_the_one_mechanism(trifold):
    flat, seq, model = trifold
    r = hold_analysis(model, seq.angles[6], [seq.fixed_face])
    assert r.unheld_creases == (0, 1) and r.free_creases == (0, 1)
    assert r.nullity == 1 and r.sigma_zero < 1e-12  # the curved-crease tri-fold is a 1-DOF mechanism
    assert not r.flat and not r.ok


def test_reflect_two_creases_known_answers():
    flat, target = reflect_two_crease_pair()
    seq = refold(flat, target, frames=6)
    model = HoldModel.from_sequence(seq)
    mids = _middle_faces(flat)
    one = hold_analysis(model, seq.angles[3], [mids[1], mids[0]])
    assert one.unheld_creases == (1,) and not one.ok and "crease 1" in one.problems[0]
    for s in range(seq.n_states):
        assert hold_analysis(model, seq.angles[s], list(mids.values())).ok


def test_straight_creases_are_free_first_order_without_a_grip():
    """Straight creases fold independently: the rank test itself names the free crease."""
    flat, target = letter_pair(120.0)
    strip = np.asarray(flat.face_data["strip"])
    seq = refold(flat, target, frames=5, drive="all", fixed_face=int(np.flatnonzero(strip == 1)[0]))
    model = HoldModel.from_sequence(seq)
    wing0 = int(np.flatnonzero(strip == 0)[0])
    wing2 = int(np.flatnonzero(strip == 2)[0])
    r = hold_analysis(model, seq.angles[2], [seq.fixed_face, wing0])
    assert r.nullity == 1 and r.free_creases == (1,) and r.unheld_creases == (1,)
    assert set(r.free_hinges) == set(model.rows[1].tolist())
    assert any("can still move" in p and "crease 1" in p for p in r.problems)
    for s, rep in holds_along(model, seq.angles, [seq.fixed_face, wing0, wing2], between=2):
        assert rep.ok and rep.nullity == 0, s
    # every ruling a hinge: the outer columns flap about straight lines of mesh edges
    loose = HoldModel.from_sequence(seq, lock_flat_rulings=False)
    r = hold_analysis(loose, seq.angles[2], [seq.fixed_face, wing0, wing2])
    assert r.nullity > 0 and not r.ok and r.free_creases == ()


def test_hold_rows_are_the_derivative_of_the_held_face_pose(trifold):
    """The twist rows against finite differences of refold's face positions."""
    from fabkit.refold.geometry import vertex_positions

    flat, seq, model = trifold
    rho = seq.angles[6]
    face = _middle_faces(flat)[2]
    tris = model.triangles_of([seq.fixed_face, face])
    A = hold_matrix(model, rho, tris[[0, -1]])
    H = A[-6:]                       # the held face's twist rows over the unlocked hinges
    rng = np.random.default_rng(3)
    d = np.zeros_like(rho)
    d[model.hinges] = rng.standard_normal(len(model.hinges))
    h = 1e-7
    Vp = vertex_positions(model.tree, model.flat_vertices, rho + h * d)
    Vm = vertex_positions(model.tree, model.flat_vertices, rho - h * d)
    V0 = vertex_positions(model.tree, model.flat_vertices, rho)
    tri = model.tris[tris[-1]]
    vel = (Vp[tri] - Vm[tri]) / (2 * h)          # point velocities of the held triangle
    tw = H @ d[model.hinges]
    pred = np.cross(tw[:3], V0[tri]) + tw[3:] * model.panel_size
    np.testing.assert_allclose(pred, vel, atol=1e-6 * np.abs(vel).max())


def test_permuted_vertex_order_gives_the_same_verdict():
    from fabkit.mesh import PolyMesh

    flat, target = reflect_two_crease_pair()
    rng = np.random.default_rng(0)
    perm = rng.permutation(flat.n_vertices)
    inv = np.argsort(perm)
    fperm = rng.permutation(flat.n_faces)
    faces = [[int(inv[v]) for v in flat.face(int(f))] for f in fperm]
    fd = {k: np.asarray(v)[fperm] for k, v in flat.face_data.items()}
    pf = PolyMesh(flat.vertices[perm], faces, face_data=fd)
    pt = PolyMesh(target.vertices[perm], faces, face_data=fd)
    seq = refold(pf, pt, frames=4)
    model = HoldModel.from_sequence(seq)
    mids = _middle_faces(pf)
    r = hold_analysis(model, seq.angles[2], [mids[1], mids[2]])
    assert r.unheld_creases == (0,) and not r.ok
    assert hold_analysis(model, seq.angles[2], list(mids.values())).ok


def test_bad_input():
    flat, target = reflect_two_crease_pair()
    seq = refold(flat, target, frames=3)
    model = HoldModel.from_sequence(seq)
    with pytest.raises(ValueError, match="no held faces"):
        hold_analysis(model, seq.angles[1], [])
    with pytest.raises(ValueError, match="not a face"):
        hold_analysis(model, seq.angles[1], [10_000])
    assert crease_rows(np.full(5, -1), np.array(["crease"] * 5)) == {}


def test_second_state_of_the_unheld_wing():
    """Reflect panel: the wing beyond the unheld crease has an exact second state with the same holds
    (the crease unfolded); on the relaxed tri-fold the nearest one misses loop closure slightly."""
    flat, target = reflect_two_crease_pair()
    seq = refold(flat, target, frames=4)
    model = HoldModel.from_sequence(seq)
    mids = _middle_faces(flat)
    r = hold_analysis(model, seq.angles[3], [mids[1], mids[2]], find_second_states=True)
    (x,) = r.second_states
    assert x.row == 0 and x.exact and x.residual < 1e-12
    assert abs(x.crease_deg[0]) < 1e-6 and abs(x.crease_deg[1]) < 1e-6 and x.wing_move_m > 0.2
    assert "a second state with the same holds" in r.problems[0]
    assert r.to_json()["second_states"][0]["exact"] is True


def test_trifold_nearest_other_state(trifold):
    flat, seq, model = trifold
    mids = _middle_faces(flat)
    r = hold_analysis(model, seq.angles[-1], [mids[1], mids[2]], find_second_states=True)
    (x,) = r.second_states
    assert not x.exact and x.residual < 1e-3            # the mirror state: edge lengths kept to 4e-5
    assert 0.07 < x.wing_move_m < 0.09 and max(abs(v) for v in x.crease_deg) < 1.0
    assert "nearest other state" in r.problems[0]


def test_same_verdicts_from_the_fold_file(trifold, tmp_path):
    """The check reads FOLD files: the model rebuilt from one gives the sequence's verdicts."""
    from fabkit.hold_model_fold import hold_model_from_fold
    from fabkit.io.fold import load_fold, save_fold
    from fabkit.refold.export import to_fold_model

    flat, seq, model = trifold
    path = tmp_path / "seq.fold"
    save_fold(to_fold_model(seq), path)
    fmodel, angles = hold_model_from_fold(load_fold(path))
    np.testing.assert_allclose(angles, seq.angles, atol=1e-9)
    mids = _middle_faces(flat)
    for held in ([mids[1], mids[2]], list(mids.values())):
        a = hold_analysis(model, seq.angles[5], held)
        b = hold_analysis(fmodel, angles[5], held)
        assert (a.ok, a.unheld_creases, a.nullity) == (b.ok, b.unheld_creases, b.nullity)
