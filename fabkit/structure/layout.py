"""Strips, columns and the middle row of a panel, given its crease edges (geometry decides every tie).

- Strips: the connected regions of faces that no crease separates. They are numbered along the
  strip adjacency (which crease separates which strips), starting at the end strip whose centroid
  comes first along the axis on which the two end strips' centroids differ most; without a chain of
  strips, breadth first from the first centroid in (x, y, z).
- Columns (quad meshes): the ribbons of quads crossing the creases: from each edge of the first
  crease (row 0) walk through opposite quad sides until the boundary. Column 0 starts at the end of
  that crease that comes first (`comes_first`). Left out when ribbons do not cover every face exactly once.
- Middle column: the ribbon whose area centroid is nearest the panel's; the middle row is one
  face per strip of it, the face nearest the centroid of the strip's part of the ribbon. Without
  ribbons, the face of each strip nearest the panel centroid.
- Clamp face: the middle-row face of the middle strip ((k - 1) // 2 of k strips); grip candidates:
  the other middle-row faces, farthest from the clamp first.

Comparisons of coordinates are rounded to 1e-9 of the panel size, so round-off does not decide.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components

from fabkit.mesh import PolyMesh

__all__ = ["comes_first", "strip_components", "order_strips", "quad_ribbons", "middle_row_faces", "geometric_key"]


def geometric_key(points: np.ndarray, size: float) -> np.ndarray:
    """Integer keys (k, 3) of points rounded to 1e-9 of `size`, for order-independent tie-breaking."""
    return np.round(np.asarray(points) / max(size, 1e-300) * 1e9).astype(np.int64)


def comes_first(a: np.ndarray, b: np.ndarray) -> bool:
    """Does point a come before point b? Compared along the axis (x, y or z) on which they differ
    most, so noise on the other axes cannot decide."""
    d = np.asarray(b, np.float64) - np.asarray(a, np.float64)
    return bool(d[int(np.argmax(np.abs(d)))] >= 0)


def _lex_first(keys: np.ndarray, candidates, points: np.ndarray) -> int:
    c = list(candidates)
    if len(c) == 2:
        return c[0] if comes_first(points[c[0]], points[c[1]]) else c[1]
    k = keys[c]
    return c[int(np.lexsort((k[:, 2], k[:, 1], k[:, 0]))[0])]


def strip_components(mesh: PolyMesh, crease: np.ndarray) -> np.ndarray:
    """Component label (F,) of every face over the non-crease interior edges (labels arbitrary)."""
    t = mesh.topology
    inner = ~t.boundary_edge_mask & ~crease
    ef = t.edge_faces[inner]
    F = t.n_faces
    A = sp.coo_matrix((np.ones(len(ef)), (ef[:, 0], ef[:, 1])), shape=(F, F))
    return connected_components(A, directed=False)[1]


def order_strips(mesh: PolyMesh, labels: np.ndarray, crease: np.ndarray) -> np.ndarray:
    """Strip number (F,) from component labels, ordered along the strip adjacency (module docstring)."""
    t = mesh.topology
    k = int(labels.max()) + 1 if len(labels) else 0
    A = mesh.face_areas
    C = np.zeros((k, 3))
    np.add.at(C, labels, mesh.face_centroids * A[:, None])
    C /= np.maximum(np.bincount(labels, weights=A, minlength=k), 1e-300)[:, None]
    keys = geometric_key(C, mesh.size)
    ef = t.edge_faces[crease]
    a, b = labels[ef[:, 0]], labels[ef[:, 1]]
    G = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(k, k)).tocsr()
    G = ((G + G.T) > 0).astype(np.int8)
    deg = np.asarray(G.sum(axis=1)).ravel()
    rank = np.full(k, -1, np.int64)
    nxt = 0
    while np.any(rank < 0):
        left = np.flatnonzero(rank < 0)
        leaves = left[deg[left] <= 1]
        start = _lex_first(keys, leaves if len(leaves) else left, C)
        # breadth first, neighbours in geometric order
        queue = [start]
        rank[start] = nxt
        nxt += 1
        while queue:
            s = queue.pop(0)
            nb = [int(x) for x in G.indices[G.indptr[s]:G.indptr[s + 1]] if rank[x] < 0]
            nb.sort(key=lambda x: tuple(keys[x]))
            for x in nb:
                rank[x] = nxt
                nxt += 1
                queue.append(x)
    return rank[labels]


def _ribbon(t, start_edge: int, face: int, quads: np.ndarray) -> list[int]:
    """Faces from `face` onward, entering through `start_edge`, exiting through opposite quad sides."""
    out, e, f = [], start_edge, face
    seen = set()
    while f >= 0 and quads[f] and f not in seen:
        seen.add(f)
        out.append(f)
        c0 = t.face_offsets[f]
        ce = t.halfedge_edge[c0:c0 + 4].tolist()
        e = ce[(ce.index(e) + 2) % 4]
        ef = t.edge_faces[e]
        f = int(ef[1] if ef[0] == f else ef[0])
    return out


def quad_ribbons(mesh: PolyMesh, chain_edges: np.ndarray) -> list[list[int]]:
    """One ribbon of quads (faces in order across the creases) through each edge of `chain_edges`."""
    t = mesh.topology
    quads = t.face_sizes == 4
    out = []
    for e in np.asarray(chain_edges).tolist():
        f0, f1 = (int(x) for x in t.edge_faces[e])
        if f0 < 0 or f1 < 0 or not (quads[f0] and quads[f1]):
            out.append([])
            continue
        a = _ribbon(t, e, f0, quads)
        b = _ribbon(t, e, f1, quads)
        out.append(a[::-1] + b)
    return out


def middle_row_faces(mesh: PolyMesh, strip: np.ndarray, ribbons: list[list[int]]) -> tuple[list[int], int]:
    """(middle-row faces ordered by strip, index of the middle ribbon or -1) — module docstring."""
    A = mesh.face_areas
    Cf = mesh.face_centroids
    size = mesh.size
    centre = (Cf * A[:, None]).sum(axis=0) / A.sum()
    k = int(strip.max()) + 1
    full = [r for r in ribbons if r and len(set(strip[r].tolist())) == k]
    best = -1
    if full:
        rc = np.array([(Cf[r] * A[r, None]).sum(axis=0) / A[r].sum() for r in full])
        d = np.round(np.linalg.norm(rc - centre, axis=1) / max(size, 1e-300) * 1e9)
        near = np.flatnonzero(d == d.min())
        keys = geometric_key(rc, size)
        best_local = near[np.lexsort((-keys[near, 2], -keys[near, 1], -keys[near, 0]))[0]]  # ties: last in (x, y, z)
        best = ribbons.index(full[best_local])
    row = []
    for s in range(k):
        if best >= 0:
            cand = np.array([f for f in ribbons[best] if strip[f] == s])
            target = (Cf[cand] * A[cand, None]).sum(axis=0) / A[cand].sum()
        else:
            cand = np.flatnonzero(strip == s)
            target = centre
        d = np.round(np.linalg.norm(Cf[cand] - target, axis=1) / max(size, 1e-300) * 1e9)
        near = cand[d == d.min()]
        keys = geometric_key(Cf[near], size)
        row.append(int(near[np.lexsort((-keys[:, 2], -keys[:, 1], -keys[:, 0]))[0]]))
    return row, best
