"""PolyMesh / MeshTopology / validate_mesh: every validation branch and the connectivity arrays."""
from __future__ import annotations

import numpy as np
import pytest

from fabkit.errors import MeshError
from fabkit.mesh import MeshTopology, PolyMesh, faces_to_csr, validate_mesh
from io_meshes import grid

SQUARE = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]


def annulus() -> PolyMesh:
    """3x3 grid of quads without the middle one: an outer loop and a hole."""
    g = grid(3, 3)
    faces = [f for k, f in enumerate(g.faces_list()) if k != 4]
    return PolyMesh(g.vertices, faces)


# ---- validation: one test per branch -------------------------------------------------------------
@pytest.mark.parametrize("vertices, faces, needle", [
    ([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]], [[0, 1, 2]], "vertex 2 has a non-finite coordinate"),
    ([[0, 0, 0], [np.inf, 0, 0], [0, 1, 0]], [[0, 1, 2]], "vertex 1 has a non-finite coordinate"),
    (SQUARE, [[0, 1, 2, 7]], "face 0 refers to vertex 7, but vertices are numbered 0..3"),
    (SQUARE, [[0, 1, 2], [0, -1, 2]], "face 1 refers to vertex -1"),
    (SQUARE, [[0, 1, 2], [2, 3]], "face 1 has 2 vertices (a face needs at least 3)"),
    (SQUARE, [[0, 1, 2, 1]], "face 0 repeats vertex 1"),
    ([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]], "face 0 has zero area"),
    ([[0, 0, 0], [1, 0, 0], [1, 0, 0]], [[0, 1, 2]], "face 0 has zero area"),
    ([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]], [[0, 1, 2], [1, 0, 3], [0, 1, 4]],
     "edge (0, 1) is shared by 3 faces [0, 1, 2]"),
    (SQUARE, [[0, 1, 2], [0, 2, 3][::-1]], "inconsistent orientation"),
    (SQUARE, [], "mesh has no faces"),
    ([[0, 0, 0, 0]], [[0, 0, 0]], "vertices must be an (n, 3) array"),
])
def test_validation_branches(vertices, faces, needle):
    with pytest.raises(MeshError) as err:
        PolyMesh(vertices, faces)
    assert needle in str(err.value)
    assert "\n" not in str(err.value)


def test_inconsistent_orientation_names_both_faces_and_the_edge():
    with pytest.raises(MeshError, match=r"faces 0 and 1 both run along edge 2->0 in the same direction"):
        PolyMesh(SQUARE, [[0, 1, 2], [3, 0, 2][::-1]])


def test_invalid_csr_and_data_lengths():
    with pytest.raises(MeshError, match="not a valid CSR"):
        MeshTopology(np.array([0, 1, 2]), np.array([0, 4]), 3)
    with pytest.raises(MeshError, match="face data 'strip' has 2 entries for 1 faces"):
        PolyMesh(SQUARE, [[0, 1, 2, 3]], face_data={"strip": [0, 1]})
    with pytest.raises(MeshError, match="vertex data 'w' has 3 entries for 4 vertices"):
        PolyMesh(SQUARE, [[0, 1, 2, 3]], vertex_data={"w": [0, 1, 2]})
    with pytest.raises(MeshError, match="a mesh needs faces"):
        PolyMesh(SQUARE)


def test_unused_vertices_warn_and_are_kept():
    with pytest.warns(UserWarning, match="1 unused vertices \\(first: 4\\)"):
        m = PolyMesh(SQUARE + [[5, 5, 5]], [[0, 1, 2, 3]])
    assert m.n_vertices == 5 and len(m.warnings) == 1
    assert not m.topology.used_vertex_mask[4] and not m.interior_vertex_mask[4]


def test_validate_mesh_names_the_source():
    m = PolyMesh([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]], validate=False)
    with pytest.raises(MeshError) as err:
        validate_mesh(m, source="panel.obj")
    assert str(err.value).startswith("panel.obj: face 0 has zero area")


def test_with_vertices_checks_shape_and_finiteness_and_shares_topology():
    m = grid(2, 1)
    moved = m.with_vertices(m.vertices + 1.0)
    assert moved.topology is m.topology
    with pytest.raises(MeshError, match="new vertices have shape"):
        m.with_vertices(m.vertices[:-1])
    V = np.array(m.vertices)
    V[3, 2] = np.nan
    with pytest.raises(MeshError, match="vertex 3 has a non-finite coordinate"):
        m.with_vertices(V)


def test_two_d_vertices_get_z_zero_and_arrays_are_read_only():
    m = PolyMesh([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]])
    assert m.vertices.shape == (3, 3) and np.all(m.vertices[:, 2] == 0)
    for arr in (m.vertices, m.edges, m.edge_faces, m.face_indices, m.face_normals, m.face_areas):
        with pytest.raises(ValueError):
            arr[0] = 0


def test_faces_to_csr_accepts_lists_arrays_and_csr():
    idx, off = faces_to_csr([[0, 1, 2], [2, 1, 3, 4]])
    assert idx.tolist() == [0, 1, 2, 2, 1, 3, 4] and off.tolist() == [0, 3, 7]
    idx2, off2 = faces_to_csr(np.array([[0, 1, 2, 3], [3, 2, 4, 5]]))
    assert off2.tolist() == [0, 4, 8] and idx2.dtype == np.int64
    idx3, off3 = faces_to_csr((idx, off))
    assert idx3.tolist() == idx.tolist() and off3.tolist() == off.tolist()
    assert faces_to_csr([])[1].tolist() == [0]


# ---- connectivity --------------------------------------------------------------------------------
def test_edges_sorted_and_edge_faces_left_right():
    m = grid(2, 2)
    E = m.edges
    assert len(E) == 12 and np.all(E[:, 0] < E[:, 1])
    keys = E[:, 0] * m.n_vertices + E[:, 1]
    assert np.all(np.diff(keys) > 0)  # lexicographic, no duplicates
    faces = m.faces_list()
    for e, (lo, hi) in enumerate(E.tolist()):
        left, right = m.edge_faces[e].tolist()
        if left >= 0:  # the left face runs lo -> hi
            f = faces[left]
            assert any(f[i] == lo and f[(i + 1) % len(f)] == hi for i in range(len(f)))
        if right >= 0:
            f = faces[right]
            assert any(f[i] == hi and f[(i + 1) % len(f)] == lo for i in range(len(f)))
        assert left >= 0 or right >= 0
    assert m.topology.interior_edges.tolist() == np.flatnonzero(np.all(m.edge_faces >= 0, axis=1)).tolist()
    assert len(m.topology.interior_edges) == 4


def test_half_edges_twins_and_corners():
    m = grid(2, 2)
    t = m.topology
    c = np.arange(len(t.face_indices))
    twin = t.halfedge_twin
    inner = twin >= 0
    assert np.array_equal(twin[twin[inner]], c[inner])
    # a half-edge and its twin run in opposite directions
    a, b = t.face_indices[c[inner]], t.face_indices[t.corner_next[c[inner]]]
    ta, tb = t.face_indices[twin[inner]], t.face_indices[t.corner_next[twin[inner]]]
    assert np.array_equal(a, tb) and np.array_equal(b, ta)
    assert np.array_equal(t.corner_prev[t.corner_next], c)
    assert np.array_equal(t.halfedge_edge[twin[inner]], t.halfedge_edge[inner])
    assert int(np.sum(~inner)) == 8  # boundary half-edges of a 2x2 grid


def test_boundary_loops_orientation_and_interior_masks():
    m = grid(2, 2)
    (loop,) = m.boundary_loops
    assert loop.tolist() == [0, 1, 2, 5, 8, 7, 6, 3]  # starts at the smallest id, mesh on the left (CCW)
    assert m.interior_vertex_mask.tolist() == [False] * 4 + [True] + [False] * 4
    assert m.boundary_vertex_mask.sum() == 8

    a = annulus()
    loops = a.boundary_loops
    assert len(loops) == 2
    V = a.vertices

    def signed_area(loop):
        x, y = V[loop, 0], V[loop, 1]
        return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)

    areas = sorted(signed_area(lp) for lp in loops)
    assert areas == [-1.0, 9.0]  # the hole runs clockwise, the outline counter-clockwise
    assert a.interior_vertex_mask.sum() == 0


def test_vertex_faces_valence_and_uniform_faces():
    m = grid(2, 2)
    faces, off = m.topology.vertex_faces
    assert sorted(faces[off[4]:off[5]].tolist()) == [0, 1, 2, 3]
    assert m.topology.vertex_valence.tolist() == [2, 3, 2, 3, 4, 3, 2, 3, 2]
    assert m.topology.face_array.shape == (4, 4)
    mixed = PolyMesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0.5, 0]], [[0, 1, 2, 3], [1, 4, 2]])
    assert not mixed.topology.is_uniform
    with pytest.raises(ValueError):
        mixed.topology.face_array
    assert repr(mixed) == "PolyMesh(5 vertices, 2 faces: 1 tris, 1 quads)"


def test_triangulate_keeps_the_map_to_polygons():
    m = PolyMesh([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 4, 5], [1, 2, 3, 4]])
    tris, tri_face = m.triangulate()
    assert tris.tolist() == [[0, 1, 4], [0, 4, 5], [1, 2, 3], [1, 3, 4]]
    assert tri_face.tolist() == [0, 0, 1, 1]
    pent = PolyMesh([[0, 0, 0], [1, 0, 0], [1.5, 1, 0], [0.5, 1.5, 0], [-0.5, 1, 0]], [[0, 1, 2, 3, 4]])
    t, tf = pent.triangulate()
    assert len(t) == 3 and tf.tolist() == [0, 0, 0]
    np.testing.assert_allclose(pent.face_areas[0], sum(0.5 * np.linalg.norm(np.cross(
        pent.vertices[b] - pent.vertices[a], pent.vertices[c] - pent.vertices[a])) for a, b, c in t))


def test_geometry_caches_on_a_unit_square():
    m = PolyMesh(SQUARE, [[0, 1, 2, 3]])
    np.testing.assert_array_equal(m.face_normals, [[0, 0, 1]])
    np.testing.assert_array_equal(m.face_centroids, [[0.5, 0.5, 0]])
    assert m.face_areas[0] == 1.0
    np.testing.assert_array_equal(np.sort(m.edge_lengths), [1, 1, 1, 1])
    assert m.size == pytest.approx(np.sqrt(2), abs=0)


def test_with_data_merges_and_keeps_topology():
    m = grid(2, 1).with_data(face_data={"strip": np.array([0, 1])})
    m2 = m.with_data(face_data={"column": np.array([0, 0])}, vertex_data={"w": np.zeros(6)})
    assert set(m2.face_data) == {"strip", "column"} and m2.topology is m.topology


def test_edge_ids_find_vertex_pairs_in_either_order():
    m = PolyMesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]], float),
                 [[0, 1, 2, 3], [1, 4, 5, 2]])
    t = m.topology
    ids = t.edge_ids(m.edges[::-1, ::-1])              # every edge, reversed pairs, reversed order
    assert np.array_equal(ids, np.arange(m.n_edges)[::-1])
    assert t.edge_ids([[0, 2], [3, 4], [0, 99], [-1, 0]]).tolist() == [-1, -1, -1, -1]   # diagonal, none, out of range
    assert t.edge_ids(np.zeros((0, 2), int)).shape == (0,)
