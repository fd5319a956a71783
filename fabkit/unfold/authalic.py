"""Authalic (area-preserving) development, for comparison with the isometric one (paper Fig. 10).

Area preservation alone leaves a huge family of maps (any area-preserving shear), so the energy is
sum_T (A2D_T / A3D_T - 1)^2 + mu * sum_T |conformal distortion_T|^2 with a weak `mu`: areas are met
as closely as possible, and among the maps that do, the least sheared one is chosen. Solved by the
same sparse Gauss-Newton as the isometric development, starting from the conformal (LSCM)
development scaled to the panel's area.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix, vstack

from fabkit.mesh import PolyMesh
from fabkit.unfold.conformal import conformal_layout, lscm_matrix, far_boundary_pair
from fabkit.unfold.isometric import gauss_newton

__all__ = ["AreaProblem", "authalic_layout"]

#: Weight of the conformal-distortion term that picks the least sheared area-preserving map.
CONFORMAL_WEIGHT = 1e-2


class AreaProblem:
    """Residuals and sparse Jacobian of the authalic energy over triangles `tris`."""

    def __init__(self, mesh: PolyMesh, tris: np.ndarray, mu: float = CONFORMAL_WEIGHT):
        V = mesh.vertices
        self.tris = tris
        self.n = mesh.n_vertices
        self.area3 = 0.5 * np.linalg.norm(np.cross(V[tris[:, 1]] - V[tris[:, 0]], V[tris[:, 2]] - V[tris[:, 0]]), axis=1)
        self.C = np.sqrt(mu) * lscm_matrix(V, tris, self.n, relative=True)

    def areas(self, uv: np.ndarray) -> np.ndarray:
        i, j, k = self.tris.T
        return 0.5 * ((uv[j, 0] - uv[i, 0]) * (uv[k, 1] - uv[i, 1]) - (uv[k, 0] - uv[i, 0]) * (uv[j, 1] - uv[i, 1]))

    def residuals(self, uv: np.ndarray) -> np.ndarray:
        return np.concatenate([self.areas(uv) / self.area3 - 1.0, self.C @ uv.ravel()])

    def jacobian(self, uv: np.ndarray) -> csr_matrix:
        i, j, k = self.tris.T
        x, y = uv[:, 0], uv[:, 1]
        w = 0.5 / self.area3
        vals = np.stack([(y[j] - y[k]) * w, (x[k] - x[j]) * w, (y[k] - y[i]) * w, (x[i] - x[k]) * w,
                         (y[i] - y[j]) * w, (x[j] - x[i]) * w], axis=1).ravel()
        cols = np.stack([2 * i, 2 * i + 1, 2 * j, 2 * j + 1, 2 * k, 2 * k + 1], axis=1).ravel()
        rows = np.repeat(np.arange(len(self.tris)), 6)
        JA = csr_matrix((vals, (rows, cols)), shape=(len(self.tris), 2 * self.n))
        return vstack([JA, self.C]).tocsr()


def authalic_layout(mesh: PolyMesh, tris: np.ndarray, *, max_iterations: int = 100) -> tuple[np.ndarray, dict]:
    """Area-preserving development (n, 2) over `tris` and the solver's account."""
    problem = AreaProblem(mesh, tris)
    uv0 = conformal_layout(mesh, tris)
    a2 = problem.areas(uv0).sum()
    uv0 = uv0 * np.sqrt(problem.area3.sum() / a2)
    p, q = far_boundary_pair(mesh)
    free = np.repeat(mesh.topology.used_vertex_mask, 2)
    free[[2 * p, 2 * p + 1, 2 * q + 1]] = False
    return gauss_newton(problem.residuals, problem.jacobian, uv0, free, max_iterations=max_iterations)
