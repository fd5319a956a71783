"""Exact incremental layout: unfold faces across edges, breadth-first from a seed face.

Each face is placed from the edge it shares with its parent in a breadth-first spanning tree of
the faces: every other corner v of the face is put where the 3D triangle (a, b, v) lands when it is
laid flat on the already placed edge a -> b, on the side the face normal says. The triangle is
reproduced exactly, so on a developable mesh with planar faces (angle sums 2π, the prerequisite of
unfolding) the layout is exact to round-off; on other meshes it is the starting point of the
least-squares refinement. Faces of one breadth-first level are placed together (vectorised), so
the Python loop runs once per level (about sqrt(#faces) times for a panel), not once per face.

Written by hand: no library we use unfolds a polygon mesh face by face (trimesh and libigl only
parameterise triangle meshes, and not exactly).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

from fabkit.errors import MeshError
from fabkit.mesh import PolyMesh

__all__ = ["Layout", "incremental_layout", "central_face"]


@dataclass(frozen=True)
class Layout:
    """An incremental layout: `uv` (n, 2), the `seed_face`, and its two first vertices (a at the
    origin, b on +x), which the refinement pins to remove the rigid-motion freedom."""

    uv: np.ndarray
    seed_face: int
    anchor: tuple[int, int]
    levels: int


def central_face(mesh: PolyMesh) -> int:
    """The face whose centroid is nearest the area-weighted centroid of the panel.

    A central seed keeps the breadth-first tree shallow, which keeps round-off (and, on
    non-developable input, the accumulated layout error) small.
    """
    c = mesh.face_centroids
    w = mesh.face_areas
    centre = (c * w[:, None]).sum(axis=0) / max(w.sum(), 1e-300)
    return int(np.argmin(np.linalg.norm(c - centre, axis=1)))


def _face_tree(mesh: PolyMesh, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Breadth-first order of the faces from `seed` and each face's parent (-9999 for the seed)."""
    t = mesh.topology
    m = t.n_faces
    adj = t.face_adjacency
    graph = coo_matrix((np.ones(len(adj)), (adj[:, 0], adj[:, 1])), shape=(m, m)).tocsr()
    n_comp, _ = connected_components(graph, directed=False)
    if n_comp > 1:
        raise MeshError(f"the mesh has {n_comp} separate pieces (faces connected only through vertices count "
                        "as separate); unfold one panel at a time")
    order, pred = breadth_first_order(graph, seed, directed=False, return_predecessors=True)
    return order, pred


def _lay_triangles(A3, B3, V3, N, a2, b2):
    """2D position of V when the 3D triangle (A, B, V) is laid on the 2D edge a2 -> b2.

    The distance to A is kept exactly and the angle at A too; V goes to the left of a2 -> b2 when it is
    on the left of A -> B seen from the face normal N.
    """
    e = B3 - A3
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    d = V3 - A3
    x = np.einsum("ij,ij->i", d, e)
    c = np.cross(e, d)
    y = np.linalg.norm(c, axis=1) * np.where(np.einsum("ij,ij->i", c, N) < 0, -1.0, 1.0)
    f = b2 - a2
    f /= np.linalg.norm(f, axis=1, keepdims=True)
    perp = np.stack([-f[:, 1], f[:, 0]], axis=1)
    return a2 + x[:, None] * f + y[:, None] * perp


def incremental_layout(mesh: PolyMesh, seed_face: int | None = None) -> Layout:
    """Unfold `mesh` face by face from `seed_face` (default: `central_face`).

    The seed face's first edge lies on the +x axis from the origin; faces come out counter-clockwise
    (their front side towards +z). Every vertex is placed by the first face that reaches it.
    """
    t = mesh.topology
    m = t.n_faces
    seed = central_face(mesh) if seed_face is None else int(seed_face)
    if not 0 <= seed < m:
        raise ValueError(f"seed face {seed} out of range 0..{m - 1}")
    order, pred = _face_tree(mesh, seed)
    V = mesh.vertices
    N = mesh.face_normal_sums
    fi = t.face_indices
    nxt = t.corner_next

    # entry half-edge of every face: the corner of f whose edge is shared with its parent
    entry = np.full(m, -1, dtype=np.int64)
    entry[seed] = t.face_offsets[seed]
    inner = t.interior_edges
    hl, hr = t.edge_halfedges[inner, 0], t.edge_halfedges[inner, 1]
    fl, fr = t.edge_faces[inner, 0], t.edge_faces[inner, 1]
    child = np.concatenate([fl, fr])
    parent = np.concatenate([fr, fl])
    half = np.concatenate([hl, hr])
    tree = pred[child] == parent
    entry[child[tree]] = half[tree]

    # breadth-first level of every face
    depth = np.zeros(m, dtype=np.int64)
    pl = pred.tolist()
    dl = depth.tolist()
    for f in order[1:].tolist():
        dl[f] = dl[pl[f]] + 1
    depth = np.asarray(dl, dtype=np.int64)

    uv = np.full((len(V), 2), np.nan)
    placed = np.zeros(len(V), dtype=bool)
    a0, b0 = int(fi[entry[seed]]), int(fi[nxt[entry[seed]]])
    uv[a0] = 0.0
    uv[b0] = [np.linalg.norm(V[b0] - V[a0]), 0.0]
    placed[[a0, b0]] = True

    # corners grouped by the level of their face
    cface = t.corner_face
    corner_order = np.argsort(depth[cface], kind="stable")
    bounds = np.searchsorted(depth[cface][corner_order], np.arange(depth.max() + 2))
    for k in range(depth.max() + 1):
        cs = corner_order[bounds[k]:bounds[k + 1]]
        f = cface[cs]
        v = fi[cs]
        new = ~placed[v]
        if not np.any(new):
            continue
        cs, f, v = cs[new], f[new], v[new]
        h = entry[f]
        a, b = fi[h], fi[nxt[h]]
        pos = _lay_triangles(V[a], V[b], V[v], N[f], uv[a], uv[b])
        first = np.unique(v, return_index=True)[1]
        uv[v[first]] = pos[first]
        placed[v[first]] = True
    used = t.used_vertex_mask
    uv[~used] = 0.0  # unused vertices stay at the origin (they are not part of the panel)
    if not np.all(np.isfinite(uv)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(uv), axis=1))[0])
        raise MeshError(f"vertex {bad} could not be laid out (degenerate face next to it)")
    return Layout(uv=uv, seed_face=seed, anchor=(a0, b0), levels=int(depth.max()) + 1)
