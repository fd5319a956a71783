"""Checks on a FLAT / TARGET pair before refolding: same panel, a flat pattern, and a real fold of it."""
from __future__ import annotations

import numpy as np

from fabkit.errors import InputError, ToleranceError
from fabkit.mesh import MeshTopology, PolyMesh

__all__ = ["NotAFoldError", "check_pair", "check_flat", "edge_length_mismatch"]


class NotAFoldError(ToleranceError):
    """TARGET's edge lengths differ from FLAT's: it is not a rigid fold of the pattern (CLI exit 1)."""

    def __init__(self, message: str, edge: tuple[int, int], relative: float):
        super().__init__(message)
        self.edge = edge
        self.relative = relative


def check_pair(flat: PolyMesh, target: PolyMesh, flat_name: str = "FLAT", target_name: str = "TARGET") -> None:
    """Same vertex count and the same faces in the same order (InputError otherwise)."""
    if flat.n_vertices != target.n_vertices:
        raise InputError(f"has {target.n_vertices} vertices but {flat_name} has {flat.n_vertices}; "
                         "FLAT and TARGET must be the same panel", source=target_name)
    if flat.n_faces != target.n_faces:
        raise InputError(f"has {target.n_faces} faces but {flat_name} has {flat.n_faces}; "
                         "FLAT and TARGET must be the same panel", source=target_name)
    if not (np.array_equal(flat.face_offsets, target.face_offsets)
            and np.array_equal(flat.face_indices, target.face_indices)):
        sizes_differ = np.diff(flat.face_offsets) != np.diff(target.face_offsets)
        if np.any(sizes_differ):
            f = int(np.flatnonzero(sizes_differ)[0])
        else:
            c = int(np.flatnonzero(flat.face_indices != target.face_indices)[0])
            f = int(flat.topology.corner_face[c])
        raise InputError(f"face {f} is {target.face(f).tolist()} but in {flat_name} it is {flat.face(f).tolist()}; "
                         "FLAT and TARGET must have the same faces", source=target_name)


def check_flat(flat: PolyMesh, tris: np.ndarray, name: str = "FLAT", rtol: float = 1e-9) -> None:
    """A crease pattern lies in z = 0 with every triangle counter-clockwise seen from +z."""
    V = flat.vertices
    used = flat.topology.used_vertex_mask
    size = max(flat.size, 1e-300)
    z = np.abs(V[used, 2])
    if z.size and z.max() > rtol * size:
        v = int(np.flatnonzero(used)[np.argmax(z)])
        raise InputError(f"is not a flat pattern: vertex {v} has z = {V[v, 2]:.6g} m (a crease pattern lies in "
                         "z = 0; use the output of 'fabkit unfold')", source=name)
    a, b, c = V[tris[:, 0]], V[tris[:, 1]], V[tris[:, 2]]
    twice = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    bad = twice <= 0
    if np.all(bad):
        raise InputError("faces are clockwise seen from +z (the pattern is mirrored; faces must be "
                         "counter-clockwise seen from the front)", source=name)
    if np.any(bad):
        t = int(np.flatnonzero(bad)[0])
        raise InputError(f"the pattern overlaps itself: triangle {tris[t].tolist()} is clockwise or degenerate "
                         "seen from +z", source=name)


def edge_length_mismatch(topology: MeshTopology, flat_vertices: np.ndarray, target_vertices: np.ndarray):
    """Relative edge-length differences of every triangle edge: (rel (E,), L_flat, L_target)."""
    E = topology.edges
    Lf = np.linalg.norm(flat_vertices[E[:, 1]] - flat_vertices[E[:, 0]], axis=1)
    Lt = np.linalg.norm(target_vertices[E[:, 1]] - target_vertices[E[:, 0]], axis=1)
    return np.abs(Lt - Lf) / Lf, Lf, Lt


def check_is_fold(topology: MeshTopology, flat_vertices: np.ndarray, target_vertices: np.ndarray,
                  rtol: float, target_name: str = "TARGET") -> float:
    """Raise NotAFoldError when some triangle edge's length differs by more than `rtol` (relative)."""
    rel, Lf, Lt = edge_length_mismatch(topology, flat_vertices, target_vertices)
    e = int(np.argmax(rel))
    if rel[e] > rtol:
        u, v = (int(x) for x in topology.edges[e])
        raise NotAFoldError(f"{target_name}: not a fold of the flat pattern: edge ({u}, {v}) is {Lt[e]:.9g} m long "
                            f"but {Lf[e]:.9g} m in FLAT (relative difference {rel[e]:.3g} > tolerance {rtol:g}; "
                            f"{int(np.sum(rel > rtol))} edges exceed it)", (u, v), float(rel[e]))
    return float(rel[e])
