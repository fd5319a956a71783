"""Solver pieces: analytic Jacobians against finite differences, LSCM invariants, the layout."""
import numpy as np
import pytest

from fabkit.mesh import PolyMesh
from fabkit.unfold import reference_lengths
from fabkit.unfold.authalic import AreaProblem
from fabkit.unfold.conformal import conformal_layout, lscm_matrix
from fabkit.unfold.isometric import SpringProblem
from fabkit.unfold.layout import incremental_layout
from fabkit.unfold.metrics import spring_lengths
from unfold_shapes import align_error, cone_strip, cylinder_strip, flat_grid, sphere_cap


def fd_jacobian(fun, uv, h=1e-7):
    x = uv.ravel()
    cols = []
    for k in range(len(x)):
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        cols.append((fun(xp.reshape(uv.shape)) - fun(xm.reshape(uv.shape))) / (2 * h))
    return np.stack(cols, axis=1)


def test_spring_jacobian_matches_finite_differences(rng):
    mesh = sphere_cap(n=5)
    pairs, rest = reference_lengths(mesh)
    p = SpringProblem(pairs, rest, mesh.n_vertices, np.ones(2 * mesh.n_vertices, bool))
    uv = mesh.vertices[:, :2] + rng.normal(scale=0.01, size=(mesh.n_vertices, 2))
    J = p.jacobian(uv).toarray()
    assert np.max(np.abs(J - fd_jacobian(p.residuals, uv))) < 1e-6
    assert np.max(np.abs(J)) > 1.0  # not trivially zero


def test_area_jacobian_matches_finite_differences(rng):
    mesh = sphere_cap(n=5)
    tris, _ = mesh.triangulate()
    p = AreaProblem(mesh, tris)
    uv = mesh.vertices[:, :2] + rng.normal(scale=0.01, size=(mesh.n_vertices, 2))
    J = p.jacobian(uv).toarray()
    assert np.max(np.abs(J - fd_jacobian(p.residuals, uv))) < 1e-5
    assert np.max(np.abs(J[: len(tris)])) > 1.0


def test_lscm_energy_is_zero_for_similarities_and_not_for_mirrors():
    mesh, uv = flat_grid()
    tris, _ = mesh.triangulate()
    A = lscm_matrix(mesh.vertices, tris, mesh.n_vertices)
    c, s = np.cos(0.7), np.sin(0.7)
    similar = 2.5 * uv @ np.array([[c, s], [-s, c]]) + [3.0, -1.0]
    assert np.max(np.abs(A @ similar.ravel())) < 1e-12
    assert np.max(np.abs(A @ (uv * [-1, 1]).ravel())) > 1e-2


def test_conformal_layout_is_a_similarity_on_a_developable_mesh():
    mesh, uv = cone_strip()
    tris, _ = mesh.triangulate()
    out = conformal_layout(mesh, tris)
    pairs, rest = reference_lengths(mesh)
    ratio = spring_lengths(out, pairs) / rest
    assert np.ptp(ratio) < 1e-9 * ratio.mean()  # one scale for every spring
    assert align_error(uv, out / ratio.mean()) < 1e-9


def test_incremental_layout_is_exact_and_reaches_every_vertex():
    mesh, uv = cylinder_strip(nu=30, nv=12)
    lay = incremental_layout(mesh)
    assert np.all(np.isfinite(lay.uv))
    assert align_error(uv, lay.uv) < 1e-13
    assert lay.levels > 1 and 0 <= lay.seed_face < mesh.n_faces
    a, b = lay.anchor
    assert np.allclose(lay.uv[a], 0) and lay.uv[b, 1] == 0


def test_layout_seed_does_not_matter_on_developable_input():
    mesh, uv = cone_strip()
    for seed in (0, mesh.n_faces // 2, mesh.n_faces - 1):
        assert align_error(uv, incremental_layout(mesh, seed).uv) < 1e-13
    with pytest.raises(ValueError):
        incremental_layout(mesh, mesh.n_faces)


def test_unused_vertices_are_ignored():
    mesh, uv = flat_grid(4, 3)
    V = np.concatenate([mesh.vertices, [[9.0, 9.0, 9.0]]])
    with pytest.warns(UserWarning, match="unused"):
        m2 = PolyMesh(V, mesh.faces_list())
    from fabkit.unfold import develop

    dev = develop(m2)
    assert dev.max_relative_deviation < 1e-12 and np.all(dev.uv[-1] == 0)


def test_solver_says_when_it_did_not_converge():
    from fabkit.unfold import develop

    dev = develop(sphere_cap(), max_iterations=1)
    assert not dev.converged and "stopped after 1 iterations" in dev.message
    assert dev.summary()["converged"] is False
    full = develop(sphere_cap())
    assert full.converged and full.mean_relative_deviation <= dev.mean_relative_deviation


def test_flip_guard_jacobian_matches_finite_differences(rng):
    from fabkit.unfold.isometric import corner_triangles

    mesh = sphere_cap(n=5)
    pairs, rest = reference_lengths(mesh)
    tris, area = corner_triangles(mesh)
    p = SpringProblem(pairs, rest, mesh.n_vertices, np.ones(2 * mesh.n_vertices, bool), tris, area)
    uv = mesh.vertices[:, :2].copy()
    uv[12] += [0.45, 0.3]  # pull the middle vertex across its neighbours: some corners turn over
    uv += rng.normal(scale=1e-3, size=uv.shape)
    r = p.residuals(uv)
    assert np.count_nonzero(r[len(pairs):]) > 0  # guards active
    J = p.jacobian(uv).toarray()
    assert np.max(np.abs(J - fd_jacobian(p.residuals, uv, h=1e-8))) < 1e-4 * np.max(np.abs(J))


def test_flip_guard_keeps_a_strong_saddle_flip_free():
    from fabkit.unfold import develop
    from unfold_shapes import grid_faces

    t = np.linspace(-1, 1, 20)
    X, Y = np.meshgrid(t, t, indexing="ij")
    saddle = PolyMesh(np.stack([X, Y, X ** 2 - Y ** 2], -1).reshape(-1, 3), grid_faces(20, 20))
    dev = develop(saddle)
    assert dev.n_flipped == 0 and not dev.outline_self_overlaps
    assert dev.mean_relative_deviation > 0.01  # far from developable, and reported as such


def test_solver_breakdown_is_a_tolerance_error(monkeypatch):
    import importlib

    from fabkit.errors import ToleranceError

    def broken(*args, **kwargs):
        raise FloatingPointError("the spring solver diverged (non-finite coordinates)")

    unfold_package = importlib.import_module("fabkit.unfold")  # `fabkit.unfold` is the stage function
    monkeypatch.setattr(unfold_package, "refine_isometric", broken)
    with pytest.raises(ToleranceError, match="isometric development failed: the spring solver diverged"):
        unfold_package.develop(sphere_cap())
