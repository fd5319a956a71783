"""Measures against exact answers: corner angles, angle defect, dihedral sign, planarity, plane fits."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fabkit import measures as M
from fabkit.mesh import PolyMesh
from io_meshes import grid

EXACT = 1e-13  # floating-point noise on unit-sized inputs


def regular_polygon(n: int, radius: float = 1.0) -> np.ndarray:
    t = 2 * np.pi * np.arange(n) / n
    return np.column_stack([radius * np.cos(t), radius * np.sin(t), np.zeros(n)])


def cube() -> PolyMesh:
    """Unit cube, 6 quads, counter-clockwise seen from outside; vertex i = (i&1, i>>1&1, i>>2&1)."""
    V = [[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)]
    F = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return PolyMesh(V, F)


def octahedron() -> PolyMesh:
    V = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    F = []
    for sx in (0, 1):
        for sy in (2, 3):
            for sz in (4, 5):
                tri = [sx, sy, sz]
                F.append(tri if (sx + sy + sz - 6) % 2 == 0 else tri[::-1])
    return PolyMesh(V, F)


# ---- corner angles --------------------------------------------------------------------------------
@pytest.mark.parametrize("n", [3, 4, 5, 6, 7, 8, 12])
def test_regular_polygon_corner_angles(n, rng):
    R = Rotation.random(random_state=12).as_matrix()
    V = regular_polygon(n, radius=rng.uniform(0.01, 10)) @ R.T + rng.normal(size=3)
    m = PolyMesh(V, [list(range(n))])
    np.testing.assert_allclose(M.corner_angles(m), (n - 2) * np.pi / n, rtol=0, atol=EXACT)
    assert M.face_planarity(m)[0] < 1e-14


def test_reflex_corner_of_an_l_shape():
    V = [[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]]
    a = M.corner_angles(PolyMesh(V, [[0, 1, 2, 3, 4, 5]]))
    np.testing.assert_allclose(a, np.array([1, 1, 1, 3, 1, 1]) * np.pi / 2, rtol=0, atol=EXACT)


def test_corner_angles_with_vertex_override_matches_with_vertices(rng):
    m = grid(3, 2)
    W = m.vertices + rng.normal(scale=0.1, size=m.vertices.shape)
    np.testing.assert_array_equal(M.corner_angles(m, W), M.corner_angles(m.with_vertices(W)))
    np.testing.assert_array_equal(M.angle_defect(m, W), M.angle_defect(m.with_vertices(W)))


# ---- angle defect ---------------------------------------------------------------------------------
def test_cube_corner_defect_is_half_pi_and_gauss_bonnet():
    m = cube()
    d = M.angle_defect(m)
    np.testing.assert_allclose(d, np.pi / 2, rtol=0, atol=EXACT)
    assert m.boundary_loops == () and m.interior_vertex_mask.all()
    assert d.sum() == pytest.approx(4 * np.pi, abs=1e-12)  # closed genus-0 surface


def test_octahedron_vertex_defect():
    m = octahedron()
    np.testing.assert_allclose(M.angle_defect(m), 2 * np.pi / 3, rtol=0, atol=EXACT)
    assert M.angle_defect(m).sum() == pytest.approx(4 * np.pi, abs=1e-12)


def test_flat_jittered_grid_has_zero_defect_and_nan_on_boundary(rng):
    m = grid(4, 4)
    V = np.array(m.vertices)
    V[:, :2] += rng.uniform(-0.2, 0.2, size=(len(V), 2))  # still flat, faces still convex
    m = m.with_vertices(V)
    d = M.angle_defect(m)
    assert np.all(np.isnan(d[m.boundary_vertex_mask]))
    np.testing.assert_allclose(d[m.interior_vertex_mask], 0.0, atol=EXACT)
    np.testing.assert_allclose(M.interior_angle_defect(m), 0.0, atol=EXACT)
    assert len(M.interior_angle_defect(m)) == 9


def test_cylinder_strip_is_developable_and_planar():
    # rulings of a cylinder of radius 0.7: every quad is a planar rectangle, every interior vertex flat
    t = np.linspace(0, 2.0, 7)
    z = np.linspace(0, 1.0, 4)
    T, Z = np.meshgrid(t, z)
    V = np.column_stack([0.7 * np.cos(T.ravel()), 0.7 * np.sin(T.ravel()), Z.ravel()])
    g = grid(6, 3)
    m = PolyMesh(V, g.faces_list())
    np.testing.assert_allclose(M.interior_angle_defect(m), 0.0, atol=EXACT)
    assert M.face_planarity(m).max() < 1e-15
    # the rulings fold by the angle between neighbouring faces, 2/6 rad; the front normals point
    # outward (u x v = (cos t, sin t, 0)), so they turn away from each other: mountain, negative
    np.testing.assert_allclose(m.face_normals[0], [np.cos(1 / 6), np.sin(1 / 6), 0], atol=EXACT)
    d = M.dihedral_angles(m)
    E = m.edges
    ruling = (E[:, 1] - E[:, 0] == 7) & ~m.topology.boundary_edge_mask
    assert ruling.sum() == 15  # 5 inner rulings x 3 rows of quads
    np.testing.assert_allclose(d[ruling], -2.0 / 6, atol=EXACT)


# ---- dihedral angles: valley positive ------------------------------------------------------------
@pytest.mark.parametrize("theta", [0.3, np.pi / 2, np.radians(170.0), -0.3, -np.radians(170.0)])
def test_folded_grid_dihedral_sign(theta):
    """Rotate the right half of a 2x1 grid about x = 1 so that it rises to +z for theta > 0 (valley)."""
    m = grid(2, 1)
    V = np.array(m.vertices)
    right = V[:, 0] > 1
    V[right, 0] = 1 + np.cos(theta)
    V[right, 2] = np.sin(theta)
    folded = m.with_vertices(V)
    d = M.dihedral_angles(folded)
    hinge = np.flatnonzero(np.all(folded.edges == [1, 4], axis=1))[0]
    assert d[hinge] == pytest.approx(theta, abs=EXACT)
    assert np.all(d[np.arange(len(d)) != hinge] == 0.0)  # boundary edges are 0


def test_convex_solid_edges_are_mountains():
    d = M.dihedral_angles(cube())
    np.testing.assert_allclose(d, -np.pi / 2, atol=EXACT)  # outward normals turn away: mountain


# ---- planarity and plane fits ---------------------------------------------------------------------
@pytest.mark.parametrize("method", ["cross", "covariance"])
@pytest.mark.parametrize("h", [1e-6, 0.01, 0.2])
def test_twisted_quad_planarity_hand_computed(method, h):
    # corners alternate +-h about z = 0: the best plane is z = 0 by symmetry, every corner at distance h,
    # each edge has length sqrt(1 + 4 h^2)
    m = PolyMesh([[0, 0, -h], [1, 0, h], [1, 1, -h], [0, 1, h]], [[0, 1, 2, 3]])
    n, origin = M.best_fit_planes(m, method)
    np.testing.assert_allclose(n[0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(origin[0], [0.5, 0.5, 0], atol=1e-15)
    np.testing.assert_allclose(M.plane_distances(m, method), [-h, h, -h, h], rtol=1e-12)
    assert M.face_planarity(m, method)[0] == pytest.approx(h / np.sqrt(1 + 4 * h * h), rel=1e-12)


def test_covariance_plane_fits_at_least_as_well_as_cross_plane(rng):
    faces, V = [], []
    for k in range(200):
        n = int(rng.integers(4, 7))
        P = regular_polygon(n) * rng.uniform(0.5, 2) + rng.normal(scale=0.15, size=(n, 3))
        R = Rotation.random(random_state=k).as_matrix()
        V.extend((P @ R.T).tolist())
        faces.append(list(range(len(V) - n, len(V))))
    m = PolyMesh(V, faces)
    t = m.topology
    d_cross = M.plane_distances(m, "cross")
    d_cov = M.plane_distances(m, "covariance")
    ss = lambda d: np.add.reduceat(d * d, t.face_offsets[:-1])  # noqa: E731
    assert np.all(ss(d_cov) <= ss(d_cross) * (1 + 1e-12) + 1e-30)
    assert np.mean(ss(d_cov) < ss(d_cross) * (1 - 1e-9)) > 0.9  # and strictly better almost always
    # both planes pass through the centroid: distances sum to zero per face
    np.testing.assert_allclose(np.add.reduceat(d_cov, t.face_offsets[:-1]), 0, atol=1e-12)
    np.testing.assert_allclose(np.add.reduceat(d_cross, t.face_offsets[:-1]), 0, atol=1e-12)
    n_cross, _ = M.best_fit_planes(m, "cross")
    n_cov, _ = M.best_fit_planes(m, "covariance")
    assert np.all(np.einsum("ij,ij->i", n_cross, n_cov) > 0)  # same orientation
    with pytest.raises(ValueError, match="unknown plane method"):
        M.best_fit_planes(m, "svd")


def test_planar_faces_and_triangles_have_zero_planarity(rng):
    R = Rotation.random(random_state=3).as_matrix()
    m = grid(3, 3).with_vertices(grid(3, 3).vertices @ R.T + 5.0)
    for method in ("cross", "covariance"):
        assert M.face_planarity(m, method).max() < 1e-14
    tri = PolyMesh(rng.normal(size=(3, 3)), [[0, 1, 2]])
    assert M.face_planarity(tri)[0] == 0.0


def test_summary_of_a_cube():
    s = M.summary(cube())
    assert (s["vertices"], s["faces"], s["edges"], s["boundary_loops"]) == (8, 6, 12, 0)
    assert s["interior_vertices"] == 8
    assert s["max_abs_angle_defect_rad"] == pytest.approx(np.pi / 2, abs=EXACT)
    assert s["max_planarity"] == 0.0 and s["min_edge_m"] == 1.0 and s["size_m"] == pytest.approx(np.sqrt(3))
