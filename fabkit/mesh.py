"""Polygon mesh with cached, read-only connectivity.

Dtype policy (said once): vertices are float64 `(n, 3)`, every index array is int64.
Faces of any size are stored compactly as CSR: `face_indices` (all corners, face after face)
and `face_offsets` (`m + 1` entries; face f is `face_indices[face_offsets[f]:face_offsets[f+1]]`).
A *corner* is a position in `face_indices`; corner c is also the half-edge from its vertex to the
next corner's vertex in the same face, so per-corner arrays double as per-half-edge arrays.

Faces are counter-clockwise seen from the front side. `PolyMesh` never reorders or merges the
user's vertices or faces (vertex ids are the model). Topology lives in `MeshTopology`, shared by
every mesh with the same faces, so `mesh.with_vertices(V)` is cheap inside solvers.
"""
from __future__ import annotations

import warnings
from functools import cached_property
from typing import Iterable, Mapping, Sequence

import numpy as np

from fabkit.errors import MeshError

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


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    a.setflags(write=False)
    return a


def faces_to_csr(faces) -> tuple[np.ndarray, np.ndarray]:
    """Faces as a list of sequences, an `(m, k)` array, or an `(indices, offsets)` pair -> CSR arrays."""
    if isinstance(faces, tuple) and len(faces) == 2 and all(isinstance(x, np.ndarray) for x in faces):
        indices, offsets = (np.asarray(x, dtype=np.int64) for x in faces)
        return indices, offsets
    if isinstance(faces, np.ndarray) and faces.ndim == 2:
        m, k = faces.shape
        return faces.astype(np.int64).ravel(), np.arange(0, m * k + 1, k, dtype=np.int64) if m else np.zeros(1, np.int64)
    faces = list(faces)
    sizes = np.fromiter((len(f) for f in faces), dtype=np.int64, count=len(faces))
    offsets = np.zeros(len(faces) + 1, dtype=np.int64)
    np.cumsum(sizes, out=offsets[1:])
    if len(faces) == 0:
        return np.zeros(0, np.int64), offsets
    indices = np.fromiter((int(i) for f in faces for i in f), dtype=np.int64, count=int(offsets[-1]))
    return indices, offsets


class MeshTopology:
    """Connectivity of a polygon mesh; built from faces and the vertex count only.

    Raises `MeshError` (naming the element) for index errors, faces with fewer than 3 or repeated
    vertices, non-manifold edges and inconsistent orientation: every cached array below assumes a
    consistently oriented manifold-with-boundary.
    """

    def __init__(self, face_indices: np.ndarray, face_offsets: np.ndarray, n_vertices: int):
        self.n_vertices = int(n_vertices)
        self.face_indices = _readonly(np.ascontiguousarray(face_indices, dtype=np.int64))
        self.face_offsets = _readonly(np.ascontiguousarray(face_offsets, dtype=np.int64))
        self._check_structure()
        self._build_edges()

    # ---- construction -------------------------------------------------------------------
    def _check_structure(self) -> None:
        idx, off = self.face_indices, self.face_offsets
        if off.ndim != 1 or len(off) < 1 or off[0] != 0 or off[-1] != len(idx) or np.any(np.diff(off) < 0):
            raise MeshError("face offsets are not a valid CSR array")
        sizes = np.diff(off)
        small = np.flatnonzero(sizes < 3)
        if len(small):
            f = int(small[0])
            raise MeshError(f"face {f} has {int(sizes[f])} vertices (a face needs at least 3)")
        bad = np.flatnonzero((idx < 0) | (idx >= self.n_vertices))
        if len(bad):
            c = int(bad[0])
            f = int(np.searchsorted(off, c, side="right") - 1)
            raise MeshError(f"face {f} refers to vertex {int(idx[c])}, but vertices are numbered 0..{self.n_vertices - 1}")
        # repeated vertex inside one face: sort (face, vertex) pairs and look for equal neighbours
        cf = self.corner_face
        order = np.lexsort((idx, cf))
        same = (cf[order][1:] == cf[order][:-1]) & (idx[order][1:] == idx[order][:-1])
        if np.any(same):
            k = int(np.flatnonzero(same)[0])
            raise MeshError(f"face {int(cf[order][k])} repeats vertex {int(idx[order][k])}")

    def _build_edges(self) -> None:
        n = self.n_vertices
        u = self.face_indices
        v = self.face_indices[self.corner_next]
        lo, hi = np.minimum(u, v), np.maximum(u, v)
        keys = lo * n + hi
        uniq, inverse = np.unique(keys, return_inverse=True)
        if len(uniq):
            q, r = np.divmod(uniq, n)
            self.edges = _readonly(np.stack([q, r], axis=1).astype(np.int64, copy=False))
        else:
            self.edges = _readonly(np.zeros((0, 2), np.int64))
        self.halfedge_edge = _readonly(inverse.astype(np.int64, copy=False))
        E = len(uniq)
        counts = np.bincount(inverse, minlength=E)
        over = np.flatnonzero(counts > 2)
        if len(over):
            e = int(over[0])
            fs = sorted(int(f) for f in self.corner_face[inverse == e])
            raise MeshError(f"edge ({self.edges[e, 0]}, {self.edges[e, 1]}) is shared by {len(fs)} faces {fs} "
                            "(non-manifold: an edge may border at most 2 faces)")
        forward = u < v  # half-edge runs lo -> hi: its face is on the edge's left (FOLD edges_faces[0])
        slot = np.where(forward, 0, 1)
        key2 = inverse * 2 + slot
        c2 = np.bincount(key2, minlength=2 * E)
        dup = np.flatnonzero(c2 > 1)
        if len(dup):
            e = int(dup[0] // 2)
            fs = sorted(int(f) for f in self.corner_face[key2 == dup[0]])
            a, b = (self.edges[e] if dup[0] % 2 == 0 else self.edges[e][::-1])
            raise MeshError(f"faces {fs[0]} and {fs[1]} both run along edge {a}->{b} in the same direction "
                            "(inconsistent orientation: flip one of them)")
        ef = np.full((E, 2), -1, dtype=np.int64)
        ef[inverse, slot] = self.corner_face
        self.edge_faces = _readonly(ef)
        eh = np.full((E, 2), -1, dtype=np.int64)
        eh[inverse, slot] = np.arange(len(u))
        self.edge_halfedges = _readonly(eh)

    # ---- corners / half-edges -----------------------------------------------------------
    @property
    def n_faces(self) -> int:
        return len(self.face_offsets) - 1

    @property
    def n_edges(self) -> int:
        return len(self.edges)

    @cached_property
    def face_sizes(self) -> np.ndarray:
        return _readonly(np.diff(self.face_offsets))

    @cached_property
    def corner_face(self) -> np.ndarray:
        """Face of each corner."""
        return _readonly(np.repeat(np.arange(self.n_faces, dtype=np.int64), np.diff(self.face_offsets)))

    @cached_property
    def corner_next(self) -> np.ndarray:
        """Next corner (counter-clockwise) in the same face."""
        c = np.arange(len(self.face_indices), dtype=np.int64) + 1
        last = self.face_offsets[1:] - 1
        c[last] = self.face_offsets[:-1]
        return _readonly(c)

    @cached_property
    def corner_prev(self) -> np.ndarray:
        """Previous corner in the same face."""
        c = np.arange(len(self.face_indices), dtype=np.int64) - 1
        c[self.face_offsets[:-1]] = self.face_offsets[1:] - 1
        return _readonly(c)

    @cached_property
    def halfedge_twin(self) -> np.ndarray:
        """Opposite half-edge (corner) across the edge, -1 on the boundary."""
        eh = self.edge_halfedges
        e = self.halfedge_edge
        c = np.arange(len(self.face_indices))
        return _readonly(np.where(eh[e, 0] == c, eh[e, 1], eh[e, 0]))

    # ---- faces ----------------------------------------------------------------------------
    def face(self, f: int) -> np.ndarray:
        return self.face_indices[self.face_offsets[f]:self.face_offsets[f + 1]]

    def faces_list(self) -> list[list[int]]:
        idx = self.face_indices.tolist()
        off = self.face_offsets.tolist()
        return [idx[off[f]:off[f + 1]] for f in range(self.n_faces)]

    @cached_property
    def is_uniform(self) -> bool:
        return self.n_faces > 0 and bool(np.all(self.face_sizes == self.face_sizes[0]))

    @cached_property
    def face_array(self) -> np.ndarray:
        """`(m, k)` array when every face has k vertices (raises otherwise)."""
        if not self.is_uniform:
            raise ValueError("faces have different sizes; use face_indices/face_offsets")
        return _readonly(self.face_indices.reshape(self.n_faces, -1))

    # ---- adjacency ------------------------------------------------------------------------
    @cached_property
    def vertex_faces(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR `(faces, offsets)`: faces around each vertex (in face order, not cyclic)."""
        order = np.argsort(self.face_indices, kind="stable")
        counts = np.bincount(self.face_indices, minlength=self.n_vertices)
        off = np.zeros(self.n_vertices + 1, dtype=np.int64)
        np.cumsum(counts, out=off[1:])
        return _readonly(self.corner_face[order]), _readonly(off)

    @cached_property
    def vertex_corners(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR `(corners, offsets)`: corners at each vertex."""
        order = np.argsort(self.face_indices, kind="stable").astype(np.int64)
        counts = np.bincount(self.face_indices, minlength=self.n_vertices)
        off = np.zeros(self.n_vertices + 1, dtype=np.int64)
        np.cumsum(counts, out=off[1:])
        return _readonly(order), _readonly(off)

    @cached_property
    def vertex_valence(self) -> np.ndarray:
        """Number of edges at each vertex."""
        return _readonly(np.bincount(self.edges.ravel(), minlength=self.n_vertices))

    @cached_property
    def boundary_edge_mask(self) -> np.ndarray:
        return _readonly(np.any(self.edge_faces < 0, axis=1))

    def edge_ids(self, pairs) -> np.ndarray:
        """Edge id (index into `edges`) of each vertex pair (k, 2), in either order; -1 where no edge joins them.

        `edges` is sorted by (lo, hi), so this is one binary search per pair.
        """
        P = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        out = np.full(len(P), -1, dtype=np.int64)
        n = max(self.n_vertices, 1)
        lo, hi = P.min(axis=1), P.max(axis=1)
        valid = (lo >= 0) & (hi < self.n_vertices)
        if not len(self.edges) or not valid.any():
            return out
        keys = self.edges[:, 0] * n + self.edges[:, 1]
        want = lo[valid] * n + hi[valid]
        pos = np.minimum(np.searchsorted(keys, want), len(keys) - 1)
        out[valid] = np.where(keys[pos] == want, pos, -1)
        return out

    @cached_property
    def interior_edges(self) -> np.ndarray:
        return _readonly(np.flatnonzero(~self.boundary_edge_mask))

    @cached_property
    def boundary_vertex_mask(self) -> np.ndarray:
        m = np.zeros(self.n_vertices, dtype=bool)
        m[self.edges[self.boundary_edge_mask].ravel()] = True
        return _readonly(m)

    @cached_property
    def used_vertex_mask(self) -> np.ndarray:
        m = np.zeros(self.n_vertices, dtype=bool)
        m[self.face_indices] = True
        return _readonly(m)

    @cached_property
    def interior_vertex_mask(self) -> np.ndarray:
        """Used vertices not on the boundary: the ones whose angle defect is meaningful."""
        return _readonly(self.used_vertex_mask & ~self.boundary_vertex_mask)

    @cached_property
    def boundary_loops(self) -> tuple[np.ndarray, ...]:
        """Boundary loops as vertex arrays, oriented like the faces (the mesh on the left).

        Loops start at their smallest vertex id, so the result is deterministic.
        """
        bh = np.flatnonzero(self.halfedge_twin < 0)
        if len(bh) == 0:
            return ()
        start = self.face_indices[bh]
        end = self.face_indices[self.corner_next[bh]]
        nxt: dict[int, list[int]] = {}
        for s, e in zip(start.tolist(), end.tolist()):
            nxt.setdefault(s, []).append(e)
        loops = []
        unvisited = set(zip(start.tolist(), end.tolist()))
        for s0 in sorted(nxt):
            while nxt.get(s0):
                loop = [s0]
                cur = s0
                for _ in range(len(bh) + 1):
                    nx = nxt[cur].pop()
                    unvisited.discard((cur, nx))
                    if nx == s0:
                        break
                    loop.append(nx)
                    cur = nx
                    if not nxt.get(cur):
                        break
                k = int(np.argmin(loop))
                loops.append(_readonly(np.array(loop[k:] + loop[:k], dtype=np.int64)))
        return tuple(loops)

    @cached_property
    def face_adjacency(self) -> np.ndarray:
        """`(k, 2)` pairs of faces sharing an interior edge (ordered like `interior_edges`)."""
        return _readonly(self.edge_faces[self.interior_edges])


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
        self.vertices = _readonly(V)
        if topology is None:
            if faces is None:
                raise MeshError("a mesh needs faces")
            idx, off = faces_to_csr(faces)
            topology = MeshTopology(idx, off, len(V))
        elif topology.n_vertices != len(V):
            raise MeshError(f"topology has {topology.n_vertices} vertices, coordinates have {len(V)}")
        self.topology = topology
        self.face_data = {k: _readonly(np.asarray(v)) for k, v in (face_data or {}).items()}
        self.vertex_data = {k: _readonly(np.asarray(v)) for k, v in (vertex_data or {}).items()}
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
        return _readonly(cross3(u, w))

    @cached_property
    def face_normal_sums(self) -> np.ndarray:
        """Sum of corner cross products per face (the paper's best-fit plane normal, unnormalised)."""
        return _readonly(np.add.reduceat(self.corner_cross, self.face_offsets[:-1], axis=0)
                         if self.n_faces else np.zeros((0, 3)))

    @cached_property
    def face_normals(self) -> np.ndarray:
        """Unit face normals (sum of corner cross products, normalised)."""
        n = self.face_normal_sums
        length = np.linalg.norm(n, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            return _readonly(np.where(length > 0, n / length, 0.0))

    @cached_property
    def face_centroids(self) -> np.ndarray:
        """Mean of each face's vertices (the paper's plane origin)."""
        s = np.add.reduceat(self.vertices[self.face_indices], self.face_offsets[:-1], axis=0) \
            if self.n_faces else np.zeros((0, 3))
        return _readonly(s / self.face_sizes[:, None])

    @cached_property
    def face_areas(self) -> np.ndarray:
        """Vector-area magnitude per face (exact for planar polygons)."""
        V = self.vertices
        t = self.topology
        a = cross3(V[t.face_indices], V[t.face_indices[t.corner_next]])
        s = np.add.reduceat(a, self.face_offsets[:-1], axis=0) if self.n_faces else np.zeros((0, 3))
        return _readonly(0.5 * np.linalg.norm(s, axis=1))

    @cached_property
    def edge_lengths(self) -> np.ndarray:
        e = self.edges
        return _readonly(np.linalg.norm(self.vertices[e[:, 1]] - self.vertices[e[:, 0]], axis=1))

    @cached_property
    def bounding_box(self) -> np.ndarray:
        used = self.vertices[self.topology.used_vertex_mask]
        return _readonly(np.array([used.min(axis=0), used.max(axis=0)]))

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
