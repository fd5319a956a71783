"""Topology edits for Fig. 3 steps c, d and f: inset, delete faces, extrude border edges, dissolve
edges and vertices (retopologise), and drop unused vertices with an explicit index map.

Every function returns a new, validated `PolyMesh`; `face_data` rides along (a merged face keeps
the data of the lowest-numbered face it absorbed, new faces get the data of the face they grew
from). Vertex ids only change in `compact`, which returns the map. Written by hand: trimesh works
on triangles only, and these edits must keep polygons and our tags.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from fabkit.errors import MeshError
from fabkit.mesh import PolyMesh

__all__ = ["compact", "delete_faces", "inset_faces", "extrude_border_edges", "dissolve_edges",
           "dissolve_vertices", "boundary_halfedges", "edge_loop", "remove_edge_loops"]


def _as_mask(sel, n: int, what: str) -> np.ndarray:
    sel = np.asarray(sel)
    if sel.dtype == bool:
        if sel.shape != (n,):
            raise ValueError(f"{what} mask has shape {sel.shape}, expected ({n},)")
        return sel.copy()
    m = np.zeros(n, dtype=bool)
    sel = sel.astype(np.int64).ravel()
    if len(sel) and (sel.min() < 0 or sel.max() >= n):
        raise ValueError(f"{what} index out of range 0..{n - 1}")
    m[sel] = True
    return m


def _faces_from(mesh: PolyMesh, keep: np.ndarray) -> list[list[int]]:
    t = mesh.topology
    idx, off = t.face_indices.tolist(), t.face_offsets.tolist()
    return [idx[off[f]:off[f + 1]] for f in np.flatnonzero(keep).tolist()]


def compact(mesh: PolyMesh) -> tuple[PolyMesh, np.ndarray]:
    """Drop unused vertices: `(mesh, old_ids)`, new vertex i was old vertex `old_ids[i]`."""
    used = mesh.topology.used_vertex_mask
    old = np.flatnonzero(used)
    new_of = np.full(mesh.n_vertices, -1, dtype=np.int64)
    new_of[old] = np.arange(len(old))
    t = mesh.topology
    out = PolyMesh(mesh.vertices[old], (new_of[t.face_indices], t.face_offsets.copy()),
                   face_data=mesh.face_data, vertex_data={k: v[old] for k, v in mesh.vertex_data.items()})
    return out, old


def delete_faces(mesh: PolyMesh, faces) -> tuple[PolyMesh, np.ndarray]:
    """Remove the given faces (indices or mask) and the vertices no face uses any more.

    Returns `(mesh, old_vertex_ids)`; the remaining faces keep their order and data.
    """
    drop = _as_mask(faces, mesh.n_faces, "face")
    keep = ~drop
    if not keep.any():
        raise MeshError("deleting these faces would leave no faces")
    t = mesh.topology
    sizes = t.face_sizes[keep]
    off = np.zeros(len(sizes) + 1, np.int64)
    np.cumsum(sizes, out=off[1:])
    idx = t.face_indices[keep[t.corner_face]]
    sub = PolyMesh(mesh.vertices, (idx, off), face_data={k: v[keep] for k, v in mesh.face_data.items()},
                   vertex_data=mesh.vertex_data, validate=False)
    return compact(sub)


def inset_faces(mesh: PolyMesh, faces, t: float = 0.2) -> PolyMesh:
    """Shrink the given faces towards their centroid by `t` and join old and new edges with quads.

    The ring quads bevel the face's border edges. New vertices are appended (one per corner of each
    inset face, in corner order). face_data["inset"]: 0 untouched, 1 the shrunk face, 2 a ring quad;
    other face data is copied from the inset face.
    """
    if not 0 < t < 1:
        raise ValueError(f"inset fraction must be in (0, 1), got {t}")
    sel = _as_mask(faces, mesh.n_faces, "face")
    top = mesh.topology
    n = mesh.n_vertices
    corners = np.flatnonzero(sel[top.corner_face])
    new_id = np.full(len(top.face_indices), -1, np.int64)
    new_id[corners] = n + np.arange(len(corners))
    cent = mesh.face_centroids[top.corner_face[corners]]
    V = np.vstack([mesh.vertices, (1 - t) * mesh.vertices[top.face_indices[corners]] + t * cent])
    out_faces, parent, kind = [], [], []
    idx = top.face_indices
    nxt = top.corner_next
    for f in range(mesh.n_faces):
        cs = np.arange(top.face_offsets[f], top.face_offsets[f + 1])
        if not sel[f]:
            out_faces.append(idx[cs].tolist())
            parent.append(f)
            kind.append(0)
            continue
        out_faces.append(new_id[cs].tolist())
        parent.append(f)
        kind.append(1)
        for c in cs:
            d = nxt[c]
            out_faces.append([int(idx[c]), int(idx[d]), int(new_id[d]), int(new_id[c])])
            parent.append(f)
            kind.append(2)
    parent = np.array(parent)
    fd = {k: v[parent] for k, v in mesh.face_data.items()}
    fd["inset"] = np.array(kind, dtype=np.int64)
    vd = {k: np.concatenate([v, v[idx[corners]]]) for k, v in mesh.vertex_data.items()}
    return PolyMesh(V, out_faces, face_data=fd, vertex_data=vd)


def boundary_halfedges(mesh: PolyMesh) -> np.ndarray:
    """Corners whose half-edge (corner vertex -> next corner vertex) lies on the boundary."""
    return np.flatnonzero(mesh.topology.halfedge_twin < 0)


def extrude_border_edges(mesh: PolyMesh, length: float, edges=None, direction: str = "tangent",
                         vector: Sequence[float] | None = None) -> PolyMesh:
    """Grow a strip of quads outwards from boundary edges (all of them, or the given edge ids).

    direction: "tangent" (in the surface, perpendicular to the border, away from the mesh),
    "loop" (towards the centroid of the vertex's boundary loop: in the loop's plane when the loop
    is planar, e.g. filling a hole left by a deleted planar face), "normal" (along the
    area-weighted vertex normal; a negative length goes inwards) or "vector" (along `vector`). length [m]. Each border vertex gets one new vertex (appended);
    each chosen edge one quad carrying the data of the face it grew from and face_data
    ["extruded"] = 1 (0 elsewhere).
    """
    top = mesh.topology
    bh = boundary_halfedges(mesh)
    if edges is not None:
        chosen = _as_mask(edges, mesh.n_edges, "edge")
        bh = bh[chosen[top.halfedge_edge[bh]]]
        if len(bh) != int(chosen.sum()):
            raise MeshError("extrude_border_edges: some chosen edges are not on the boundary")
    if len(bh) == 0:
        raise MeshError("extrude_border_edges: no boundary edges to extrude")
    if not (np.isfinite(length) and length != 0):
        raise ValueError(f"extrusion length must be finite and non-zero, got {length}")
    idx = top.face_indices
    a, b = idx[bh], idx[top.corner_next[bh]]
    V0 = mesh.vertices
    verts = np.unique(np.concatenate([a, b]))
    counts = np.bincount(np.concatenate([a, b]), minlength=mesh.n_vertices)
    if np.any(counts[verts] > 2):
        v = int(verts[np.argmax(counts[verts] > 2)])
        raise MeshError(f"extrude_border_edges: vertex {v} has more than two chosen border edges (a pinch)")
    new_of = np.full(mesh.n_vertices, -1, np.int64)
    new_of[verts] = mesh.n_vertices + np.arange(len(verts))
    if direction == "tangent":
        fn = mesh.face_normals[top.corner_face[bh]]
        out = np.cross(V0[b] - V0[a], fn)  # to the right of a->b: away from the face
        out /= np.linalg.norm(out, axis=1, keepdims=True)
        d = np.zeros_like(V0)
        np.add.at(d, a, out)
        np.add.at(d, b, out)
    elif direction == "loop":
        d = np.zeros_like(V0)
        for loop in top.boundary_loops:
            d[loop] = V0[loop].mean(axis=0) - V0[loop]
    elif direction == "normal":
        d = np.zeros_like(V0)
        np.add.at(d, idx, mesh.face_normal_sums[top.corner_face])
    elif direction == "vector":
        if vector is None or np.shape(vector) != (3,):
            raise ValueError("direction='vector' needs a 3-vector")
        d = np.tile(np.asarray(vector, float), (mesh.n_vertices, 1))
    else:
        raise ValueError(f"unknown extrusion direction {direction!r} (tangent, loop, normal or vector)")
    dv = d[verts]
    norm = np.linalg.norm(dv, axis=1, keepdims=True)
    if np.any(norm < 1e-300):
        raise MeshError("extrude_border_edges: a border vertex has no defined direction")
    V = np.vstack([V0, V0[verts] + length * dv / norm])
    faces = mesh.faces_list()
    new = [[int(bb), int(aa), int(new_of[aa]), int(new_of[bb])] for aa, bb in zip(a, b)]
    parent = np.concatenate([np.arange(mesh.n_faces), top.corner_face[bh]])
    fd = {k: v[parent] for k, v in mesh.face_data.items()}
    fd["extruded"] = np.concatenate([np.zeros(mesh.n_faces, np.int64), np.ones(len(new), np.int64)])
    vd = {k: np.concatenate([v, v[verts]]) for k, v in mesh.vertex_data.items()}
    return PolyMesh(V, faces + new, face_data=fd, vertex_data=vd)


def dissolve_edges(mesh: PolyMesh, edges) -> PolyMesh:
    """Remove interior edges, merging the faces on both sides into one polygon.

    The merged polygon is the boundary of the union of the faces, walked in the faces' own
    direction, so orientation is kept. Refused when a merge would make a face with a hole or touch
    itself (the union of the merged faces must be a disk bounded by one loop).
    Vertices left with only two edges stay in the polygon: remove them with `dissolve_vertices`.
    """
    top = mesh.topology
    sel = _as_mask(edges, mesh.n_edges, "edge")
    if np.any(sel & top.boundary_edge_mask):
        e = int(np.flatnonzero(sel & top.boundary_edge_mask)[0])
        raise MeshError(f"edge {e} {top.edges[e].tolist()} is on the boundary; only interior edges can be dissolved")
    # union-find over faces
    parent = np.arange(mesh.n_faces)

    def find(x):
        root = x
        while parent[root] != root:
            root = parent[root]
        while parent[x] != root:
            parent[x], x = root, parent[x]
        return root

    for e in np.flatnonzero(sel):
        fl, fr = (int(f) for f in top.edge_faces[e])
        ra, rb = find(fl), find(fr)
        if ra == rb:
            raise MeshError(f"dissolving edge {e} {top.edges[e].tolist()} would close a loop of merged faces")
        parent[max(ra, rb)] = min(ra, rb)
    group = np.array([find(f) for f in range(mesh.n_faces)])
    idx = top.face_indices
    nxt = top.corner_next
    twin = top.halfedge_twin
    # a corner survives when its half-edge is not a dissolved edge
    alive = ~sel[top.halfedge_edge]
    # next surviving half-edge after c in the merged polygon: from the end vertex of c, rotate through
    # dissolved half-edges: next(c) if alive, else next(twin(next(c))) ...
    faces_out, fdata_parent = [], []
    # corners grouped by merged face (one sort instead of a scan per group)
    corner_group = group[top.corner_face]
    order = np.argsort(corner_group, kind="stable")
    roots, starts = np.unique(corner_group[order], return_index=True)
    bounds = np.append(starts, len(order))
    for k, g in enumerate(roots):
        cs = order[bounds[k]:bounds[k + 1]]
        members = np.unique(top.corner_face[cs])
        cs = cs[alive[cs]]
        start = int(cs[0])
        poly = []
        c = start
        for _ in range(len(cs) + 1):
            poly.append(int(idx[c]))
            d = int(nxt[c])
            for _ in range(len(idx)):
                if alive[d]:
                    break
                d = int(nxt[twin[d]])
            c = d
            if c == start:
                break
        if len(poly) != len(cs):
            raise MeshError(f"merging faces {members.tolist()} gives a region with a hole or a pinch")
        faces_out.append(poly)
        fdata_parent.append(int(g))
    fdp = np.array(fdata_parent)
    return PolyMesh(mesh.vertices, faces_out, face_data={k: v[fdp] for k, v in mesh.face_data.items()},
                    vertex_data=mesh.vertex_data)


def dissolve_vertices(mesh: PolyMesh, vertices) -> tuple[PolyMesh, np.ndarray]:
    """Remove vertices that have exactly two edges (the two edges become one) and compact.

    Returns `(mesh, old_vertex_ids)`. A vertex with more edges is refused (dissolve its extra
    edges first), and so is one whose removal would leave a face with fewer than 3 vertices.
    """
    sel = _as_mask(vertices, mesh.n_vertices, "vertex")
    val = mesh.topology.vertex_valence
    bad = np.flatnonzero(sel & (val != 2))
    if len(bad):
        v = int(bad[0])
        raise MeshError(f"vertex {v} has {int(val[v])} edges; only vertices with two edges can be dissolved")
    faces = [[v for v in f if not sel[v]] for f in mesh.faces_list()]
    for k, f in enumerate(faces):
        if len(f) < 3:
            raise MeshError(f"dissolving these vertices leaves face {k} with {len(f)} vertices")
    sub = PolyMesh(mesh.vertices, faces, face_data=mesh.face_data, vertex_data=mesh.vertex_data, validate=False)
    return compact(sub)


def edge_loop(mesh: PolyMesh, edge: int) -> np.ndarray:
    """The quad-mesh edge loop through `edge`: ordered edge ids.

    From each end, the loop continues through vertices with four edges and four quads to the edge
    that shares no face with the incoming one; it stops at the boundary, at an irregular vertex or
    when it closes.
    """
    top = mesh.topology
    E = mesh.edges
    if not 0 <= edge < mesh.n_edges:
        raise ValueError(f"edge {edge} out of range 0..{mesh.n_edges - 1}")
    vf_faces, vf_off = top.vertex_faces
    by_vertex: dict[int, list[int]] = {}
    for e, (a, b) in enumerate(E.tolist()):
        by_vertex.setdefault(a, []).append(e)
        by_vertex.setdefault(b, []).append(e)
    sizes = top.face_sizes

    def step(e: int, v: int) -> int:
        es = by_vertex[v]
        faces = vf_faces[vf_off[v]:vf_off[v + 1]]
        if len(es) != 4 or len(faces) != 4 or np.any(sizes[faces] != 4) or top.boundary_vertex_mask[v]:
            return -1
        fe = set(int(f) for f in top.edge_faces[e] if f >= 0)
        rest = [x for x in es if x != e and not (set(int(f) for f in top.edge_faces[x] if f >= 0) & fe)]
        return rest[0] if len(rest) == 1 else -1

    loop = [int(edge)]
    closed = False
    for direction in (1, 0):
        e, v = int(edge), int(E[edge, direction])
        for _ in range(mesh.n_edges):
            nxt = step(e, v)
            if nxt < 0:
                break
            if nxt == edge:
                closed = True
                break
            (loop.append if direction == 1 else lambda x: loop.insert(0, x))(nxt)
            v = int(E[nxt, 1] if E[nxt, 0] == v else E[nxt, 0])
            e = nxt
        if closed:
            break
    return np.array(loop, dtype=np.int64)


def remove_edge_loops(mesh: PolyMesh, edges: Sequence[int]) -> tuple[PolyMesh, np.ndarray]:
    """Remove the edge loops through the given edges and the vertices they leave with two edges.

    The faces on both sides of each loop merge (a quad strip on each side becomes one strip), and
    a vertex that had more than two edges before and two after is dissolved, so the rulings across
    the removed loop become single edges. Returns `(mesh, old_vertex_ids)`.
    """
    top = mesh.topology
    sel = np.zeros(mesh.n_edges, dtype=bool)
    for e in edges:
        sel[edge_loop(mesh, int(e))] = True
    if np.any(sel & top.boundary_edge_mask):
        raise MeshError("an edge loop to remove runs along the boundary")
    before = top.vertex_valence
    merged = dissolve_edges(mesh, sel)
    after = merged.topology.vertex_valence
    lone = np.flatnonzero((after == 2) & (before > 2))
    return dissolve_vertices(merged, lone)
