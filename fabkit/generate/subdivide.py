"""Catmull–Clark subdivision (Fig. 3 step e), vectorised: no Python loop over faces.

Written by hand: trimesh only subdivides triangles (loop / midpoint) and libigl's Python
bindings have no Catmull–Clark for polygon meshes; we need n-gons, boundaries and the map back.

Rules (Catmull & Clark 1978; boundary rules as in DeRose et al. 1998 / OpenSubdiv "edge and corner"):
- face point: centroid of the face;
- interior edge point: (v0 + v1 + both face points) / 4; boundary edge point: the midpoint;
- interior vertex of valence n: (Q + 2R + (n - 3) P) / n, Q = mean of the adjacent face points,
  R = mean of the incident edge midpoints;
- boundary vertex with two boundary edges and at least two faces: (prev + 6 P + next) / 8;
- corners (boundary vertices of a single face) and non-manifold boundary vertices stay fixed.

Sharp creases (DeRose, Kass & Truong 1998, "infinitely sharp" creases; Maya and OpenSubdiv offer
the same): with `crease_key`, the interior edges whose two faces differ in `face_data[crease_key]`
(e.g. "strip": the fold creases) follow the boundary rules: edge point = midpoint; a vertex on
exactly two sharp-or-boundary edges uses (prev + 6 P + next) / 8 along them; a vertex on three or
more is a corner and stays; a vertex on one sharp edge (a dart) uses the smooth rule. The crease
polylines then refine to cubic B-spline curves, and a crease polyline of three vertices gives a
planar curve (paper §3.1).

Numbering: the old vertices keep their ids (0..n-1), then one edge point per edge (in
`topology.edges` order), then one face point per face. Every face of k corners becomes k quads
(vertex, next edge point, face point, previous edge point), in corner order, so the new faces of
old face f are contiguous and `face_data` is inherited from f. Float `vertex_data` (e.g. "uv") is
subdivided with the same operator; other vertex data is dropped (it has no meaning at new points).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from fabkit.mesh import MeshTopology, PolyMesh

__all__ = ["catmull_clark", "catmull_clark_operator", "catmull_clark_points", "catmull_clark_quads",
           "crease_edges_of"]


@dataclass(frozen=True)
class _Rules:
    """Which rule every element follows in one step (shared by the operator and the direct path)."""

    interior: np.ndarray  # (E,) smooth interior edge (not boundary, not sharp)
    valence: np.ndarray  # (n,) edges at each vertex, float
    inner: np.ndarray  # (n,) smooth interior vertex rule
    smooth_boundary: np.ndarray  # (n,) (prev + 6 P + next) / 8 rule
    b_edges: np.ndarray  # (k, 2) boundary and sharp edges


def _rules(t: MeshTopology, sharp: np.ndarray | None) -> _Rules:
    interior = np.all(t.edge_faces >= 0, axis=1)
    if sharp is not None:
        sharp = np.asarray(sharp, dtype=bool)
        if sharp.shape != (t.n_edges,):
            raise ValueError(f"sharp mask has shape {sharp.shape}, expected ({t.n_edges},)")
        interior = interior & ~sharp  # a sharp edge subdivides like a boundary edge
    n = t.n_vertices
    valence = np.bincount(t.edges.ravel(), minlength=n).astype(np.float64)
    n_faces_at = np.bincount(t.face_indices, minlength=n)
    b_edges = t.edges[~interior]
    n_bedges = np.bincount(b_edges.ravel(), minlength=n)
    # a dart (one sharp edge, not on the boundary) keeps the smooth rule; corners and unused stay
    is_boundary = (n_bedges >= 2) | t.boundary_vertex_mask
    smooth_boundary = (n_bedges == 2) & (n_faces_at >= 2)
    inner = ~is_boundary & (n_faces_at > 0)
    return _Rules(interior, valence, inner, smooth_boundary, b_edges)


def catmull_clark_quads(topology: MeshTopology) -> tuple[np.ndarray, np.ndarray]:
    """`(quads, face_parent)`: one new quad per old corner (vertex, next edge point, face point,
    previous edge point) and the old face of each."""
    t = topology
    n, E = t.n_vertices, t.n_edges
    idx, cf = t.face_indices, t.corner_face
    quads = np.stack([idx, n + t.halfedge_edge, n + E + cf, n + t.halfedge_edge[t.corner_prev]], axis=1)
    return quads.astype(np.int64), cf.copy()


def catmull_clark_points(topology: MeshTopology, X: np.ndarray, sharp: np.ndarray | None = None) -> np.ndarray:
    """New points `(n + E + F, k)` of one step for per-vertex values `X` `(n, k)` (positions, uv...).

    The same numbers as `catmull_clark_operator(...)[0] @ X`, computed directly with bincounts
    (about six times faster than assembling the sparse matrix, which matters at a million faces).
    """
    t = topology
    X = np.asarray(X, dtype=np.float64)
    squeeze = X.ndim == 1
    X = X[:, None] if squeeze else X
    n, E, F = t.n_vertices, t.n_edges, t.n_faces
    idx, cf = t.face_indices, t.corner_face
    r = _rules(t, sharp)

    def sums(ids: np.ndarray, vals: np.ndarray, m: int) -> np.ndarray:
        return np.stack([np.bincount(ids, weights=vals[:, c], minlength=m) for c in range(vals.shape[1])], axis=1)

    fp = sums(cf, X[idx], F) / t.face_sizes[:, None]
    edges, ef = t.edges, t.edge_faces
    ep = 0.5 * (X[edges[:, 0]] + X[edges[:, 1]])
    ei = np.flatnonzero(r.interior)
    ep[ei] = 0.5 * ep[ei] + 0.25 * (fp[ef[ei, 0]] + fp[ef[ei, 1]])
    vp = X.copy()
    inner = r.inner
    if inner.any():
        q = sums(idx, fp[cf], n)  # sum of the adjacent face points
        nb = sums(edges.ravel(), X[edges[:, ::-1].ravel()], n)  # sum of the neighbours
        k = r.valence[inner][:, None]
        vp[inner] = (q[inner] + nb[inner]) / k ** 2 + (k - 2.0) / k * X[inner]
    sb = r.smooth_boundary
    if sb.any():
        bn = sums(r.b_edges.ravel(), X[r.b_edges[:, ::-1].ravel()], n)
        vp[sb] = 0.75 * X[sb] + 0.125 * bn[sb]
    out = np.vstack([vp, ep, fp])
    return out[:, 0] if squeeze else out


def catmull_clark_operator(topology: MeshTopology, sharp: np.ndarray | None = None
                           ) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """`(S, quads, face_parent)` for one Catmull–Clark step of `topology`.

    sharp: optional `(E,)` bool mask of interior edges to keep as sharp creases (boundary rules).

    S is the sparse `(n + E + F, n)` matrix with new vertices = S @ old vertices (the subdivision as
    a linear map, e.g. for solvers that need its transpose); quads `(C, 4)` (C = number of corners)
    are the new faces; face_parent `(C,)` the old face of every new face.
    """
    t = topology
    n, E, F = t.n_vertices, t.n_edges, t.n_faces
    idx = t.face_indices
    cf = t.corner_face
    sizes = t.face_sizes.astype(np.float64)
    r = _rules(t, sharp)
    interior, valence, inner, smooth_boundary, b_edges = r.interior, r.valence, r.inner, r.smooth_boundary, r.b_edges

    # face points: Fm (F x n) averaging each face's corners
    Fm = sp.csr_matrix((1.0 / sizes[cf], (cf, idx)), shape=(F, n))

    # edge points
    edges = t.edges
    ef = t.edge_faces
    e_all = np.arange(E)
    w_vert = np.where(interior, 0.25, 0.5)
    Ev = sp.csr_matrix((np.concatenate([w_vert, w_vert]), (np.concatenate([e_all, e_all]),
                                                           np.concatenate([edges[:, 0], edges[:, 1]]))), shape=(E, n))
    ei = np.flatnonzero(interior)
    Lf = sp.csr_matrix((np.full(2 * len(ei), 0.25), (np.concatenate([ei, ei]), np.concatenate([ef[ei, 0], ef[ei, 1]]))),
                       shape=(E, F))
    Em = Ev + Lf @ Fm

    # vertex points; interior: Q/n + 2R/n + (n-3)/n P = (1/n^2) VF Fm + (1/n^2) A + ((n-2)/n) I
    inv_n2 = np.where(inner, 1.0 / np.maximum(valence, 1.0) ** 2, 0.0)
    VF = sp.csr_matrix((inv_n2[idx], (idx, cf)), shape=(n, F))
    a = np.concatenate([edges[:, 0], edges[:, 1]])
    b = np.concatenate([edges[:, 1], edges[:, 0]])
    A = sp.csr_matrix((inv_n2[a], (a, b)), shape=(n, n))
    diag = np.where(inner, (valence - 2.0) / np.maximum(valence, 1.0), 1.0)  # corners, unused: stay
    diag = np.where(smooth_boundary, 0.75, diag)
    ba = np.concatenate([b_edges[:, 0], b_edges[:, 1]])
    bb = np.concatenate([b_edges[:, 1], b_edges[:, 0]])
    keep = smooth_boundary[ba]
    B = sp.csr_matrix((np.full(int(keep.sum()), 0.125), (ba[keep], bb[keep])), shape=(n, n))
    Vm = VF @ Fm + A + B + sp.diags(diag)

    S = sp.vstack([Vm, Em, Fm]).tocsr()
    quads, parent = catmull_clark_quads(t)
    return S, quads, parent


def crease_edges_of(mesh: PolyMesh, key: str) -> np.ndarray:
    """`(E,)` mask of interior edges whose two faces differ in `face_data[key]`."""
    if key not in mesh.face_data:
        raise ValueError(f"mesh has no face data {key!r} to mark creases")
    tag = np.asarray(mesh.face_data[key])
    ef = mesh.edge_faces
    inner = np.all(ef >= 0, axis=1)
    out = np.zeros(mesh.n_edges, dtype=bool)
    out[inner] = tag[ef[inner, 0]] != tag[ef[inner, 1]]
    return out


def catmull_clark(mesh: PolyMesh, levels: int = 1, crease_key: str | None = None) -> PolyMesh:
    """`levels` Catmull–Clark steps; keeps old vertex ids, inherits face data (see module docstring).

    crease_key: name of a face_data array; edges between faces with different values stay sharp.
    """
    if int(levels) != levels or levels < 0:
        raise ValueError(f"levels must be a non-negative integer, got {levels}")
    for _ in range(int(levels)):
        sharp = crease_edges_of(mesh, crease_key) if crease_key is not None else None
        quads, parent = catmull_clark_quads(mesh.topology)
        V = catmull_clark_points(mesh.topology, mesh.vertices, sharp)
        fd = {k: np.asarray(v)[parent] for k, v in mesh.face_data.items()}
        vd = {k: catmull_clark_points(mesh.topology, v, sharp) for k, v in mesh.vertex_data.items()
              if np.issubdtype(np.asarray(v).dtype, np.floating)}
        mesh = PolyMesh(V, quads, face_data=fd, vertex_data=vd, validate=False)
    return mesh
