"""Refold maths: triangulation maps, loop closure and its Jacobian, positions from angles, solvers."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fabkit.measures import dihedral_angles
from fabkit.mesh import PolyMesh
from fabkit.refold import RefoldSolver
from fabkit.refold.geometry import build_face_tree, corner_mismatch, face_transforms, vertex_positions
from fabkit.refold.kinematics import (JacobianPattern, MinNormSolver, _chord_stalls, _qmul, _qrotate,
                                      build_vertex_loops, loop_closure)
from fabkit.refold.triangulate import BOUNDARY, CREASE, DIAGONAL, RULING, triangulate_panel
from refold_panels import DEG, reflect_pair, straight_crease_pair


# ---- triangulation -------------------------------------------------------------------------------
def test_triangulation_keeps_maps_to_quads_and_classifies_edges():
    flat, target = reflect_pair(2, columns=6, rows=2)
    p = triangulate_panel(flat)
    assert p.n_tris == 2 * flat.n_faces
    np.testing.assert_array_equal(np.bincount(p.tri_face), np.full(flat.n_faces, 2))
    # every triangle's corners belong to its quad, and triangles stay counter-clockwise
    for t, f in zip(p.tris, p.tri_face):
        assert set(t) <= set(flat.face(int(f)).tolist())
    V = flat.vertices
    a, b, c = V[p.tris[:, 0]], V[p.tris[:, 1]], V[p.tris[:, 2]]
    assert np.all(np.cross(b - a, c - a)[:, 2] > 0)
    kinds = np.bincount(p.edge_kind, minlength=4)
    assert kinds[DIAGONAL] == flat.n_faces
    assert kinds[BOUNDARY] == int(flat.topology.boundary_edge_mask.sum())
    # two crease rows, each one edge per column
    assert kinds[CREASE] == 2 * 6
    np.testing.assert_array_equal(np.sort(np.unique(p.edge_crease[p.edge_kind == CREASE])), [0, 1])
    assert kinds[RULING] == flat.n_edges - kinds[BOUNDARY] - kinds[CREASE]
    # polygon edge map: same vertex pair, and -1 exactly for diagonals
    pe = p.edge_poly_edge
    assert np.all((pe < 0) == (p.edge_kind == DIAGONAL))
    np.testing.assert_array_equal(flat.edges[pe[pe >= 0]], p.edges[pe >= 0])


@pytest.mark.parametrize("rule", ["short", "02", "13"])
def test_diagonal_rule(rule):
    # one 2 x 1 rectangle-ish quad: the 1-3 diagonal is the shorter one
    V = np.array([[0, 0, 0], [2, 0, 0], [2.5, 1, 0], [0.5, 1, 0]], float)
    p = triangulate_panel(PolyMesh(V, [[0, 1, 2, 3]]), rule)
    diag = p.edges[p.edge_kind == DIAGONAL][0].tolist()
    assert diag == {"short": [1, 3], "02": [0, 2], "13": [1, 3]}[rule]


# ---- quaternion helpers against scipy ------------------------------------------------------------
def test_quaternion_helpers_match_scipy():
    a, b = Rotation.random(50, random_state=1), Rotation.random(50, random_state=2)
    q = _qmul(a.as_quat(), b.as_quat())
    assert np.allclose(np.abs(np.einsum("ij,ij->i", q, (a * b).as_quat())), 1.0, atol=1e-14)
    v = np.random.default_rng(3).normal(size=(50, 3))
    np.testing.assert_allclose(_qrotate(a.as_quat(), v), a.apply(v), atol=1e-14)


def _closure_reference(loops, rho, i):
    """Loop product of vertex i composed with scipy Rotation, one step at a time."""
    P = Rotation.identity()
    for e, ax in zip(loops.edge[i], loops.axis[i]):
        if e >= 0:
            P = P * Rotation.from_rotvec(ax * rho[e])
    return P.as_rotvec()


def test_loop_closure_matches_scipy_composition(rng):
    flat, _ = reflect_pair(1, columns=5, rows=2)
    p = triangulate_panel(flat)
    loops = build_vertex_loops(p.topology, flat.vertices)
    rho = rng.normal(scale=0.6, size=p.topology.n_edges)
    r, _ = loop_closure(loops, rho)
    for i in range(loops.n_loops):
        np.testing.assert_allclose(r[i], _closure_reference(loops, rho, i), atol=1e-13)


# ---- known answers: closure holds exactly at real folds, and only there -------------------------------
@pytest.mark.parametrize("n", [1, 2])
def test_target_angles_close_every_loop(n):
    flat, target = reflect_pair(n, columns=10, rows=3)
    p = triangulate_panel(flat)
    loops = build_vertex_loops(p.topology, flat.vertices)
    rho = dihedral_angles(PolyMesh(target.vertices, topology=p.topology, validate=False))
    r, _ = loop_closure(loops, rho)
    assert np.abs(r).max() < 1e-12
    assert np.abs(loop_closure(loops, np.zeros_like(rho))[0]).max() == 0.0
    # a single crease hinge changed alone breaks closure at its end vertices
    e = int(np.flatnonzero(p.edge_kind == CREASE)[3])
    bumped = rho.copy()
    bumped[e] += 0.01
    r2, _ = loop_closure(loops, bumped)
    assert np.abs(r2).max() > 1e-4


def test_jacobian_matches_finite_differences_on_the_manifold():
    flat, target = reflect_pair(2, columns=6, rows=2)
    p = triangulate_panel(flat)
    loops = build_vertex_loops(p.topology, flat.vertices)
    rho = dihedral_angles(PolyMesh(target.vertices, topology=p.topology, validate=False))
    hinges = np.flatnonzero(p.hinge_mask)
    pat = JacobianPattern(loops, hinges)
    _, omega = loop_closure(loops, rho)
    C = pat.matrix(omega).toarray()
    h = 1e-6
    fd = np.zeros_like(C)
    for j, e in enumerate(hinges):
        up, dn = rho.copy(), rho.copy()
        up[e] += h
        dn[e] -= h
        fd[:, j] = (loop_closure(loops, up, jacobian=False)[0] - loop_closure(loops, dn, jacobian=False)[0]).ravel() / (2 * h)
    assert np.abs(C - fd).max() < 1e-8
    assert np.abs(C).max() > 0.5  # the check is not vacuous


def test_jacobian_off_the_manifold_is_first_order_accurate(rng):
    flat, target = reflect_pair(1, columns=6, rows=2)
    p = triangulate_panel(flat)
    loops = build_vertex_loops(p.topology, flat.vertices)
    rho0 = dihedral_angles(PolyMesh(target.vertices, topology=p.topology, validate=False))
    hinges = np.flatnonzero(p.hinge_mask)
    pat = JacobianPattern(loops, hinges)
    errs = []
    for eps in (1e-2, 1e-3):
        rho = rho0 + eps * rng.normal(size=rho0.shape)
        r, omega = loop_closure(loops, rho)
        C = pat.matrix(omega).toarray()
        j = 3
        up, dn = rho.copy(), rho.copy()
        up[hinges[j]] += 1e-7
        dn[hinges[j]] -= 1e-7
        fd = (loop_closure(loops, up, jacobian=False)[0] - loop_closure(loops, dn, jacobian=False)[0]).ravel() / 2e-7
        errs.append(np.abs(C[:, j] - fd).max() / np.abs(r).max())
    assert max(errs) < 2.0  # error / |r| bounded: O(|r|)


# ---- positions from angles ------------------------------------------------------------------------
def test_straight_crease_positions_known_answer():
    angle = 70 * DEG
    flat, target = straight_crease_pair(angle)
    p = triangulate_panel(flat)
    rho = dihedral_angles(PolyMesh(target.vertices, topology=p.topology, validate=False))
    crease = p.edge_kind == CREASE
    np.testing.assert_allclose(rho[crease], angle, atol=1e-14)
    np.testing.assert_allclose(rho[~crease], 0.0, atol=1e-14)
    # clamp a left-half triangle: the positions are the target itself
    root = int(np.flatnonzero(flat.face_data["strip"][p.tri_face] == 0)[0])
    tree = build_face_tree(p.topology, flat.vertices, root)
    V = vertex_positions(tree, flat.vertices, rho)
    np.testing.assert_allclose(V, target.vertices, atol=1e-15)


def test_positions_reproduce_reflect_target_and_keep_edge_lengths():
    flat, target = reflect_pair(2, columns=10, rows=3)
    p = triangulate_panel(flat)
    rho = dihedral_angles(PolyMesh(target.vertices, topology=p.topology, validate=False))
    tree = build_face_tree(p.topology, flat.vertices, 7)
    tr = face_transforms(tree, rho)
    V = vertex_positions(tree, flat.vertices, rho, tr)
    assert corner_mismatch(p.topology, flat.vertices, V, tr) < 1e-13
    E = p.edges
    L0 = np.linalg.norm(flat.vertices[E[:, 1]] - flat.vertices[E[:, 0]], axis=1)
    L = np.linalg.norm(V[E[:, 1]] - V[E[:, 0]], axis=1)
    assert np.abs(L / L0 - 1).max() < 1e-13
    # the clamped triangle stays where it is in the pattern
    np.testing.assert_array_equal(V[p.tris[7]], flat.vertices[p.tris[7]])
    # rigidly the same shape as the target: align on the clamped triangle
    a, b = V[p.tris[7]], np.asarray(target.vertices)[p.tris[7]]
    R, _ = Rotation.align_vectors(a - a.mean(0), b - b.mean(0))
    aligned = R.apply(target.vertices - b.mean(0)) + a.mean(0)
    assert np.abs(aligned - V).max() < 1e-13


def test_face_tree_covers_every_face_once():
    flat, _ = reflect_pair(1, columns=5, rows=2)
    p = triangulate_panel(flat)
    tree = build_face_tree(p.topology, flat.vertices, 3)
    seen = np.concatenate(tree.levels)
    np.testing.assert_array_equal(np.sort(seen), np.arange(p.n_tris))
    assert tree.parent[3] == -1 and np.all(tree.depth[tree.parent[tree.parent >= 0]] == tree.depth[tree.parent >= 0] - 1)


# ---- the three minimum-norm solvers agree -------------------------------------------------------------
def test_min_norm_solvers_agree(rng):
    flat, target = reflect_pair(1, columns=6, rows=2)
    p = triangulate_panel(flat)
    loops = build_vertex_loops(p.topology, flat.vertices)
    rho = 0.5 * dihedral_angles(PolyMesh(target.vertices, topology=p.topology, validate=False))
    _, omega = loop_closure(loops, rho)
    C = JacobianPattern(loops, np.flatnonzero(p.hinge_mask)).matrix(omega)
    b = C @ rng.normal(size=C.shape[1])  # consistent right-hand side
    xs = {m: MinNormSolver(m).solve(C, b) for m in ("direct", "lsmr", "dense")}
    for m, x in xs.items():
        np.testing.assert_allclose(C @ x, b, atol=1e-9, err_msg=m)
    np.testing.assert_allclose(xs["direct"], xs["dense"], atol=1e-8)
    np.testing.assert_allclose(xs["lsmr"], xs["dense"], atol=1e-7)
    # minimum norm: no component in the null space of C
    ns = np.linalg.svd(C.toarray())[2][C.shape[0]:]
    assert np.abs(ns @ xs["dense"]).max() < 1e-9


def test_solver_refuses_unknown_method():
    with pytest.raises(ValueError, match="unknown solver"):
        MinNormSolver("cholesky")
    flat, target = reflect_pair(1, columns=4, rows=2)
    with pytest.raises(ValueError, match="unknown solver"):
        RefoldSolver(flat, target, solver="qr")


def test_chord_refresh_rule():
    """Keep the factorisation while chord steps are fast, or slow but nearly done; refactorise otherwise."""
    assert not _chord_stalls(2e-7, 1e-6, 1e-12)      # contracts by 0.2
    assert _chord_stalls(8e-7, 1e-6, 1e-12)          # by 0.8: too slow
    assert _chord_stalls(5e-7, 1e-6, 1e-12)          # by 0.5 with 19 halvings to go
    assert not _chord_stalls(5e-12, 1e-11, 1e-12)    # by 0.5 with 3 halvings to go
    assert _chord_stalls(2e-6, 1e-6, 1e-12)          # growing
    assert not _chord_stalls(0.0, 1e-6, 1e-12)


def test_direct_solver_on_a_tall_jacobian_is_the_pseudo_inverse(rng):
    """More equations than unknowns (diagonals held): C^T C is factorised; same answer as numpy's pinv."""
    flat, target = reflect_pair(2, columns=6, rows=2)
    p = triangulate_panel(flat)
    loops = build_vertex_loops(p.topology, flat.vertices)
    rho = 0.5 * dihedral_angles(PolyMesh(target.vertices, topology=p.topology, validate=False))
    _, omega = loop_closure(loops, rho)
    quad_edges = np.flatnonzero(p.hinge_mask & (p.edge_kind != DIAGONAL))
    C = JacobianPattern(loops, quad_edges).matrix(omega)
    assert C.shape[0] > C.shape[1]
    A = C.toarray()
    for b in (C @ rng.normal(size=C.shape[1]), rng.normal(size=C.shape[0])):  # consistent, then not
        solver = MinNormSolver("direct")
        x = solver.solve(C, b)
        xp = np.linalg.pinv(A, rcond=1e-12) @ b
        # the 1e-13 regularisation shifts the answer by ~mu / sigma_min^2 (7e-7 here: cond(C) = 2.7e3)
        assert np.linalg.norm(x - xp) <= 1e-6 * np.linalg.norm(xp)
        assert np.abs(A.T @ (A @ x - b)).max() <= 1e-9 * np.abs(A.T @ b).max()  # least squares
        np.testing.assert_allclose(solver.solve(None, b, reuse=True), x, rtol=0, atol=1e-12 * np.abs(x).max())
    b = C @ rng.normal(size=C.shape[1])
    np.testing.assert_allclose(A @ MinNormSolver("direct").solve(C, b), b, atol=1e-9)  # consistent: solved


def test_loop_closure_with_mixed_valences_matches_scipy(rng):
    """Union-jack triangulation of a 4 x 4 grid: interior valences 4 and 8, so the loops are padded."""
    n = 5
    V = np.array([[i, j, 0.0] for j in range(n) for i in range(n)], float)
    tris = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            tris += [[a, b, c], [a, c, d]] if (i + j) % 2 == 0 else [[a, b, d], [b, c, d]]
    mesh = PolyMesh(V, tris)
    loops = build_vertex_loops(mesh.topology, V)
    valence = (loops.edge >= 0).sum(axis=1)
    assert set(valence.tolist()) == {4, 8}
    rho = rng.normal(scale=0.6, size=mesh.topology.n_edges)
    r, omega = loop_closure(loops, rho)
    for i in range(loops.n_loops):
        np.testing.assert_allclose(r[i], _closure_reference(loops, rho, i), atol=1e-13)
    # at the flat state every loop closes, so omega is the exact derivative there (padded slots skipped)
    zero = np.zeros_like(rho)
    _, omega = loop_closure(loops, zero)
    h = 1e-6
    for i in range(loops.n_loops):
        for k in range(valence[i]):
            e = loops.edge[i, k]
            up, dn = zero.copy(), zero.copy()
            up[e], dn[e] = h, -h
            fd = (loop_closure(loops, up, jacobian=False)[0][i] - loop_closure(loops, dn, jacobian=False)[0][i]) / (2 * h)
            np.testing.assert_allclose(omega[i, k], fd, atol=1e-8)
