"""Polygon mesh with cached, read-only connectivity.

Dtype policy (said once): vertices are float64 `(n, 3)`, every index array is int64.
Faces of any size are stored compactly as CSR: `face_indices` (all corners, face after face)
and `face_offsets` (`m + 1` entries; face f is `face_indices[face_offsets[f]:face_offsets[f+1]]`).
A *corner* is a position in `face_indices`; corner c is also the half-edge from its vertex to the
next corner's vertex in the same face, so per-corner arrays double as per-half-edge arrays.

Faces are counter-clockwise seen from the front side. `PolyMesh` never reorders or merges the
user's vertices or faces (vertex ids are the model). Topology lives in `MeshTopology`
(`fabkit.mesh_topology`, re-exported here), shared by every mesh with the same faces, so
`mesh.with_vertices(V)` is cheap inside solvers.
"""
from __future__ import annotations

import warnings
from functools import cached_property
from typing import Mapping

import numpy as np

from fabkit.errors import MeshError
from fabkit.mesh_topology import MeshTopology, faces_to_csr, read_only

__all__ = ["MeshTopology", "PolyMesh", "validate_mesh", "faces_to_csr"]


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (k, 3) arrays (explicit components: several times faster than np.cross)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out


class PolyMesh:
    """Vertices plus shared topology, with read-only cached geometry.

    Construct with `PolyMesh(vertices, faces)`; faces may be a list of index sequences, an `(m, k)`
    array or a CSR `(indices, offsets)` pair. Per-element data (`face_data`, `vertex_data`: name ->
    array) rides along through every reader, writer and stage that keeps the topology.
    """

    def __init__(self, vertices, faces=None, *, topology: MeshTopology | None = None,
                 face_data: Mapping[str, np.ndarray] | None = None,
                 vertex_data: Mapping[str, np.ndarray] | None = None,
                 validate: bool = True):
        V = np.array(vertices, dtype=np.float64, copy=True)
        if V.ndim != 2 or V.shape[1] != 3:
            if V.ndim == 2 and V.shape[1] == 2:
                V = np.column_stack([V, np.zeros(len(V))])
            elif V.size == 0:
                V = V.reshape(0, 3)
            else:
                raise MeshError(f"vertices must be an (n, 3) array, got shape {V.shape}")
        self.vertices = read_only(V)
        if topology is None:
            if faces is None:
                raise MeshError("a mesh needs faces")
            idx, off = faces_to_csr(faces)
            topology = MeshTopology(idx, off, len(V))
        elif topology.n_vertices != len(V):
            raise MeshError(f"topology has {topology.n_vertices} vertices, coordinates have {len(V)}")
        self.topology = topology
        self.face_data = {k: read_only(np.asarray(v)) for k, v in (face_data or {}).items()}
        self.vertex_data = {k: read_only(np.asarray(v)) for k, v in (vertex_data or {}).items()}
        for k, v in self.face_data.items():
            if len(v) != topology.n_faces:
                raise MeshError(f"face data '{k}' has {len(v)} entries for {topology.n_faces} faces")
        for k, v in self.vertex_data.items():
            if len(v) != len(V):
                raise MeshError(f"vertex data '{k}' has {len(v)} entries for {len(V)} vertices")
        if validate:
            self.warnings = validate_mesh(self)
        else:
            self.warnings = []

    # ---- basic views ----------------------------------------------------------------------
    def __repr__(self) -> str:
        sizes = np.bincount(self.topology.face_sizes) if self.n_faces else []
        kinds = ", ".join(f"{c} {'tri' if k == 3 else 'quad' if k == 4 else f'{k}-gon'}s"
                          for k, c in enumerate(sizes) if c)
        return f"PolyMesh({self.n_vertices} vertices, {self.n_faces} faces: {kinds})"

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def n_faces(self) -> int:
        return self.topology.n_faces

    @property
    def n_edges(self) -> int:
        return self.topology.n_edges

    @property
    def face_indices(self) -> np.ndarray:
        return self.topology.face_indices

    @property
    def face_offsets(self) -> np.ndarray:
        return self.topology.face_offsets

    @property
    def edges(self) -> np.ndarray:
        return self.topology.edges

    @property
    def edge_faces(self) -> np.ndarray:
        return self.topology.edge_faces

    @property
    def face_sizes(self) -> np.ndarray:
        return self.topology.face_sizes

    @property
    def boundary_loops(self) -> tuple[np.ndarray, ...]:
        return self.topology.boundary_loops

    @property
    def boundary_vertex_mask(self) -> np.ndarray:
        return self.topology.boundary_vertex_mask

    @property
    def interior_vertex_mask(self) -> np.ndarray:
        return self.topology.interior_vertex_mask

    def faces_list(self) -> list[list[int]]:
        return self.topology.faces_list()

    def face(self, f: int) -> np.ndarray:
        return self.topology.face(f)

    def with_vertices(self, vertices, *, check_finite: bool = True) -> "PolyMesh":
        """Same topology and data, new coordinates (no re-validation of the topology)."""
        V = np.asarray(vertices, dtype=np.float64)
        if V.shape != self.vertices.shape:
            raise MeshError(f"new vertices have shape {V.shape}, expected {self.vertices.shape}")
        if check_finite and not np.all(np.isfinite(V)):
            v = int(np.flatnonzero(~np.all(np.isfinite(V), axis=1))[0])
            raise MeshError(f"vertex {v} has a non-finite coordinate")
        return PolyMesh(V, topology=self.topology, face_data=self.face_data, vertex_data=self.vertex_data,
                        validate=False)

    def with_data(self, *, face_data: Mapping | None = None, vertex_data: Mapping | None = None) -> "PolyMesh":
        """Same geometry, data updated (merged) with the given arrays."""
        fd = {**self.face_data, **(face_data or {})}
        vd = {**self.vertex_data, **(vertex_data or {})}
        return PolyMesh(self.vertices, topology=self.topology, face_data=fd, vertex_data=vd, validate=False)

    # ---- cached geometry --------------------------------------------------------------------
    @cached_property
    def corner_cross(self) -> np.ndarray:
        """Per corner: (next - here) x (prev - here); points to the front side at convex corners."""
        t = self.topology
        V = self.vertices
        here = V[t.face_indices]
        u = V[t.face_indices[t.corner_next]] - here
        w = V[t.face_indices[t.corner_prev]] - here
        return read_only(cross3(u, w))

    @cached_property
    def face_normal_sums(self) -> np.ndarray:
        """Sum of corner cross products per face (the paper's best-fit plane normal, unnormalised)."""
        return read_only(np.add.reduceat(self.corner_cross, self.face_offsets[:-1], axis=0)
                         if self.n_faces else np.zeros((0, 3)))

    @cached_property
    def face_normals(self) -> np.ndarray:
        """Unit face normals (sum of corner cross products, normalised)."""
        n = self.face_normal_sums
        length = np.linalg.norm(n, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            return read_only(np.where(length > 0, n / length, 0.0))

    @cached_property
    def face_centroids(self) -> np.ndarray:
        """Mean of each face's vertices (the paper's plane origin)."""
        s = np.add.reduceat(self.vertices[self.face_indices], self.face_offsets[:-1], axis=0) \
            if self.n_faces else np.zeros((0, 3))
        return read_only(s / self.face_sizes[:, None])

    @cached_property
    def face_areas(self) -> np.ndarray:
        """Vector-area magnitude per face (exact for planar polygons)."""
        V = self.vertices
        t = self.topology
        a = cross3(V[t.face_indices], V[t.face_indices[t.corner_next]])
        s = np.add.reduceat(a, self.face_offsets[:-1], axis=0) if self.n_faces else np.zeros((0, 3))
        return read_only(0.5 * np.linalg.norm(s, axis=1))

    @cached_property
    def edge_lengths(self) -> np.ndarray:
        e = self.edges
        return read_only(np.linalg.norm(self.vertices[e[:, 1]] - self.vertices[e[:, 0]], axis=1))

    @cached_property
    def bounding_box(self) -> np.ndarray:
        used = self.vertices[self.topology.used_vertex_mask]
        return read_only(np.array([used.min(axis=0), used.max(axis=0)]))

    @property
    def size(self) -> float:
        """Diagonal of the bounding box: the panel size used for relative tolerances."""
        bb = self.bounding_box
        return float(np.linalg.norm(bb[1] - bb[0]))

    def triangulate(self) -> tuple[np.ndarray, np.ndarray]:
        """Fan triangulation `(triangles (t, 3), triangle_face (t,))`; quads split along the 0-2 diagonal.

        Keeps the map back to the polygon each triangle came from.
        """
        t = self.topology
        sizes = t.face_sizes
        n_tri = sizes - 2
        tri_face = np.repeat(np.arange(self.n_faces, dtype=np.int64), n_tri)
        first = np.repeat(t.face_offsets[:-1], n_tri)
        k = np.arange(len(tri_face)) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
        tris = np.stack([t.face_indices[first], t.face_indices[first + k + 1], t.face_indices[first + k + 2]], axis=1)
        return tris, tri_face

    def to_trimesh(self):
        """A trimesh.Trimesh for viewing/export (triangulated; process=False keeps vertex ids)."""
        import trimesh

        tris, _ = self.triangulate()
        return trimesh.Trimesh(vertices=np.array(self.vertices), faces=tris, process=False)


def validate_mesh(mesh: PolyMesh, *, source: str | None = None, area_rtol: float = 1e-12) -> list[str]:
    """Check a mesh once at the public boundary; raise `MeshError` naming the element, return warnings.

    Structural checks (indices, face sizes, repeated vertices, non-manifold edges, orientation)
    already ran when the topology was built; this adds coordinates and degenerate faces, and warns
    about unused vertices.
    """
    V = mesh.vertices
    bad = ~np.all(np.isfinite(V), axis=1)
    if np.any(bad):
        v = int(np.flatnonzero(bad)[0])
        raise MeshError(f"vertex {v} has a non-finite coordinate {V[v].tolist()}", source=source)
    if mesh.n_faces == 0:
        raise MeshError("mesh has no faces", source=source)
    t = mesh.topology
    # zero-area faces: compare the vector area with the squared longest edge of the face
    corner_len = np.linalg.norm(V[t.face_indices[t.corner_next]] - V[t.face_indices], axis=1)
    longest = np.maximum.reduceat(corner_len, t.face_offsets[:-1])
    tiny = mesh.face_areas <= area_rtol * np.maximum(longest, 1e-300) ** 2
    if np.any(tiny):
        f = int(np.flatnonzero(tiny)[0])
        raise MeshError(f"face {f} has zero area (vertices {t.face(f).tolist()})", source=source)
    warn = []
    unused = np.flatnonzero(~t.used_vertex_mask)
    if len(unused):
        msg = f"{len(unused)} unused vertices (first: {int(unused[0])}); they are kept, ids unchanged"
        warn.append(msg)
        warnings.warn(f"{source}: {msg}" if source else msg, stacklevel=3)
    return warn
