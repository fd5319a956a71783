"""Panel structure from geometry: creases exactly the true crease edges, M/V right, invariant to
vertex and face order, no false creases on faceted cylinders or from noise; tags win."""
import numpy as np
import pytest

from fabkit.measures import dihedral_angles
from fabkit.structure import panel_structure
from structure_panels import (cylinder_strip, noisy, plain, reflect_tagged, shuffled, triangulated,
                              true_creases)

CASES = [(1, 30.0), (1, 90.0), (1, 175.0), (2, 60.0), (2, 120.0), (2, 175.0)]


@pytest.mark.parametrize("n,fold", CASES)
@pytest.mark.parametrize("variant", ["exact", "noise"])
def test_inferred_creases_are_the_true_crease_edges(n, fold, variant):
    tagged = reflect_tagged(n, fold)
    mesh = plain(tagged) if variant == "exact" else noisy(plain(tagged), 0.01, seed=n)
    s = panel_structure(mesh)
    truth = true_creases(tagged)
    assert np.array_equal(s.crease, truth)
    assert s.n_strips == n + 1 and s.source["creases"] == "inferred"
    # M/V: the preset folds crease 0 valley and crease 1 mountain; each crease row is one letter
    ef = tagged.edge_faces[truth]
    preset_row = np.minimum(tagged.face_data["strip"][ef[:, 0]], tagged.face_data["strip"][ef[:, 1]])
    assert np.array_equal(s.assignment[truth], np.where(preset_row == 0, "V", "M"))
    for r in range(n):
        assert len(set(s.assignment[s.crease_row == r])) == 1
    assert len(s.middle_row) == n + 1 and sorted(s.strip[s.middle_row].tolist()) == list(range(n + 1))
    assert s.clamp_face in s.middle_row and s.clamp_face not in s.grip_faces
    assert len(s.grip_faces) == n and len(s.middle_creases) >= n


def test_triangulated_quads_give_the_same_creases():
    tagged = reflect_tagged(2, 60.0)
    tri = triangulated(plain(tagged))
    s = panel_structure(tri)
    truth_pairs = {tuple(e) for e in tagged.edges[true_creases(tagged)].tolist()}
    assert {tuple(e) for e in tri.edges[s.crease].tolist()} == truth_pairs
    assert s.n_strips == 3


def test_crease_folded_near_180_stays_one_assignment():
    tagged = reflect_tagged(1, 178.0, columns=30, skew=0.05)
    truth = true_creases(tagged)
    raw = dihedral_angles(tagged)[truth]
    assert (raw < 0).any() and (raw > 0).any()          # the measured sign flips at one end
    for mesh in (plain(tagged), noisy(plain(tagged), 1e-3)):
        s = panel_structure(mesh)
        assert np.array_equal(s.crease, truth)
        assert set(s.assignment[truth]) == {"V"}
        assert np.all(s.fold_angle[truth] > np.radians(165))
    assert set(panel_structure(tagged).assignment[truth]) == {"V"}   # tagged panels too


@pytest.mark.parametrize("columns,jitter", [(12, 0.0), (10, 0.17), (13, 0.17), (40, 0.0)])
def test_faceted_cylinder_has_no_crease(columns, jitter):
    cyl = cylinder_strip(columns=columns, jitter=jitter, seed=columns)
    bends = np.degrees(np.abs(dihedral_angles(cyl)))[~cyl.topology.boundary_edge_mask]
    if columns in (10, 13):
        assert bends.max() > 5.0                       # coarse: rulings of ~4.5-6.4 deg
    for mesh in (cyl, noisy(cyl, 0.01, seed=3)):
        s = panel_structure(mesh)
        assert not s.crease.any() and s.n_strips == 1
        assert len(s.middle_row) == 1 and len(s.grip_faces) == 0


@pytest.mark.parametrize("n", [1, 2])
def test_structure_is_invariant_to_vertex_and_face_order(n):
    base = noisy(plain(reflect_tagged(n, 75.0)), 0.005, seed=7)
    s0 = panel_structure(base)
    for seed in (1, 2):
        mesh, new_of_old, old_of_new = shuffled(base, seed)
        s = panel_structure(mesh)
        old_of_new_v = np.argsort(new_of_old)
        pairs = {tuple(sorted(old_of_new_v[e].tolist())) for e in mesh.edges[s.crease]}
        assert pairs == {tuple(e) for e in base.edges[s0.crease].tolist()}
        assert old_of_new[s.middle_row].tolist() == s0.middle_row.tolist()
        assert int(old_of_new[s.clamp_face]) == s0.clamp_face
        assert old_of_new[s.grip_faces].tolist() == s0.grip_faces.tolist()
        assert np.array_equal(s.strip, s0.strip[old_of_new])
        mv = {tuple(sorted(old_of_new_v[e].tolist())): a for e, a in zip(mesh.edges[s.crease], s.assignment[s.crease])}
        assert mv == {tuple(e): a for e, a in zip(base.edges[s0.crease].tolist(), s0.assignment[s0.crease])}


def test_tags_win_and_round_trip():
    tagged = reflect_tagged(2, 60.0)
    s = panel_structure(tagged)
    assert s.source == {"creases": "tags", "strips": "tags", "columns": "tags", "middle_row": "tags"}
    assert s.middle_row.tolist() == np.flatnonzero(tagged.face_data["middle"]).tolist()
    inferred = panel_structure(plain(tagged))
    retagged = inferred.with_tags(plain(tagged))
    again = panel_structure(retagged)
    assert again.source["creases"] == "tags"
    assert np.array_equal(again.crease, inferred.crease)
    assert again.middle_row.tolist() == inferred.middle_row.tolist()
    assert again.clamp_face == inferred.clamp_face
    # a user's own strip tags are obeyed even where the geometry says otherwise
    st = np.zeros(tagged.n_faces, np.int64)
    fake = plain(tagged).with_data(face_data={"strip": st})
    assert not panel_structure(fake).crease.any()


def test_flat_untagged_mesh_has_no_creases():
    tagged = reflect_tagged(1, 60.0)
    uv = np.asarray(tagged.vertex_data["uv"])
    flat = plain(tagged, np.column_stack([uv, np.zeros(len(uv))]))
    s = panel_structure(flat)
    assert not s.crease.any() and s.n_strips == 1


def test_strips_one_face_wide_and_the_trifold_preset():
    from fold_fixtures import folded_grid_model
    from fabkit.generate.trifold import trifold_panel

    grid = folded_grid_model(n_states=3, angles=[np.radians(30), np.radians(-45)]).frame_mesh(-1)
    s = panel_structure(plain(grid))
    assert np.array_equal(s.crease, true_creases(grid)) and s.n_strips == 3
    assert s.clamp_face == 6 and s.grip_faces.tolist() == [8, 7]   # middle column: first strip, far end first
    tri = trifold_panel()
    s = panel_structure(plain(tri))
    assert np.array_equal(s.crease, true_creases(tri)) and s.n_strips == 3


def test_given_crease_edges_win_over_the_geometry():
    """A FOLD crease pattern's M/V/U edges are creases even where the sheet is flat."""
    tagged = reflect_tagged(2, 60.0)
    uv = np.asarray(tagged.vertex_data["uv"])
    flat = plain(tagged, np.column_stack([uv, np.zeros(len(uv))]))
    truth = true_creases(tagged)
    s = panel_structure(flat, crease_edges=np.flatnonzero(truth))
    assert np.array_equal(s.crease, truth) and s.n_strips == 3 and s.source["creases"] == "assignments"
    assert set(s.assignment[truth]) == {"U"} and len(s.middle_row) == 3


def test_strips_of_a_fold_files_assignments_are_the_structures(tmp_path):
    """A FOLD file without strip tags: the loader's strips come from its M/V edges through
    `fabkit.structure` - the tagged panel's strips (as regions), the numbers `panel_structure` gives
    for those creases, and the same faces for any vertex and face order."""
    import json

    from fabkit.io.load import load_panel

    tagged = reflect_tagged(2, 60.0)
    truth = panel_structure(tagged)
    loaded = []
    for seed in (None, 1, 2):
        mesh, new_of_old, order = (tagged, np.arange(tagged.n_vertices), np.arange(tagged.n_faces)) if seed is None \
            else shuffled(tagged, seed)
        s = panel_structure(mesh)
        doc = {"file_spec": 1.2, "frame_classes": ["foldedForm"], "vertices_coords": mesh.vertices.tolist(),
               "faces_vertices": mesh.faces_list(), "edges_vertices": mesh.edges.tolist(),
               "edges_assignment": s.assignment.tolist()}
        path = tmp_path / f"panel{seed}.fold"
        path.write_text(json.dumps(doc))
        got, _ = load_panel(path)
        strip = np.asarray(got.face_data["strip"])
        assert np.array_equal(strip, panel_structure(plain(got), crease_edges=np.flatnonzero(s.crease)).strip)
        # the same regions as the tags (one label per tagged strip, and back)
        pairs = set(zip(np.asarray(tagged.face_data["strip"])[order].tolist(), strip.tolist()))
        assert len(pairs) == truth.n_strips == len({b for _, b in pairs})
        loaded.append(strip[np.argsort(order)])  # per original face
    assert all(np.array_equal(loaded[0], other) for other in loaded[1:])
