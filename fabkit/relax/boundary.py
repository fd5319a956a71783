"""An extra row of boundary faces (paper §2.5, Fig. 9): in plane, extruded out, extruded in.

Adding one quad outside every boundary edge turns the original boundary vertices into interior ones
(their angle sums must then reach 2π too); the new outer vertices are held fixed, so the row steers
the solution. After solving, `strip_row` drops the row again: the output keeps the input's vertex
order and faces.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabkit.mesh import PolyMesh

ROW_KINDS = ("row-in-plane", "row-out", "row-in")


@dataclass(frozen=True)
class ExtendedMesh:
    mesh: PolyMesh            # original vertices first (same ids), then the row's outer vertices
    n_original_vertices: int
    n_original_faces: int

    @property
    def row_vertex_mask(self) -> np.ndarray:
        m = np.zeros(self.mesh.n_vertices, dtype=bool)
        m[self.n_original_vertices:] = True
        return m


def _unit(a: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(a, axis=-1, keepdims=True)
    return a / np.where(n > 0, n, 1.0)


def add_boundary_row(mesh: PolyMesh, kind: str, width: float = 1.0, tilt: float = np.pi / 4) -> ExtendedMesh:
    """Mesh with one extra quad per boundary edge; outer vertices offset by `width` × mean boundary edge.

    kind: "row-in-plane" (offset along the outward in-plane direction, the bisector at corners),
    "row-out" (along the vertex normal, the front side, leaning outward by `tilt` rad), "row-in" (the
    back side, same lean). tilt = 0 extrudes exactly along the normal.
    """
    if kind not in ROW_KINDS:
        raise ValueError(f"row kind must be one of {', '.join(ROW_KINDS)}, got {kind!r}")
    t = mesh.topology
    V = mesh.vertices
    n = mesh.n_vertices
    normals = mesh.face_normals
    # vertex normals: sum of the faces' (unnormalised, area-weighted) normals
    vn = _unit(np.stack([np.bincount(t.face_indices, weights=mesh.face_normal_sums[t.corner_face][:, k],
                                     minlength=n) for k in range(3)], axis=1))
    # boundary half-edges a -> b (the mesh on their left) and their face normals
    bh = np.flatnonzero(t.halfedge_twin < 0)
    a = t.face_indices[bh]
    b = t.face_indices[t.corner_next[bh]]
    d = V[b] - V[a]
    mean_len = float(np.linalg.norm(d, axis=1).mean())
    h = width * mean_len
    outward = _unit(np.cross(d, normals[t.corner_face[bh]]))  # right of a->b seen from the front
    out_v = np.zeros((n, 3))
    np.add.at(out_v, a, outward)
    np.add.at(out_v, b, outward)
    out_v = _unit(out_v)
    new_id = np.full(n, -1, dtype=np.int64)
    bverts = np.unique(np.concatenate([a, b]))
    new_id[bverts] = n + np.arange(len(bverts))
    if kind == "row-in-plane":
        offset = out_v[bverts]
    else:
        # extruded: along the vertex normal (front side for "out"), leaning outward by `tilt` so the
        # row's angles at panel corners stay near what the corner needs (pure normals leave π/2 there)
        sign = 1.0 if kind == "row-out" else -1.0
        offset = _unit(np.cos(tilt) * sign * vn[bverts] + np.sin(tilt) * out_v[bverts])
    newV = V[bverts] + h * offset
    # outer quad for boundary edge a -> b: (b, a, a', b') runs b -> a, opposite to the inner face
    new_faces = np.stack([b, a, new_id[a], new_id[b]], axis=1)
    faces = mesh.faces_list() + new_faces.tolist()
    ext = PolyMesh(np.vstack([V, newV]), faces, validate=False)
    return ExtendedMesh(ext, n, mesh.n_faces)


def strip_row(extended: ExtendedMesh, X: np.ndarray) -> np.ndarray:
    """Positions of the original vertices from the extended mesh's positions X."""
    return np.asarray(X)[:extended.n_original_vertices]
