"""Conway polyhedron operators used by Fig. 3 (steps b and c): ambo, truncate, chamfer, bevel.

Definitions (Hart, "Conway notation for polyhedra"; counts for a cube in brackets):
- ambo `a`: one vertex per edge (its midpoint); a face per old face (the midpoints of its edges)
  and a face per old vertex (the midpoints of its edges, in cyclic order) [cube -> cuboctahedron
  12 V / 24 E / 14 F].
- truncate `t`: every vertex cut off at fraction `t` along its edges; a k-gon becomes a 2k-gon and
  each vertex of valence n an n-gon [cube -> 24 V / 36 E / 14 F].
- bevel `b = t a` (truncate of ambo) [cube -> truncated cuboctahedron 48 V / 72 E / 26 F].
- chamfer `c`: every face shrunk towards its centroid by `t` (a copy of the face), the old
  vertices kept, and every old edge replaced by a hexagon (both ends of the edge plus the two
  shrunk copies of it) [cube -> 32 V / 48 E / 18 F].

All operators need a closed, consistently oriented mesh (an open one is refused: its boundary
vertices have no complete ring) and keep orientation (outward stays outward). Written by hand:
compas has these operators, but over its own half-edge datastructure and pure Python; ours are
numpy over `MeshTopology` and return the tags the Fig. 3 pipeline needs (`face_data["origin"]`:
0 = from an old face, 1 = from an old edge, 2 = from an old vertex; `face_data["source"]`: the
index of that old element).
"""
from __future__ import annotations

import numpy as np

from fabkit.errors import MeshError
from fabkit.mesh import MeshTopology, PolyMesh

__all__ = ["vertex_rings", "ambo", "truncate", "chamfer", "bevel", "ORIGIN_FACE", "ORIGIN_EDGE", "ORIGIN_VERTEX"]

ORIGIN_FACE, ORIGIN_EDGE, ORIGIN_VERTEX = 0, 1, 2


def _require_closed(mesh: PolyMesh, op: str) -> None:
    if np.any(mesh.topology.halfedge_twin < 0):
        raise MeshError(f"{op} needs a closed mesh; this one has {len(mesh.boundary_loops)} boundary loop(s)")


def vertex_rings(topology: MeshTopology) -> list[np.ndarray]:
    """For every vertex with a closed ring: its corners in cyclic order, the order in which a face
    around the vertex must list them to face the same way as the mesh (checked by `MeshTopology`).

    Step: from corner c at v the half-edge into v is prev(c); its twin leaves v in the neighbouring
    face. Vertices on the boundary (open ring) or with a non-manifold fan get an empty array.
    """
    t = topology
    twin, prev = t.halfedge_twin, t.corner_prev
    corners, off = t.vertex_corners
    rings = []
    for v in range(t.n_vertices):
        cs = corners[off[v]:off[v + 1]]
        if len(cs) == 0:
            rings.append(np.zeros(0, np.int64))
            continue
        ring = [int(cs[0])]
        ok = True
        for _ in range(len(cs)):
            h = int(twin[prev[ring[-1]]])
            if h < 0:
                ok = False
                break
            if h == ring[0]:
                break
            ring.append(h)
        if not ok or len(ring) != len(cs):
            rings.append(np.zeros(0, np.int64))
            continue
        rings.append(np.array(ring, dtype=np.int64))
    return rings


def ambo(mesh: PolyMesh) -> PolyMesh:
    """Conway ambo (rectification): vertices at edge midpoints."""
    _require_closed(mesh, "ambo")
    t = mesh.topology
    E = mesh.edges
    V = 0.5 * (mesh.vertices[E[:, 0]] + mesh.vertices[E[:, 1]])
    he = t.halfedge_edge
    faces = [he[t.face_offsets[f]:t.face_offsets[f + 1]].tolist() for f in range(mesh.n_faces)]
    origin = [ORIGIN_FACE] * len(faces)
    source = list(range(len(faces)))
    for v, ring in enumerate(vertex_rings(t)):
        if len(ring):
            # the edge leaving v at each corner, counter-clockwise around v: the new face's boundary
            faces.append(he[ring].tolist())
            origin.append(ORIGIN_VERTEX)
            source.append(v)
    return PolyMesh(V, faces, face_data={"origin": np.array(origin), "source": np.array(source)})


def truncate(mesh: PolyMesh, t: float = 1.0 / 3.0) -> PolyMesh:
    """Conway truncate: cut every vertex at fraction `t` (0 < t < 1/2) of each incident edge."""
    _require_closed(mesh, "truncate")
    if not 0 < t < 0.5:
        raise ValueError(f"truncate fraction must be in (0, 1/2), got {t}")
    top = mesh.topology
    Vo = mesh.vertices
    idx = top.face_indices
    nxt = top.corner_next
    # two new vertices per half-edge c (a -> b): near a (index 2c) and near b (index 2c + 1);
    # twins share them, so number them per edge: edge e gets 2e (near lo) and 2e + 1 (near hi)
    E = mesh.edges
    V = np.vstack([(1 - t) * Vo[E[:, 0]] + t * Vo[E[:, 1]], (1 - t) * Vo[E[:, 1]] + t * Vo[E[:, 0]]])
    nE = len(E)
    near_lo, near_hi = np.arange(nE), nE + np.arange(nE)
    he = top.halfedge_edge
    a, b = idx, idx[nxt]
    start_pt = np.where(a < b, near_lo[he], near_hi[he])  # point of half-edge c near its start a
    end_pt = np.where(a < b, near_hi[he], near_lo[he])  # near its end b
    faces, origin, source = [], [], []
    for f in range(mesh.n_faces):
        cs = range(top.face_offsets[f], top.face_offsets[f + 1])
        faces.append([p for c in cs for p in (int(start_pt[c]), int(end_pt[c]))])
        origin.append(ORIGIN_FACE)
        source.append(f)
    for v, ring in enumerate(vertex_rings(top)):
        if len(ring):
            faces.append(start_pt[ring].tolist())
            origin.append(ORIGIN_VERTEX)
            source.append(v)
    return PolyMesh(V, faces, face_data={"origin": np.array(origin), "source": np.array(source)})


def bevel(mesh: PolyMesh, t: float = 1.0 / 3.0) -> PolyMesh:
    """Conway bevel = truncate(ambo(mesh)); `origin`/`source` refer to the input mesh's elements."""
    am = ambo(mesh)
    tr = truncate(am, t)
    # faces of tr: first one per ambo face (origin of that ambo face), then one per ambo vertex (= old edge)
    # truncate made one face per ambo face, then one per ambo vertex (every ambo vertex of a closed
    # mesh has a full ring), and ambo vertex i is the old edge i
    origin = np.concatenate([am.face_data["origin"], np.full(am.n_vertices, ORIGIN_EDGE)])
    source = np.concatenate([am.face_data["source"], np.arange(am.n_vertices)])
    return tr.with_data(face_data={"origin": origin, "source": source})


def chamfer(mesh: PolyMesh, t: float = 0.25) -> PolyMesh:
    """Conway chamfer: faces shrunk by `t` (0 < t < 1) towards their centroid, old edges -> hexagons.

    Vertices: the old ones (same ids) then one per corner (``n + c``). Faces: the shrunk copies
    (origin 0, same order), then one hexagon per old edge (origin 1, edge order).
    """
    _require_closed(mesh, "chamfer")
    if not 0 < t < 1:
        raise ValueError(f"chamfer fraction must be in (0, 1), got {t}")
    top = mesh.topology
    n = mesh.n_vertices
    idx = top.face_indices
    cent = mesh.face_centroids[top.corner_face]
    V = np.vstack([mesh.vertices, (1 - t) * mesh.vertices[idx] + t * cent])
    shrunk = [(n + np.arange(top.face_offsets[f], top.face_offsets[f + 1])).tolist() for f in range(mesh.n_faces)]
    eh = top.edge_halfedges  # [lo->hi half-edge (left face), hi->lo half-edge (right face)]
    nxt = top.corner_next
    hexes = []
    for e in range(mesh.n_edges):
        h, g = int(eh[e, 0]), int(eh[e, 1])  # h: a -> b in face fl, g: b -> a in face fr
        a, b = int(idx[h]), int(idx[g])
        # the shrunk edges run p(fl,a)->p(fl,b) and p(fr,b)->p(fr,a); the hexagon runs against both
        hexes.append([n + int(nxt[h]), n + h, a, n + int(nxt[g]), n + g, b])
    origin = [ORIGIN_FACE] * len(shrunk) + [ORIGIN_EDGE] * len(hexes)
    source = list(range(len(shrunk))) + list(range(len(hexes)))
    return PolyMesh(V, shrunk + hexes, face_data={"origin": np.array(origin), "source": np.array(source)})
