"""Refold acceptance: every state is a rigid fold, the last is the target, driven angles move linearly."""
import json
import re

import numpy as np
import pytest

from fabkit.errors import InputError
from fabkit.mesh import PolyMesh
from fabkit.refold import NotAFoldError, RefoldSolver, refold
from fabkit.refold.sequence import build_schedule, load_drive_file, middle_row_hinges
from fabkit.refold.triangulate import CREASE, DIAGONAL
from refold_panels import DEG, reflect_pair, straight_crease_pair

TOL_STATE = 1e-9     # loop residual [rad] and relative edge-length error at every state
TOL_TARGET = 1e-6    # last state to target, relative to the panel size


def assert_acceptance(seq, *, linear_driven=True):
    assert seq.converged.all(), seq.notes
    assert seq.residual.max() <= TOL_STATE
    assert seq.edge_length_error.max() <= TOL_STATE
    assert seq.corner_mismatch.max() <= TOL_STATE * seq.panel_size
    assert seq.target_distance <= TOL_TARGET * seq.panel_size
    np.testing.assert_array_equal(seq.angles[0], 0.0)
    np.testing.assert_allclose(seq.angles[-1], seq.target_angles, atol=1e-9)
    # monotone from 0 to the target on every crease hinge
    crease = np.flatnonzero(seq.edge_kind == "crease")
    steps = np.diff(seq.angles[:, crease], axis=0) * np.sign(seq.target_angles[crease])
    assert steps.min() >= -1e-12
    if linear_driven:
        frac = np.linspace(0, 1, seq.n_states)
        np.testing.assert_allclose(seq.angles[:, seq.driven], frac[:, None] * seq.target_angles[seq.driven],
                                   atol=1e-14)
    assert seq.intersections.max() == 0


@pytest.mark.parametrize("n_creases", [1, 2])
def test_reflect_panel_refolds_exactly(n_creases):
    flat, target = reflect_pair(n_creases, columns=12, rows=3)
    seq = refold(flat, target, frames=8)
    assert seq.n_states == 8
    assert len(seq.driven) == n_creases  # one middle-row crease hinge per crease
    assert np.all(seq.edge_kind[seq.driven] == "crease")
    assert_acceptance(seq)
    # the fixed face is the first strip's middle-row face (one end: the grip takes the other) and
    # stays at its flat position
    fixed = seq.fixed_face
    assert flat.face_data["middle"][fixed] == 1
    assert flat.face_data["strip"][fixed] == 0
    tri = seq.tris[seq.fixed_triangle]
    for s in range(seq.n_states):
        np.testing.assert_array_equal(seq.positions[s][tri], flat.vertices[tri])


def test_trifold_relaxed_and_unfolded_refolds(tmp_path):
    """The real pipeline: generate trifold -> relax -> unfold -> refold."""
    from fabkit.cli import main
    from fabkit.io.obj import load_obj

    src, relaxed, flatp = tmp_path / "tri.obj", tmp_path / "relaxed.obj", tmp_path / "flat.obj"
    assert main(["generate", "trifold", "-o", str(src), "-q"]) == 0
    assert main(["relax", str(src), "-o", str(relaxed), "-q"]) == 0
    assert main(["unfold", str(relaxed), "-o", str(flatp), "-q"]) == 0
    flat, target = load_obj(flatp), load_obj(relaxed)
    seq = refold(flat, target, frames=10)
    assert len(seq.driven) == 2
    assert_acceptance(seq)


def test_straight_crease_all_hinges_linear():
    """Known answer: a straight crease folds rigidly with every hinge at t * angle, nothing else moving."""
    flat, target = straight_crease_pair(100 * DEG)
    seq = refold(flat, target, frames=5, drive="all")
    assert_acceptance(seq)
    t = np.linspace(0, 1, 5)
    np.testing.assert_allclose(seq.angles, t[:, None] * seq.target_angles[None, :], atol=1e-12)
    crease = seq.edge_kind == "crease"
    np.testing.assert_allclose(seq.target_angles[crease], 100 * DEG, atol=1e-13)


def test_drive_all_creases_and_steps():
    flat, target = reflect_pair(2, columns=8, rows=2)
    seq = refold(flat, target, frames=5, drive="all")
    assert len(seq.driven) == 2 * 8
    assert_acceptance(seq)
    seq2 = refold(flat, target, frames=5, steps="crease1,crease0")
    assert seq2.n_states == 1 + 2 * 4
    np.testing.assert_array_equal(seq2.step, [-1, 0, 0, 0, 0, 1, 1, 1, 1])
    assert seq2.converged.all() and seq2.residual.max() <= TOL_STATE
    assert seq2.edge_length_error.max() <= TOL_STATE
    assert seq2.target_distance <= TOL_TARGET * seq2.panel_size
    row = {int(seq2.edges[e][0]): e for e in seq2.driven}
    first = [e for e in seq2.driven if np.any(seq2.angles[4, e] != 0)]
    assert len(first) == 1  # only the crease-1 hinge has moved after the first step
    assert np.all(seq2.angles[:5, np.setdiff1d(seq2.driven, first)] == 0.0)
    assert row  # non-empty


def test_custom_drive_file_with_vertex_pairs_and_steps(tmp_path):
    flat, target = reflect_pair(2, columns=6, rows=2)
    solver = RefoldSolver(flat, target)
    mid = middle_row_hinges(solver.panel)
    pairs = [solver.panel.edges[e].tolist()[::-1] for e in mid]  # any vertex order
    f = tmp_path / "drive.json"
    f.write_text(json.dumps({"steps": [[pairs[0]], [pairs[1]]]}))
    driven, steps = load_drive_file(f, flat, solver.panel)
    np.testing.assert_array_equal(driven, np.sort(mid))
    assert [len(s) for s in steps] == [1, 1]
    F, step_of_state = build_schedule(solver.panel, driven, steps, 3)
    seq = solver.solve(F, driven, step_of_state)
    assert seq.converged.all() and seq.target_distance <= TOL_TARGET * seq.panel_size
    # polygon edge ids work too
    ids = [int(solver.panel.edge_poly_edge[e]) for e in mid]
    f.write_text(json.dumps(ids))
    driven2, steps2 = load_drive_file(f, flat, solver.panel)
    np.testing.assert_array_equal(driven2, np.sort(mid))
    assert steps2 is None


@pytest.mark.parametrize("content, needle", [
    ("[[0, 1, 2]]", "not a [u, v] pair"),
    ("[99999]", "does not exist"),
    ("[[0, 50]]", "not joined by an edge"),
    ('{"drive": [], "extra": 1}', "unknown keys"),
    ("[]", "no edges to drive"),
    ("{not json", "not a readable JSON"),
    ('["a"]', "neither an edge id"),
])
def test_bad_drive_files(tmp_path, content, needle):
    flat, target = reflect_pair(1, columns=4, rows=2)
    solver = RefoldSolver(flat, target)
    f = tmp_path / "d.json"
    f.write_text(content)
    with pytest.raises(InputError, match=re.escape(needle)):
        load_drive_file(f, flat, solver.panel)


def test_boundary_edge_cannot_be_driven(tmp_path):
    flat, target = reflect_pair(1, columns=4, rows=2)
    solver = RefoldSolver(flat, target)
    b = int(np.flatnonzero(solver.panel.edge_kind == 0)[0])
    f = tmp_path / "d.json"
    f.write_text(json.dumps([solver.panel.edges[b].tolist()]))
    with pytest.raises(InputError, match="boundary"):
        load_drive_file(f, flat, solver.panel)


def test_not_a_fold_names_the_worst_edge():
    flat, target = reflect_pair(1, columns=6, rows=2)
    V = np.array(target.vertices)
    V[10] += [0.0, 0.0, 0.01]  # stretches the edges at vertex 10
    bad = PolyMesh(V, target.faces_list(), face_data=target.face_data)
    with pytest.raises(NotAFoldError) as info:
        refold(flat, bad, frames=3)
    assert 10 in info.value.edge and info.value.relative > 1e-3
    assert "not a fold of the flat pattern" in str(info.value) and str(tuple(info.value.edge)) in str(info.value)


def test_pair_and_flatness_checks():
    flat, target = reflect_pair(1, columns=6, rows=2)
    with pytest.raises(InputError, match="not a flat pattern"):
        RefoldSolver(target, target)
    other, _ = reflect_pair(1, columns=5, rows=2)
    with pytest.raises(InputError, match="same panel"):
        RefoldSolver(other, target)
    faces = target.faces_list()
    faces[0] = faces[0][1:] + faces[0][:1]  # same quad, different first corner
    with pytest.raises(InputError, match="same faces"):
        RefoldSolver(flat, PolyMesh(target.vertices, faces))
    mirrored = PolyMesh(np.asarray(flat.vertices) * [1, -1, 1], [f[::-1] for f in flat.faces_list()])
    # mirrored and re-oriented is fine; mirrored alone is a clockwise pattern
    flipped = PolyMesh(np.asarray(flat.vertices) * [1, -1, 1], flat.faces_list(), validate=False)
    with pytest.raises(InputError, match="clockwise"):
        RefoldSolver(flipped, target)
    assert mirrored.n_faces == flat.n_faces
    with pytest.raises(InputError, match="fixed face"):
        RefoldSolver(flat, target, fixed_face=10_000)


def test_untagged_panel_refolds_like_the_tagged_one_and_overdriving_is_reported():
    flat, target = reflect_pair(1, columns=7, rows=2)
    bare_flat = PolyMesh(flat.vertices, flat.faces_list())
    bare_target = PolyMesh(target.vertices, target.faces_list())
    tagged = RefoldSolver(flat, target)
    solver = RefoldSolver(bare_flat, bare_target)
    assert solver.structure.source["creases"] == "inferred"
    np.testing.assert_array_equal(solver.panel.edge_kind, tagged.panel.edge_kind)
    d, notes = solver.driven_hinges("middle-row")
    np.testing.assert_array_equal(d, tagged.driven_hinges("middle-row")[0])   # the odd middle column: no tie
    assert solver.fixed_face == tagged.fixed_face and any("inferred" in n for n in notes)
    assert_acceptance(refold(bare_flat, bare_target, frames=4))
    # driving every crease and ruling linearly over-constrains a curved crease (no rigid fold has those
    # angles): the converged states are kept and the failure names the worst hinge
    every = np.flatnonzero((solver.panel.edge_kind == CREASE) | (solver.panel.edge_kind == 2))
    seq = refold(bare_flat, bare_target, frames=4, drive=every)
    assert not seq.complete and 1 <= seq.failed_state < 4 and seq.n_states == seq.failed_state
    assert seq.converged.all() and seq.residual.max() <= TOL_STATE
    assert re.search(r"worst hinge \(\d+, \d+\)", seq.failure) and seq.failure in seq.problems(1e-6)
    assert np.isnan(seq.target_distance)
    from fabkit.refold.export import to_fold_model

    model = to_fold_model(seq)           # no NaN reaches the file, every written state converged
    assert model.n_frames == seq.n_states and model.file_data["fabkit:failed_state"] == seq.failed_state
    # the straight crease untagged: drive all works and is exact
    f2, t2 = straight_crease_pair(40 * DEG)
    seq2 = refold(PolyMesh(f2.vertices, f2.faces_list()), PolyMesh(t2.vertices, t2.faces_list()), frames=3,
                  drive="all")
    assert_acceptance(seq2)


def test_schedule_needs_two_frames_and_every_driven_hinge_in_a_step():
    flat, target = reflect_pair(2, columns=4, rows=2)
    solver = RefoldSolver(flat, target)
    d, _ = solver.driven_hinges()
    with pytest.raises(InputError, match="at least 2 frames"):
        build_schedule(solver.panel, d, None, 1)
    with pytest.raises(InputError, match="in no step"):
        build_schedule(solver.panel, d, [d[:1]], 3)
    with pytest.raises(InputError, match="creaseK or stripK"):
        refold(flat, target, steps="fold0")
    with pytest.raises(InputError, match="no driven crease hinges left"):
        refold(flat, target, steps="crease0,crease0")


def test_newton_chord_and_full_newton_both_meet_acceptance():
    flat, target = reflect_pair(2, columns=10, rows=3)
    seqs, factorizations = [], []
    for chord in (True, False):
        s = RefoldSolver(flat, target, chord=chord)
        d, _ = s.driven_hinges()
        F, st = build_schedule(s.panel, d, None, 6)
        seqs.append(s.solve(F, d, st))
        factorizations.append(s.linear_solver.factorizations)
        assert_acceptance(seqs[-1])
    # the chord steps pay off: about one factorisation per state instead of one per Newton step
    assert factorizations[0] <= seqs[0].n_states - 1 < factorizations[1]
    # different points of the same manifold only where closure leaves freedom: close, same ends
    assert np.abs(seqs[0].angles - seqs[1].angles).max() < 1e-3
    np.testing.assert_array_equal(seqs[0].angles[[0, -1]], seqs[1].angles[[0, -1]])


def test_strip_steps_fold_the_creases_bounding_each_strip_in_order():
    flat, target = reflect_pair(2, columns=8, rows=2)
    seq = refold(flat, target, frames=4, steps="strip0,strip1")  # strip0: crease 0; strip1: crease 1 (left)
    assert seq.converged.all() and seq.residual.max() <= TOL_STATE
    assert seq.target_distance <= TOL_TARGET * seq.panel_size
    crease_row = seq.edge_crease[seq.driven]
    first = seq.driven[crease_row == 0]
    second = seq.driven[crease_row == 1]
    np.testing.assert_allclose(seq.angles[3, first], seq.target_angles[first], atol=1e-14)
    np.testing.assert_array_equal(seq.angles[:4, second], 0.0)
    np.testing.assert_allclose(seq.angles[4:, second] / seq.target_angles[second], [[1 / 3], [2 / 3], [1.0]],
                               atol=1e-14)


def test_planar_quads_stay_planar_and_freeing_their_diagonals_also_folds():
    flat, target = reflect_pair(2, columns=10, rows=3)
    seqs = {}
    for hold in (True, False):
        s = RefoldSolver(flat, target, hold_planar_quads=hold)
        diagonals = np.flatnonzero(s.panel.edge_kind == DIAGONAL)
        assert len(s.held) == (len(diagonals) if hold else 0)
        d, _ = s.driven_hinges()
        F, st = build_schedule(s.panel, d, None, 6)
        seqs[hold] = seq = s.solve(F, d, st)
        assert_acceptance(seq)
        assert not seq.notes
    held, free = seqs[True], seqs[False]
    # held: every diagonal sits exactly at its scheduled angle (a fraction of ~1e-15), i.e. the quads stay planar
    np.testing.assert_array_equal(held.angles[:, diagonals], (held.fractions * held.target_angles)[:, diagonals])
    assert np.abs(held.angles[:, diagonals]).max() < 1e-13
    # free: the minimum-norm steps bend the quads a little on the way, and both end exactly at the target
    assert np.abs(free.angles[:, diagonals]).max() > 1e-8
    np.testing.assert_array_equal(held.angles[-1], free.angles[-1])
