"""Mesh connectivity: faces as CSR arrays and the edges, half-edges, boundary loops and adjacency
derived from them once (`MeshTopology`), shared by every `fabkit.mesh.PolyMesh` with the same faces.

Dtype policy as in `fabkit.mesh`: every index array is int64; derived arrays are read-only.
"""
from __future__ import annotations

from functools import cached_property

import numpy as np

from fabkit.errors import MeshError

__all__ = ["MeshTopology", "faces_to_csr", "read_only"]


def read_only(a: np.ndarray) -> np.ndarray:
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
        self.face_indices = read_only(np.ascontiguousarray(face_indices, dtype=np.int64))
        self.face_offsets = read_only(np.ascontiguousarray(face_offsets, dtype=np.int64))
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
            self.edges = read_only(np.stack([q, r], axis=1).astype(np.int64, copy=False))
        else:
            self.edges = read_only(np.zeros((0, 2), np.int64))
        self.halfedge_edge = read_only(inverse.astype(np.int64, copy=False))
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
        self.edge_faces = read_only(ef)
        eh = np.full((E, 2), -1, dtype=np.int64)
        eh[inverse, slot] = np.arange(len(u))
        self.edge_halfedges = read_only(eh)

    # ---- corners / half-edges -----------------------------------------------------------
    @property
    def n_faces(self) -> int:
        return len(self.face_offsets) - 1

    @property
    def n_edges(self) -> int:
        return len(self.edges)

    @cached_property
    def face_sizes(self) -> np.ndarray:
        return read_only(np.diff(self.face_offsets))

    @cached_property
    def corner_face(self) -> np.ndarray:
        """Face of each corner."""
        return read_only(np.repeat(np.arange(self.n_faces, dtype=np.int64), np.diff(self.face_offsets)))

    @cached_property
    def corner_next(self) -> np.ndarray:
        """Next corner (counter-clockwise) in the same face."""
        c = np.arange(len(self.face_indices), dtype=np.int64) + 1
        last = self.face_offsets[1:] - 1
        c[last] = self.face_offsets[:-1]
        return read_only(c)

    @cached_property
    def corner_prev(self) -> np.ndarray:
        """Previous corner in the same face."""
        c = np.arange(len(self.face_indices), dtype=np.int64) - 1
        c[self.face_offsets[:-1]] = self.face_offsets[1:] - 1
        return read_only(c)

    @cached_property
    def halfedge_twin(self) -> np.ndarray:
        """Opposite half-edge (corner) across the edge, -1 on the boundary."""
        eh = self.edge_halfedges
        e = self.halfedge_edge
        c = np.arange(len(self.face_indices))
        return read_only(np.where(eh[e, 0] == c, eh[e, 1], eh[e, 0]))

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
        return read_only(self.face_indices.reshape(self.n_faces, -1))

    # ---- adjacency ------------------------------------------------------------------------
    @cached_property
    def vertex_faces(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR `(faces, offsets)`: faces around each vertex (in face order, not cyclic)."""
        order = np.argsort(self.face_indices, kind="stable")
        counts = np.bincount(self.face_indices, minlength=self.n_vertices)
        off = np.zeros(self.n_vertices + 1, dtype=np.int64)
        np.cumsum(counts, out=off[1:])
        return read_only(self.corner_face[order]), read_only(off)

    @cached_property
    def vertex_corners(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR `(corners, offsets)`: corners at each vertex."""
        order = np.argsort(self.face_indices, kind="stable").astype(np.int64)
        counts = np.bincount(self.face_indices, minlength=self.n_vertices)
        off = np.zeros(self.n_vertices + 1, dtype=np.int64)
        np.cumsum(counts, out=off[1:])
        return read_only(order), read_only(off)

    @cached_property
    def vertex_valence(self) -> np.ndarray:
        """Number of edges at each vertex."""
        return read_only(np.bincount(self.edges.ravel(), minlength=self.n_vertices))

    @cached_property
    def boundary_edge_mask(self) -> np.ndarray:
        return read_only(np.any(self.edge_faces < 0, axis=1))

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
        return read_only(np.flatnonzero(~self.boundary_edge_mask))

    @cached_property
    def boundary_vertex_mask(self) -> np.ndarray:
        m = np.zeros(self.n_vertices, dtype=bool)
        m[self.edges[self.boundary_edge_mask].ravel()] = True
        return read_only(m)

    @cached_property
    def used_vertex_mask(self) -> np.ndarray:
        m = np.zeros(self.n_vertices, dtype=bool)
        m[self.face_indices] = True
        return read_only(m)

    @cached_property
    def interior_vertex_mask(self) -> np.ndarray:
        """Used vertices not on the boundary: the ones whose angle defect is meaningful."""
        return read_only(self.used_vertex_mask & ~self.boundary_vertex_mask)

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
                loops.append(read_only(np.array(loop[k:] + loop[:k], dtype=np.int64)))
        return tuple(loops)

    @cached_property
    def face_adjacency(self) -> np.ndarray:
        """`(k, 2)` pairs of faces sharing an interior edge (ordered like `interior_edges`)."""
        return read_only(self.edge_faces[self.interior_edges])
