"""Polyhedra, Conway operators, Catmull–Clark and topology edits against known counts and positions."""
import numpy as np
import pytest

from fabkit import measures
from fabkit.errors import InputError, MeshError
from fabkit.generate import (ambo, bevel, box, catmull_clark, chamfer, compact, cube, delete_faces, dissolve_edges,
                             dissolve_vertices, extrude_border_edges, grid, inset_faces, octahedron, prism,
                             signed_volume, tetrahedron, truncate)
from fabkit.mesh import PolyMesh


def euler(m):
    return m.n_vertices - m.n_edges + m.n_faces


# ---- polyhedra ----------------------------------------------------------------------------------

@pytest.mark.parametrize("mesh, volume", [
    (cube(2.0), 8.0),
    (box(1.0, 2.0, 3.0), 6.0),
    (tetrahedron(1.0), 1 / (6 * np.sqrt(2))),
    (octahedron(1.0), np.sqrt(2) / 3),
    (prism(6, 1.0, 1.0), 3 * np.sqrt(3) / 2),
    (prism(3, 1.0, 2.0), 2 * 3 * np.sqrt(3) / 4),
])
def test_polyhedra_are_closed_outward_and_exact(mesh, volume):
    assert len(mesh.boundary_loops) == 0 and euler(mesh) == 2
    assert np.isclose(signed_volume(mesh), volume, rtol=1e-14)
    # every face normal points away from the centre
    assert np.all(np.einsum("ij,ij->i", mesh.face_normals, mesh.face_centroids) > 0)
    assert measures.face_planarity(mesh).max() <= 1e-15


def test_prism_and_grid_refuse_bad_values():
    with pytest.raises(InputError, match="sides"):
        prism(2)
    with pytest.raises(InputError, match="radius"):
        prism(5, radius=-1)
    with pytest.raises(InputError, match="nx"):
        grid(0, 3)


def test_grid_layout():
    g = grid(3, 2, 3.0, 2.0)
    assert g.n_vertices == 12 and g.n_faces == 6
    assert np.allclose(g.vertices[[0, 11]], [[-1.5, -1, 0], [1.5, 1, 0]])
    assert np.all(g.face_normals[:, 2] == 1.0)


# ---- Conway -------------------------------------------------------------------------------------

@pytest.mark.parametrize("op, base, counts, sizes", [
    (chamfer, cube(), (32, 48, 18), {4: 6, 6: 12}),
    (bevel, cube(), (48, 72, 26), {4: 12, 6: 8, 8: 6}),
    (ambo, cube(), (12, 24, 14), {3: 8, 4: 6}),
    (truncate, cube(), (24, 36, 14), {3: 8, 8: 6}),
    (chamfer, tetrahedron(), (16, 24, 10), {3: 4, 6: 6}),
    (bevel, tetrahedron(), (24, 36, 14), {4: 6, 6: 8}),  # truncated octahedron
    (ambo, octahedron(), (12, 24, 14), {3: 8, 4: 6}),
    (bevel, prism(5), (60, 90, 32), {4: 15, 6: 10, 8: 5, 10: 2}),
])
def test_conway_counts(op, base, counts, sizes):
    m = op(base)
    assert (m.n_vertices, m.n_edges, m.n_faces) == counts
    assert dict(zip(*np.unique(m.face_sizes, return_counts=True))) == sizes
    assert len(m.boundary_loops) == 0 and euler(m) == 2
    assert signed_volume(m) > 0  # orientation kept: still outward


def test_bevel_of_cube_has_planar_faces_and_origins():
    m = bevel(cube(), 1 / 3)
    assert measures.face_planarity(m).max() <= 1e-12
    origin, source = m.face_data["origin"], m.face_data["source"]
    assert np.all(m.face_sizes[origin == 0] == 8) and sorted(source[origin == 0]) == list(range(6))
    assert np.all(m.face_sizes[origin == 1] == 4) and sorted(source[origin == 1]) == list(range(12))
    assert np.all(m.face_sizes[origin == 2] == 6) and sorted(source[origin == 2]) == list(range(8))
    # each octagon lies in its cube face's plane
    c = cube()
    for f in range(6):
        oct_face = np.flatnonzero((origin == 0) & (source == f))[0]
        n = c.face_normals[f]
        assert np.allclose(m.vertices[m.face(oct_face)] @ n, 0.5, atol=1e-15)


def test_chamfer_keeps_old_vertices_and_face_directions():
    c = cube()
    m = chamfer(c, 0.25)
    assert np.array_equal(m.vertices[:8], c.vertices)
    shrunk = np.flatnonzero(m.face_data["origin"] == 0)
    assert np.allclose(m.face_normals[shrunk], c.face_normals, atol=1e-15)
    # a shrunk face is the old one scaled by 0.75 about its centroid
    assert np.allclose(m.face_areas[shrunk], 0.75 ** 2 * c.face_areas)


def test_conway_refuses_open_meshes():
    with pytest.raises(MeshError, match="closed"):
        chamfer(grid(2, 2))


# ---- Catmull–Clark ------------------------------------------------------------------------------

def test_catmull_clark_cube_counts_and_exact_first_level():
    c = cube(1.0)
    m1, m2 = catmull_clark(c, 1), catmull_clark(c, 2)
    assert (m1.n_vertices, m1.n_faces, m2.n_vertices, m2.n_faces) == (26, 24, 98, 96)
    assert np.all(m1.face_sizes == 4) and np.all(m2.face_sizes == 4)
    # old corners keep their ids and move to (Q + 2R + 0 P) / 3 = 5/18 per coordinate
    assert np.allclose(np.abs(m1.vertices[:8]), 5 / 18, rtol=0, atol=1e-15)
    assert np.array_equal(np.sign(m1.vertices[:8]), np.sign(c.vertices))
    # edge points: (v0 + v1 + f1 + f2) / 4 -> two coordinates +-3/8, one 0
    ep = np.sort(np.abs(m1.vertices[8:20]), axis=1)
    assert np.allclose(ep, [0, 0.375, 0.375], atol=1e-15)
    # face points are the face centroids
    assert np.allclose(m1.vertices[20:], c.face_centroids, atol=1e-15)
    assert signed_volume(m1) > 0 and len(m1.boundary_loops) == 0


def test_catmull_clark_handles_ngons_and_keeps_face_data():
    p = prism(5)
    p = p.with_data(face_data={"id": np.arange(p.n_faces)})
    m = catmull_clark(p)
    assert (m.n_vertices, m.n_faces) == (10 + 15 + 7, 2 * 5 + 5 * 4)
    assert np.array_equal(m.face_data["id"], np.repeat(np.arange(7), p.face_sizes))
    # face point of a regular pentagon cap is its centre
    assert np.allclose(m.vertices[10 + 15], [0, 0, -0.5], atol=1e-15)


def test_catmull_clark_boundary_rules():
    # a flat 2 x 1 grid with one raised boundary vertex: boundary rules only use boundary neighbours
    g = grid(2, 1, 2.0, 1.0)
    V = np.array(g.vertices)
    V[2, 2] = 1.0  # vertex 2 = column 1, row 0: a boundary vertex with two faces
    g = g.with_vertices(V)
    m = catmull_clark(g)
    # corners (one face each) stay fixed
    for v in (0, 1, 4, 5):
        assert np.array_equal(m.vertices[v], g.vertices[v])
    # boundary vertex: (prev + 6 P + next) / 8
    assert np.allclose(m.vertices[2], (V[0] + 6 * V[2] + V[4]) / 8, atol=1e-15)
    # boundary edge points are midpoints
    E = g.edges
    for e in np.flatnonzero(g.topology.boundary_edge_mask):
        assert np.allclose(m.vertices[6 + e], V[E[e]].mean(axis=0), atol=1e-15)
    # a flat grid stays flat, uv is subdivided with the same weights
    f = catmull_clark(grid(3, 3), 2)
    assert np.all(f.vertices[:, 2] == 0)
    assert np.allclose(f.vertex_data["uv"], f.vertices[:, :2], atol=1e-15)


def test_catmull_clark_matches_the_plain_python_reference(rng):
    from bench.bench_subdivide import reference_catmull_clark

    base = catmull_clark(prism(7), 1)  # has extraordinary vertices
    V = base.vertices + 0.01 * rng.standard_normal(base.vertices.shape)
    base = base.with_vertices(V)
    open_mesh, _ = delete_faces(base, [0, 5, 9])  # and boundaries with corners
    for mesh in (base, open_mesh):
        fast = catmull_clark(mesh)
        Vr, Fr = reference_catmull_clark(mesh.vertices.tolist(), mesh.faces_list())
        assert np.allclose(fast.vertices, Vr, atol=1e-14)
        assert fast.faces_list() == Fr


def test_sharp_creases_stay_creases():
    # two planes meeting at a 90 degree crease along x: a bent grid
    g = grid(4, 4, 1.0, 1.0)
    V = np.array(g.vertices)
    up = V[:, 1] > 0
    V[up, 2], V[up, 1] = V[up, 1], 0.0
    strip = (g.face_centroids[:, 1] > 0).astype(int)
    g = PolyMesh(V, g.faces_list(), face_data={"strip": strip})
    sharp = catmull_clark(g, 2, crease_key="strip")
    smooth = catmull_clark(g, 2)
    for m, flat in ((sharp, True), (smooth, False)):
        s = m.face_data["strip"]
        lower = np.unique(m.topology.face_array[s == 0])
        upper = np.unique(m.topology.face_array[s == 1])
        on_planes = np.allclose(m.vertices[lower, 2], 0, atol=1e-15) and np.allclose(m.vertices[upper, 1], 0, atol=1e-15)
        assert on_planes == flat
    d = measures.dihedral_angles(sharp)
    crease = np.isclose(np.abs(d), np.pi / 2)
    assert crease.sum() == 16  # the 16 child edges of the crease keep the full right angle


# ---- topology edits -----------------------------------------------------------------------------

def test_delete_faces_returns_the_index_map():
    g = grid(3, 3)
    m, old = delete_faces(g, [0, 1, 2])
    assert m.n_faces == 6 and m.n_vertices == 12
    assert np.array_equal(m.vertices, g.vertices[old])
    with pytest.raises(MeshError, match="no faces"):
        delete_faces(g, np.ones(9, bool))
    m2, old2 = compact(g)
    assert np.array_equal(old2, np.arange(16))


def test_inset_faces_counts_and_areas():
    c = cube()
    m = inset_faces(c, [0, 1], 0.5)
    assert (m.n_vertices, m.n_faces) == (8 + 8, 6 + 2 * 4)
    assert np.bincount(m.face_data["inset"]).tolist() == [4, 2, 8]
    assert np.allclose(m.face_areas[m.face_data["inset"] == 1], 0.25)
    assert np.isclose(signed_volume(m), 1.0)


def test_extrude_border_edges_directions():
    g = grid(2, 2, 2.0, 2.0)
    t = extrude_border_edges(g, 0.5)
    assert (t.n_vertices, t.n_faces) == (9 + 8, 4 + 8)
    assert np.all(t.vertices[:, 2] == 0)
    new = t.vertices[9:]
    # edge midpoints move straight out by 0.5, corners along the diagonal by 0.5
    r = np.abs(new[:, :2]).max(axis=1)
    assert np.allclose(np.sort(r), [1 + 0.5 / np.sqrt(2)] * 4 + [1.5] * 4)
    assert len(t.boundary_loops) == 1 and t.face_data["extruded"].sum() == 8
    n = extrude_border_edges(g, -0.25, direction="normal")
    assert np.allclose(n.vertices[9:, 2], -0.25)
    inward = extrude_border_edges(g, 0.25, direction="loop")
    assert np.abs(inward.vertices[9:, :2]).max() < 1.0
    with pytest.raises(MeshError, match="no boundary"):
        extrude_border_edges(cube(), 0.1)


def test_dissolve_edges_and_vertices():
    g = grid(2, 1)  # two quads side by side
    inner = g.topology.interior_edges
    m = dissolve_edges(g, inner)
    assert m.n_faces == 1 and m.face_sizes[0] == 6
    assert np.isclose(m.face_areas[0], g.face_areas.sum())
    mids = np.flatnonzero(m.topology.vertex_valence == 2)
    mids = [v for v in mids if abs(m.vertices[v, 0]) < 1e-12]  # the two middle vertices
    q, old = dissolve_vertices(m, mids)
    assert q.n_faces == 1 and q.face_sizes[0] == 4 and q.n_vertices == 4
    assert np.isclose(q.face_areas[0], 1.0)
    with pytest.raises(MeshError, match="boundary"):
        dissolve_edges(g, [0])
    with pytest.raises(MeshError, match="edges"):
        dissolve_vertices(grid(2, 2), [4])
    # a ring of faces around a vertex cannot merge into a disk with a hole
    gg = grid(3, 3)
    ef = gg.edge_faces
    ring = [e for e in gg.topology.interior_edges if 4 not in ef[e]]  # face 4 is the centre
    assert len(ring) == 8
    with pytest.raises(MeshError, match="loop"):
        dissolve_edges(gg, ring)


def test_edge_loops_and_their_removal():
    from fabkit.generate import catmull_clark, edge_loop, remove_edge_loops

    g = grid(4, 3, 4.0, 3.0)
    V, E = g.vertices, g.edges
    on_x0 = [e for e, (a, b) in enumerate(E) if V[a, 0] == 0 and V[b, 0] == 0]
    loop = edge_loop(g, on_x0[1])
    assert sorted(loop.tolist()) == sorted(on_x0) and len(loop) == 3
    m, old = remove_edge_loops(g, [on_x0[0]])
    # the two middle columns merge: 3 columns x 3 rows of quads, x = 0 line gone
    assert (m.n_faces, m.n_vertices) == (9, 16) and np.all(m.face_sizes == 4)
    assert not np.any(m.vertices[:, 0] == 0)
    assert np.isclose(m.face_areas.sum(), 12.0)
    # on a closed quad mesh a loop stops at irregular vertices (the cube's old corners, valence 3)
    c = catmull_clark(cube())
    assert len(edge_loop(c, 0)) == 2
    with pytest.raises(MeshError, match="boundary"):
        remove_edge_loops(g, [0])


def test_extrude_chosen_edges_and_vector():
    g = grid(2, 1, 2.0, 1.0)
    bottom = [e for e, (a, b) in enumerate(g.edges) if g.vertices[a, 1] == -0.5 and g.vertices[b, 1] == -0.5]
    t = extrude_border_edges(g, 0.3, edges=bottom, direction="vector", vector=[0.0, 0.0, -1.0])
    assert (t.n_vertices, t.n_faces) == (6 + 3, 2 + 2)
    assert np.allclose(t.vertices[6:], g.vertices[[0, 2, 4]] + [0, 0, -0.3])
    with pytest.raises(MeshError, match="not on the boundary"):
        extrude_border_edges(g, 0.3, edges=g.topology.interior_edges)
    with pytest.raises(ValueError, match="direction"):
        extrude_border_edges(g, 0.3, direction="sideways")


def test_direct_points_equal_the_sparse_operator(rng):
    from fabkit.generate.subdivide import catmull_clark_operator, catmull_clark_points, crease_edges_of

    base = catmull_clark(prism(7), 1)
    base = base.with_vertices(base.vertices + 0.01 * rng.standard_normal(base.vertices.shape))
    base, _ = delete_faces(base, [0, 5, 9])
    tag = (base.face_centroids[:, 2] > 0).astype(int)
    base = base.with_data(face_data={"half": tag})
    for sharp in (None, crease_edges_of(base, "half")):
        S, quads, parent = catmull_clark_operator(base.topology, sharp)
        X = np.column_stack([base.vertices, rng.standard_normal(base.n_vertices)])
        assert np.allclose(catmull_clark_points(base.topology, X, sharp), S @ X, atol=1e-15)
        assert np.allclose(catmull_clark_points(base.topology, X[:, 0], sharp), S @ X[:, 0], atol=1e-15)
        # every row of S sums to one: subdivision reproduces constants (affine invariance)
        assert np.allclose(np.asarray(S.sum(axis=1)).ravel(), 1.0, atol=1e-15)
