"""Conformal development: least-squares conformal maps (LSCM, Lévy et al. 2002) with scipy.sparse.

For every triangle with isometric local coordinates z_0, z_1, z_2 (complex), the map U is
conformal on it when sum_j (z_{j+2} - z_{j+1}) U_j = 0. Stacking the real and imaginary parts of that
sum (each triangle weighted by 1/sqrt(2 area)) gives a sparse linear least-squares problem; two
vertices far apart on the boundary are pinned to remove the similarity freedom and the normal
equations are solved by a sparse direct factorisation. The result is scaled by the least-squares
best factor against the 3D spring lengths, as the baseline in the reference notes does.

Written with scipy.sparse because libigl (which has `igl.lscm`) is a bench-only dependency.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.linalg import splu

from fabkit.mesh import PolyMesh

__all__ = ["triangle_local_coords", "lscm_matrix", "conformal_layout", "best_scale", "far_boundary_pair"]


def triangle_local_coords(V: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Complex local coordinates (T, 3) of each triangle in its own plane (z_0 = 0, z_1 on +x) and
    the triangle areas (T,)."""
    p0, p1, p2 = V[tris[:, 0]], V[tris[:, 1]], V[tris[:, 2]]
    e1 = p1 - p0
    l1 = np.linalg.norm(e1, axis=1)
    x = e1 / l1[:, None]
    n = np.cross(e1, p2 - p0)
    area = 0.5 * np.linalg.norm(n, axis=1)
    y = np.cross(n / np.linalg.norm(n, axis=1, keepdims=True), x)
    d = p2 - p0
    z = np.zeros((len(tris), 3), dtype=complex)
    z[:, 1] = l1
    z[:, 2] = np.einsum("ij,ij->i", d, x) + 1j * np.einsum("ij,ij->i", d, y)
    return z, area


def lscm_matrix(V: np.ndarray, tris: np.ndarray, n: int, *, relative: bool = False) -> csr_matrix:
    """The (2T, 2n) real LSCM matrix acting on (u0, v0, u1, v1, ...).

    Rows are Re and Im of sum_j W_j U_j / sqrt(2A) (the LSCM energy), or / (2A) when `relative`
    (a dimensionless conformal distortion per triangle, used by the authalic solver).
    """
    z, area = triangle_local_coords(V, tris)
    W = np.stack([z[:, 2] - z[:, 1], z[:, 0] - z[:, 2], z[:, 1] - z[:, 0]], axis=1)
    W = W / ((2 * area) if relative else np.sqrt(2 * area))[:, None]
    a, b = W.real, W.imag
    T = len(tris)
    # Re(W U) = a u - b v ; Im(W U) = a v + b u
    rows_re = np.repeat(2 * np.arange(T), 6)
    rows_im = rows_re + 1
    cu, cv = 2 * tris, 2 * tris + 1
    cols = np.stack([cu, cv], axis=2).reshape(T, 6)
    vals_re = np.stack([a, -b], axis=2).reshape(T, 6)
    vals_im = np.stack([b, a], axis=2).reshape(T, 6)
    return csr_matrix((np.concatenate([vals_re.ravel(), vals_im.ravel()]),
                       (np.concatenate([rows_re, rows_im]), np.concatenate([cols.ravel(), cols.ravel()]))),
                      shape=(2 * T, 2 * n))


def far_boundary_pair(mesh: PolyMesh) -> tuple[int, int]:
    """Two boundary vertices far apart (the farthest from the first, then the farthest from that)."""
    loops = mesh.boundary_loops
    b = np.concatenate(loops) if loops else np.flatnonzero(mesh.topology.used_vertex_mask)
    P = mesh.vertices[b]
    i = int(np.argmax(np.linalg.norm(P - P[0], axis=1)))
    j = int(np.argmax(np.linalg.norm(P - P[i], axis=1)))
    return int(b[i]), int(b[j])


def best_scale(uv: np.ndarray, pairs: np.ndarray, rest: np.ndarray) -> float:
    """The factor s minimising sum ((s l2D - L) / L)^2 over the springs."""
    l2 = np.linalg.norm(uv[pairs[:, 1]] - uv[pairs[:, 0]], axis=1) / rest
    return float(np.sum(l2) / np.sum(l2 * l2))


def conformal_layout(mesh: PolyMesh, tris: np.ndarray) -> np.ndarray:
    """LSCM development (n, 2) of `mesh` over the triangles `tris` (not yet scaled)."""
    n = mesh.n_vertices
    V = mesh.vertices
    A = lscm_matrix(V, tris, n).tocsc()
    p, q = far_boundary_pair(mesh)
    pinned_uv = np.zeros(2 * n)
    pinned_uv[2 * q] = np.linalg.norm(V[q] - V[p])
    fixed = np.zeros(2 * n, dtype=bool)
    fixed[[2 * p, 2 * p + 1, 2 * q, 2 * q + 1]] = True
    fixed |= ~np.repeat(mesh.topology.used_vertex_mask, 2)
    free = np.flatnonzero(~fixed)
    Af = A[:, free]
    rhs = -(A[:, np.flatnonzero(fixed)] @ pinned_uv[fixed])
    H = (Af.T @ Af).tocsc()
    lu = splu(H, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    x = lu.solve(Af.T @ rhs)
    for _ in range(2):  # iterative refinement: the normal equations square the condition number
        x += lu.solve(Af.T @ (rhs - Af @ x))
    out = pinned_uv.copy()
    out[free] = x
    return out.reshape(n, 2)
