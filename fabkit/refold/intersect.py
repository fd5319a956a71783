"""Do faces of a fold state pass through each other? Triangle-triangle tests, vectorised.

Broad phase: bounding spheres (centroid, farthest corner) in a scipy cKDTree; candidate pairs are
those whose spheres overlap. Pairs that share a vertex are skipped (neighbours always touch).
Narrow phase: the separating-axis test for two triangles (face normals, the nine edge-edge cross
products, and the in-plane edge normals for the coplanar case). Written by hand because neither
scipy nor trimesh has a triangle-triangle intersection test for one mesh against itself (trimesh's
collision manager needs python-fcl, which is not a dependency).

Touching within `tol` (a length) does not count as intersecting.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

__all__ = ["neighbour_keys", "candidate_pairs", "triangles_intersect", "intersecting_pairs"]


def neighbour_keys(tris: np.ndarray) -> np.ndarray:
    """Sorted keys `i * T + j` of the triangle pairs (i < j) that share a vertex.

    Depends on the topology only: compute once and pass to `candidate_pairs` for every state.
    """
    tris = np.asarray(tris, np.int64)
    T = len(tris)
    tri_of = np.repeat(np.arange(T), 3)
    inc = sp.csr_matrix((np.ones(3 * T), (tris.ravel(), tri_of)), shape=(int(tris.max(initial=-1)) + 1, T))
    adj = sp.triu(inc.T @ inc, k=1).tocoo()   # triangles sharing at least one vertex
    return np.sort(adj.row.astype(np.int64) * T + adj.col)


def candidate_pairs(V: np.ndarray, tris: np.ndarray, pad: float = 0.0,
                    neighbours: np.ndarray | None = None) -> np.ndarray:
    """Pairs (i < j) of triangles whose bounding spheres overlap and that share no vertex.

    `neighbours`: `neighbour_keys(tris)` if already known (saves recomputing it per state).
    """
    P = V[tris]
    c = P.mean(axis=1)
    rad = np.sqrt(((P - c[:, None]) ** 2).sum(axis=2).max(axis=1)) + pad
    if len(tris) < 2:
        return np.zeros((0, 2), np.int64)
    pairs = cKDTree(c).query_pairs(2.0 * float(rad.max()), output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), np.int64)
    i, j = pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)
    d = c[i] - c[j]
    reach = rad[i] + rad[j]
    near = np.einsum("ij,ij->i", d, d) <= reach * reach
    i, j = i[near], j[near]
    lo, hi = np.minimum(i, j), np.maximum(i, j)
    if neighbours is None:
        neighbours = neighbour_keys(tris)
    keys = lo * len(tris) + hi
    pos = np.minimum(np.searchsorted(neighbours, keys), max(len(neighbours) - 1, 0))
    share = neighbours[pos] == keys if len(neighbours) else np.zeros(len(keys), bool)
    return np.stack([lo[~share], hi[~share]], axis=1)


def _separated_on(axes: np.ndarray, A: np.ndarray, B: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """True where one of `axes` (k, m, 3) separates triangles A, B (k, 3, 3) by more than -tol."""
    length = np.linalg.norm(axes, axis=2)
    scale = np.maximum(np.abs(A).max(axis=(1, 2)), np.abs(B).max(axis=(1, 2)))
    valid = length > 1e-12 * np.max(length, axis=1, keepdims=True) + 1e-300
    unit = axes / np.where(valid, length, 1.0)[:, :, None]
    pA = np.einsum("kav,kpv->kap", unit, A)
    pB = np.einsum("kav,kpv->kap", unit, B)
    gap = np.maximum(pB.min(axis=2) - pA.max(axis=2), pA.min(axis=2) - pB.max(axis=2))
    return np.any(valid & (gap >= -(tol + 1e-12 * scale)[:, None]), axis=1)


def triangles_intersect(A: np.ndarray, B: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """For stacks of triangles A, B (k, 3, 3): True where they overlap by more than `tol`.

    Separating-axis test: two convex sets are disjoint iff some axis separates their projections.
    For triangles the candidate axes are n_A, n_B, e_A x e_B (9) and, for (near-)coplanar pairs,
    n x e for every edge (6); degenerate (zero) axes are ignored. Cheap axes go first and only the
    pairs they cannot separate reach the expensive ones.
    """
    k = len(A)
    out = np.zeros(k, bool)
    if k == 0:
        return out
    tolv = np.full(k, float(tol))
    # axis-aligned boxes
    sep = np.any((A.min(axis=1) > B.max(axis=1) + tolv[:, None]) | (B.min(axis=1) > A.max(axis=1) + tolv[:, None]),
                 axis=1)
    idx = np.flatnonzero(~sep)
    eA = np.roll(A[idx], -1, axis=1) - A[idx]
    eB = np.roll(B[idx], -1, axis=1) - B[idx]
    nA = np.cross(eA[:, 0], eA[:, 1])
    nB = np.cross(eB[:, 0], eB[:, 1])
    sep = _separated_on(np.stack([nA, nB], axis=1), A[idx], B[idx], tolv[idx])
    keep = ~sep
    idx, eA, eB, nA, nB = idx[keep], eA[keep], eB[keep], nA[keep], nB[keep]
    m = len(idx)
    axes = np.concatenate([np.cross(eA[:, :, None], eB[:, None, :]).reshape(m, 9, 3),
                           np.cross(nA[:, None], eA), np.cross(nB[:, None], eB)], axis=1)
    sep = _separated_on(axes, A[idx], B[idx], tolv[idx])
    out[idx[~sep]] = True
    return out


def intersecting_pairs(V: np.ndarray, tris: np.ndarray, tol: float = 0.0, chunk: int = 20000,
                       neighbours: np.ndarray | None = None) -> np.ndarray:
    """Pairs of triangles (sharing no vertex) that pass through each other in positions V.

    `neighbours`: `neighbour_keys(tris)`, to skip recomputing it for every state of one mesh.
    """
    V = np.asarray(V, np.float64)
    pairs = candidate_pairs(V, tris, pad=tol, neighbours=neighbours)
    hits = []
    for s in range(0, len(pairs), chunk):
        p = pairs[s:s + chunk]
        hit = triangles_intersect(V[tris[p[:, 0]]], V[tris[p[:, 1]]], tol)
        hits.append(p[hit])
    return np.concatenate(hits) if hits else np.zeros((0, 2), np.int64)
