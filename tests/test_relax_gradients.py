"""Every analytic derivative of the relaxation energy against central finite differences (rel. err <= 1e-6)."""
import numpy as np
import pytest

from fabkit.generate import reflect_panel
from fabkit.mesh import PolyMesh
from fabkit.relax.energy import EnergyModel
from fabkit.relax.fd_gradient import colored_fd_gradient

from relax_meshes import perturbed

REL = 1e-6


def _mixed_mesh() -> PolyMesh:
    """Quads, a pentagon and triangles around interior vertices, gently bent out of plane."""
    V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0], [0, 2, 0], [1, 2, 0],
                  [2, 2, 0], [1.5, 2.6, 0], [3, 1, 0], [3, 2, 0]], float)
    V[:, 2] = 0.15 * np.sin(V[:, 0]) * np.cos(0.7 * V[:, 1])
    faces = [[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 9, 7], [2, 10, 5], [5, 10, 11, 8]]
    return PolyMesh(V, faces)


def _fd_gradient(model: EnergyModel, X: np.ndarray, h: float) -> np.ndarray:
    G = np.zeros_like(X)
    for i in np.flatnonzero(model.free_mask):
        for k in range(3):
            Xp, Xm = X.copy(), X.copy()
            Xp[i, k] += h
            Xm[i, k] -= h
            G[i, k] = (model.energy(Xp) - model.energy(Xm)) / (2 * h)
    return G


def _fd_jacobian(model: EnergyModel, X: np.ndarray, h: float) -> np.ndarray:
    y = model.pack(X)
    cols = []
    for c in range(len(y)):
        yp, ym = y.copy(), y.copy()
        yp[c] += h
        ym[c] -= h
        rp, _ = model.residuals_and_jacobian(model.unpack(yp, X), need_jacobian=False)
        rm, _ = model.residuals_and_jacobian(model.unpack(ym, X), need_jacobian=False)
        cols.append((rp - rm) / (2 * h))
    return np.stack(cols, axis=1)


def _rel(a, b):
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


CASES = [(plane, free, mesh) for plane in ("cross", "covariance") for free in ("all", "interior", "some")
         for mesh in ("reflect", "mixed")]


@pytest.mark.parametrize("plane,free,which", CASES)
def test_gradient_and_jacobian_match_finite_differences(plane, free, which):
    if which == "reflect":
        mesh, _ = perturbed(reflect_panel(columns=4, rows=2), 0.05, seed=3)
    else:
        mesh = _mixed_mesh()
    t = mesh.topology
    rng = np.random.default_rng(7)
    free_mask = {"all": np.ones(mesh.n_vertices, bool), "interior": t.interior_vertex_mask.copy(),
                 "some": rng.random(mesh.n_vertices) < 0.7}[free]
    L = float(mesh.edge_lengths.mean())
    X = np.array(mesh.vertices)
    model = EnergyModel(t, defect_mask=t.interior_vertex_mask, free_mask=free_mask, planarity_weight=0.7,
                        plane_method=plane, length_scale=L, closeness_weight=0.3,
                        x_ref=X + rng.normal(scale=0.01 * L, size=X.shape))
    ev = model.evaluate(X)
    h = 1e-6 * L
    assert _rel(ev.gradient, _fd_gradient(model, X, h)) <= REL
    assert np.all(ev.gradient[~free_mask] == 0)
    r, J = model.residuals_and_jacobian(X)
    assert _rel(J.toarray(), _fd_jacobian(model, X, h)) <= REL
    # the residual vector carries the energy: E = ½‖r‖² + closeness
    close = 0.5 * 0.3 / L**2 * np.sum((X - model.x_ref) ** 2)
    assert 0.5 * r @ r + close == pytest.approx(ev.energy, rel=1e-12)


def test_boundary_vertices_feel_their_interior_neighbours_defect():
    """§2.5 Fig. 7: with planarity off, boundary vertices still get a developability force."""
    mesh, _ = perturbed(reflect_panel(columns=4, rows=2), 0.05, seed=1)
    t = mesh.topology
    model = EnergyModel(t, defect_mask=t.interior_vertex_mask, free_mask=np.ones(mesh.n_vertices, bool),
                        planarity_weight=0.0, length_scale=float(mesh.edge_lengths.mean()))
    G = model.gradient(np.array(mesh.vertices))
    b = t.boundary_vertex_mask
    near = np.zeros(mesh.n_vertices, bool)
    near[mesh.edges[(b[mesh.edges[:, 0]] ^ b[mesh.edges[:, 1]])].ravel()] = True
    touched = b & near
    assert np.all(np.linalg.norm(G[touched], axis=1) > 0)
    assert _rel(G, _fd_gradient(model, np.array(mesh.vertices), 1e-6 * model.L)) <= REL


def test_coloured_finite_difference_gradient_matches_analytic():
    mesh, _ = perturbed(reflect_panel(columns=6, rows=3), 0.03, seed=2)
    t = mesh.topology
    model = EnergyModel(t, defect_mask=t.interior_vertex_mask, free_mask=np.ones(mesh.n_vertices, bool),
                        length_scale=float(mesh.edge_lengths.mean()))
    X = np.array(mesh.vertices)
    assert _rel(colored_fd_gradient(model, X), model.gradient(X)) <= REL


def test_reflex_corner_angle_and_gradient():
    """An L-shaped hexagon has a reflex corner: its angle is > π and the gradient still matches."""
    V = np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0.1], [1, 2, 0], [0, 2, 0], [3, 0, 0], [3, 1, 0],
                  [2, 2, 0.05], [0, -1, 0], [2, -1, 0]], float)
    faces = [[0, 1, 2, 3, 4, 5], [1, 6, 7, 2], [3, 2, 8, 4], [9, 10, 1, 0]]
    mesh = PolyMesh(V, faces)
    t = mesh.topology
    assert t.interior_vertex_mask.any()
    model = EnergyModel(t, defect_mask=t.interior_vertex_mask, free_mask=np.ones(mesh.n_vertices, bool),
                        length_scale=float(mesh.edge_lengths.mean()))
    X = np.array(mesh.vertices)
    assert _rel(model.gradient(X), _fd_gradient(model, X, 1e-6 * model.L)) <= REL
    r, J = model.residuals_and_jacobian(X)
    assert _rel(J.toarray(), _fd_jacobian(model, X, 1e-6 * model.L)) <= REL
