"""Best-fit planes of the faces and the row-wise vector helpers of the relaxation energy.

Faces with k >= 4 vertices are grouped by k (`FaceGroup`: an (m, k) vertex array) so the plane of
every face of a group is computed at once: the cross-product plane (normal = sum of the corner
cross products, origin = centroid) or the covariance plane (smallest-eigenvalue eigenvector,
Poranne et al. 2013). `fabkit.relax.energy` builds the planarity energy, gradient and Jacobian
on these. Hand-written for the reason given there.
"""
from __future__ import annotations

import numpy as np

from fabkit.mesh import MeshTopology

__all__ = ["FaceGroup", "face_groups", "group_planes", "normal_adjoint", "covariance_normal_terms",
           "planarity_rows", "cross_rows", "dot_rows", "scatter_rows"]


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product along the last axis (faster than np.cross for small trailing axes)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def dot_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def scatter_rows(n: int, idx: np.ndarray, vals: np.ndarray) -> np.ndarray:
    """Sum 3-vectors `vals` into rows `idx` of an (n, 3) array (bincount per coordinate: fast)."""
    idx = idx.ravel()
    vals = vals.reshape(-1, 3)
    return np.stack([np.bincount(idx, weights=vals[:, k], minlength=n) for k in range(3)], axis=1)


class FaceGroup:
    """Faces with the same number of vertices k >= 4, as an (m, k) vertex array (planarity terms)."""

    def __init__(self, faces: np.ndarray, face_ids: np.ndarray):
        self.faces = faces
        self.face_ids = face_ids
        self.m, self.k = faces.shape


def face_groups(t: MeshTopology, mask: np.ndarray) -> list[FaceGroup]:
    """The faces with >= 4 vertices where `mask` (F,) is set, one group per face size."""
    fi, sizes = t.face_indices, t.face_sizes
    groups = []
    for k in np.flatnonzero(np.bincount(sizes)):  # the face sizes present (np.unique would load numpy.ma)
        if k < 4:
            continue
        ids = np.flatnonzero((sizes == k) & mask)
        if len(ids) == 0:
            continue
        faces = np.stack([fi[t.face_offsets[ids] + j] for j in range(k)], axis=1)
        groups.append(FaceGroup(faces, ids))
    return groups


def planarity_rows(g: FaceGroup, plane_method: str) -> int:
    """Residual rows per face: one per quad with the cross plane (its distances are (a, -a, a, -a)),
    else one per vertex."""
    return 1 if (g.k == 4 and plane_method == "cross") else g.k


def group_planes(g: FaceGroup, X: np.ndarray, plane_method: str):
    """The planes of group `g` at positions X -> (P, R, U, W, Nsum, Nlen, n, d, elen, extra): face
    vertices, offsets from the centroid, edges to next / prev, normal sum and its length, unit
    normal, signed distances (m, k), edge lengths, and (eigenvalues, eigenvectors) for the
    covariance plane (None for the cross plane)."""
    P = X[g.faces]                       # (m, k, 3)
    C = P.mean(axis=1)
    R = P - C[:, None, :]
    U = np.roll(P, -1, axis=1) - P       # next - here
    W = np.roll(P, 1, axis=1) - P        # prev - here
    Nsum = cross_rows(U, W).sum(axis=1)
    Nlen = np.sqrt(dot_rows(Nsum, Nsum))
    extra = None
    n = Nsum / Nlen[:, None]
    if plane_method == "covariance":
        M = np.einsum("mki,mkj->mij", R, R)
        lam, vec = np.linalg.eigh(M)
        nc = vec[:, :, 0]
        nc = nc * np.where(dot_rows(nc, n) < 0, -1.0, 1.0)[:, None]
        extra = (lam, vec)
        n = nc
    d = dot_rows(R, n[:, None, :])           # (m, k)
    elen = np.sqrt(dot_rows(U, U))
    return P, R, U, W, Nsum, Nlen, n, d, elen, extra


def normal_adjoint(U, W, p):
    """(∂N/∂x_j)ᵀ p for every face vertex j, N = Σ corner cross products; p (..., 3) per row.

    U, W: (m, k, 3); p: (m, r, 3) -> (m, r, k, 3).
    """
    A = cross_rows(W[:, None, :, :], p[:, :, None, :])   # to "next" of each corner
    B = cross_rows(p[:, :, None, :], U[:, None, :, :])   # to "prev" of each corner
    return -A - B + np.roll(A, 1, axis=2) + np.roll(B, -1, axis=2)


def covariance_normal_terms(R, n, d, extra):
    """The covariance plane's share of ∂d_c/∂x_j beyond the centroid term (m, rows c, verts j, 3):
    the normal turns by first-order eigenvector perturbation, G = Σ_{i=1,2} e_i e_iᵀ / (λ_i − λ_0)."""
    lam, vec = extra
    gap1 = np.maximum(lam[:, 1] - lam[:, 0], 1e-300)
    gap2 = np.maximum(lam[:, 2] - lam[:, 0], 1e-300)
    e1, e2 = vec[:, :, 1], vec[:, :, 2]
    Gm = (e1[:, :, None] * e1[:, None, :]) / gap1[:, None, None] + \
         (e2[:, :, None] * e2[:, None, :]) / gap2[:, None, None]
    GR = np.einsum("mij,mcj->mci", Gm, R)                     # G r_c  (m, c, 3)
    term1 = -d[:, None, :, None] * GR[:, :, None, :]         # -d_j G r_c
    term2 = -np.einsum("mji,mci->mcj", R, GR)[..., None] * n[:, None, None, :]  # -n (r_j·G r_c)
    return term1 + term2
