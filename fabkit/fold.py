"""FOLD model in memory: a crease pattern (key frame) plus fold states (child frames).

The arrays follow the FOLD names (`vertices_coords`, `edges_vertices`, `edges_assignment`,
`faces_vertices`) with two conventions that differ from the file and are converted at exactly one
boundary (`fabkit.io.fold`): coordinates are in **metres** and fold angles in **radians** (valley
positive, mountain negative, NaN where the file has `null`).

`FoldModel.from_mesh` builds a model from a `PolyMesh` using the mesh's own edge order (sorted
lo < hi, so `edges_vertices[e] == mesh.edges[e]`); `model.mesh()` and `model.frame_mesh(i)` go back.
`validate_fold_model` checks a model once at the boundary and raises `InputError` naming the element.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from typing import Mapping, Sequence

import numpy as np

from fabkit.errors import InputError
from fabkit.mesh import MeshTopology, PolyMesh, faces_to_csr

__all__ = ["FoldModel", "FoldFrame", "ASSIGNMENTS", "validate_fold_model", "default_assignment"]

#: FOLD 1.2 edge assignments: Border, Mountain, Valley, Flat, Join, Unassigned, Cut.
ASSIGNMENTS = "BMVFJUC"

#: Slack allowed on the M/V sign of a fold angle (radians): -1e-12 on a valley is numerical noise.
ANGLE_SLACK = 1e-9


def _readonly(a, dtype=None) -> np.ndarray:
    a = np.array(a, dtype=dtype, copy=True)
    a.setflags(write=False)
    return a


def _coords(V) -> np.ndarray:
    """Coordinates as a read-only float64 `(n, 3)` array (2D coordinates get z = 0)."""
    V = np.array(V, dtype=np.float64, copy=True)
    if V.size == 0:
        V = V.reshape(0, 3)
    if V.ndim == 2 and V.shape[1] == 2:
        V = np.column_stack([V, np.zeros(len(V))])
    V.setflags(write=False)
    return V


def _data(d: Mapping | None) -> dict[str, np.ndarray]:
    return {str(k): _readonly(v) for k, v in (d or {}).items()}


@dataclass(frozen=True, eq=False)
class FoldFrame:
    """One fold state (a FOLD child frame with `frame_inherit: true`, `frame_parent: 0`).

    `vertices_coords` (n, 3) metres; `edges_fold_angle` (E,) radians (valley +) or None when the
    frame inherits the key frame's angles; `classes` its `frame_classes`; `data` extra namespaced
    keys of the frame (e.g. `frame_fabkit:state`), kept as read.
    """

    vertices_coords: np.ndarray
    edges_fold_angle: np.ndarray | None = None
    classes: tuple[str, ...] = ("foldedForm",)
    data: dict = field(default_factory=dict)
    attributes: tuple[str, ...] = ("3D",)

    def __post_init__(self) -> None:
        object.__setattr__(self, "vertices_coords", _coords(self.vertices_coords))
        if self.edges_fold_angle is not None:
            object.__setattr__(self, "edges_fold_angle", _readonly(self.edges_fold_angle, np.float64))
        object.__setattr__(self, "classes", tuple(self.classes))
        object.__setattr__(self, "attributes", tuple(self.attributes))
        object.__setattr__(self, "data", dict(self.data))


@dataclass(frozen=True, eq=False)
class FoldModel:
    """A crease pattern with its fold states (see module docstring for units and conventions).

    `faces_vertices` is a tuple of polygons exactly as written (quads stay quads; triangles when `J`
    diagonals are present); `face_indices`/`face_offsets` give the same faces as CSR arrays.
    `faces_data` / `vertices_data` / `edges_data` map a name to a per-element array (the file keys
    `faces_fabkit:<name>` etc. without the prefix). `unit` is the unit of the file it came from
    (or will be written in); `classes` the key frame's `frame_classes`. `notes` are remarks a reader
    made while importing (e.g. a pattern rotated into z = 0).
    """

    vertices_coords: np.ndarray
    faces_vertices: tuple
    edges_vertices: np.ndarray
    edges_assignment: np.ndarray
    edges_fold_angle: np.ndarray
    faces_data: dict = field(default_factory=dict)
    vertices_data: dict = field(default_factory=dict)
    edges_data: dict = field(default_factory=dict)
    file_data: dict = field(default_factory=dict)
    frames: tuple = ()
    unit: str = "mm"
    classes: tuple[str, ...] = ("creasePattern",)
    creator: str = "fabkit"
    title: str = ""
    attributes: tuple[str, ...] = ("2D",)
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "vertices_coords", _coords(self.vertices_coords))
        set_(self, "faces_vertices", tuple(tuple(int(i) for i in f) for f in self.faces_vertices))
        ev = np.array(self.edges_vertices, dtype=np.int64, copy=True)
        set_(self, "edges_vertices", _readonly(ev.reshape(0, 2) if ev.size == 0 else ev))
        set_(self, "edges_assignment", _readonly(np.asarray(self.edges_assignment, dtype="<U1")))
        set_(self, "edges_fold_angle", _readonly(self.edges_fold_angle, np.float64))
        for name in ("faces_data", "vertices_data", "edges_data"):
            set_(self, name, _data(getattr(self, name)))
        set_(self, "file_data", dict(self.file_data))
        set_(self, "frames", tuple(self.frames))
        set_(self, "classes", tuple(self.classes))
        set_(self, "attributes", tuple(self.attributes))
        set_(self, "notes", tuple(self.notes))

    # ---- sizes and CSR views ----------------------------------------------------------------
    @property
    def n_vertices(self) -> int:
        return len(self.vertices_coords)

    @property
    def n_edges(self) -> int:
        return len(self.edges_vertices)

    @property
    def n_faces(self) -> int:
        return len(self.faces_vertices)

    @property
    def n_frames(self) -> int:
        """Number of fold states (child frames), not counting the key frame."""
        return len(self.frames)

    @cached_property
    def _csr(self) -> tuple[np.ndarray, np.ndarray]:
        idx, off = faces_to_csr(self.faces_vertices)
        return _readonly(idx), _readonly(off)

    @property
    def face_indices(self) -> np.ndarray:
        return self._csr[0]

    @property
    def face_offsets(self) -> np.ndarray:
        return self._csr[1]

    # ---- construction -------------------------------------------------------------------------
    @classmethod
    def from_mesh(cls, mesh: PolyMesh, edges_assignment: Sequence[str] | np.ndarray | None = None,
                  edges_fold_angle: np.ndarray | None = None, *, frames: Sequence[FoldFrame] = (),
                  edges_data: Mapping | None = None, file_data: Mapping | None = None,
                  unit: str = "mm", classes: Sequence[str] = ("creasePattern",), title: str = "",
                  creator: str = "fabkit", attributes: Sequence[str] | None = None) -> "FoldModel":
        """A model whose edges are `mesh.edges` (same order), faces the mesh's polygons.

        `edges_assignment` defaults to `default_assignment(mesh, edges_fold_angle)`; `edges_fold_angle`
        (radians, valley +) defaults to 0 on every edge. `mesh.face_data` / `mesh.vertex_data` become
        `faces_data` / `vertices_data`. The model is validated before it is returned.
        """
        E = mesh.n_edges
        angle = np.zeros(E) if edges_fold_angle is None else np.asarray(edges_fold_angle, dtype=np.float64)
        if edges_assignment is None:
            assignment = default_assignment(mesh, angle)
        else:
            assignment = np.asarray(list(edges_assignment) if isinstance(edges_assignment, str)
                                    else edges_assignment, dtype="<U1")
        if attributes is None:
            flat = mesh.n_vertices == 0 or bool(np.all(mesh.vertices[:, 2] == 0.0))
            attributes = ("2D",) if flat else ("3D",)
        model = cls(
            vertices_coords=mesh.vertices, faces_vertices=mesh.faces_list(), edges_vertices=mesh.edges,
            edges_assignment=assignment, edges_fold_angle=angle, faces_data=mesh.face_data,
            vertices_data=mesh.vertex_data, edges_data=edges_data or {}, file_data=file_data or {},
            frames=tuple(frames), unit=unit, classes=tuple(classes), creator=creator, title=title,
            attributes=tuple(attributes),
        )
        model.__dict__["topology"] = mesh.topology  # same faces, same vertex count: share, don't rebuild
        validate_fold_model(model)
        return model

    def with_frames(self, frames: Sequence[FoldFrame]) -> "FoldModel":
        """The same crease pattern with these fold states (validated)."""
        model = dataclasses.replace(self, frames=tuple(frames))
        validate_fold_model(model)
        return model

    # ---- back to meshes ---------------------------------------------------------------------
    @cached_property
    def topology(self) -> MeshTopology:
        """Mesh connectivity of the faces (raises `MeshError` if they are not a manifold mesh)."""
        return MeshTopology(self.face_indices, self.face_offsets, self.n_vertices)

    def mesh(self, validate: bool = True) -> PolyMesh:
        """The key frame (crease pattern) as a `PolyMesh` with `faces_data` / `vertices_data`."""
        return PolyMesh(self.vertices_coords, topology=self.topology, face_data=self.faces_data,
                        vertex_data=self.vertices_data, validate=validate)

    def frame_mesh(self, i: int) -> PolyMesh:
        """The mesh at fold state `frames[i]` (0-based into `frames`, i.e. FOLD frame i+1; -1 = last).

        Shares the key frame's topology and data; coordinates must be finite.
        """
        if not -self.n_frames <= i < self.n_frames:
            raise IndexError(f"frame {i} out of range: the model has {self.n_frames} fold states")
        return self.mesh(validate=False).with_vertices(self.frames[i].vertices_coords)

    def frame_fold_angle(self, i: int) -> np.ndarray:
        """Fold angles of `frames[i]` in radians (the key frame's when the frame does not override them)."""
        a = self.frames[i].edges_fold_angle
        return self.edges_fold_angle if a is None else a

    @cached_property
    def mesh_edge_index(self) -> np.ndarray:
        """For each model edge, the index of the same edge in `self.mesh().edges` (sorted order).

        Identity when the model was built with `from_mesh`; a permutation for files that order
        their edges differently.
        """
        return _readonly(self.topology.edge_ids(self.edges_vertices))


def default_assignment(mesh: PolyMesh, edges_fold_angle: np.ndarray | None = None) -> np.ndarray:
    """Assignments for `mesh.edges`: boundary `B`; interior `V`/`M` by the sign of the fold angle;
    interior edges with zero angle are `U` on the panel's creases (`fabkit.structure.crease_mask`:
    strip tags, or inferred from a folded mesh; a crease not folded yet) and `F` otherwise.
    """
    from fabkit.structure import crease_mask  # here, so that reading a FOLD file does not import scipy

    E = mesh.n_edges
    angle = np.zeros(E) if edges_fold_angle is None else np.asarray(edges_fold_angle, dtype=np.float64)
    out = np.full(E, "F", dtype="<U1")
    ef = mesh.edge_faces
    boundary = np.any(ef < 0, axis=1)
    out[crease_mask(mesh)] = "U"
    out[~boundary & (angle > 0)] = "V"
    out[~boundary & (angle < 0)] = "M"
    out[boundary] = "B"
    return out


def _check_angles(angle: np.ndarray, assignment: np.ndarray, where: str, source: str | None) -> None:
    """|angle| <= pi; valley edges >= 0, mountain edges <= 0 (NaN = unknown is allowed)."""
    finite = np.isfinite(angle)
    big = finite & (np.abs(angle) > np.pi)  # exactly: pi is 180.0 in the file, and the reader allows 180
    if np.any(big):
        e = int(np.flatnonzero(big)[0])
        raise InputError(f"{where}edge {e} has fold angle {np.degrees(angle[e]):.6g} deg, outside [-180, 180]",
                         source=source)
    if np.any(np.isinf(angle)):
        e = int(np.flatnonzero(np.isinf(angle))[0])
        raise InputError(f"{where}edge {e} has an infinite fold angle", source=source)
    wrong = finite & (((assignment == "V") & (angle < -ANGLE_SLACK)) | ((assignment == "M") & (angle > ANGLE_SLACK)))
    if np.any(wrong):
        e = int(np.flatnonzero(wrong)[0])
        kind = "valley" if assignment[e] == "V" else "mountain"
        raise InputError(f"{where}edge {e} is a {kind} ({assignment[e]}) but its fold angle is "
                         f"{np.degrees(angle[e]):.6g} deg (valley must be >= 0, mountain <= 0)", source=source)


def _check_coords(V: np.ndarray, n: int, where: str, source: str | None) -> None:
    if V.shape != (n, 3):
        raise InputError(f"{where}vertices_coords has shape {V.shape}, expected ({n}, 3)", source=source)
    bad = ~np.all(np.isfinite(V), axis=1)
    if np.any(bad):
        v = int(np.flatnonzero(bad)[0])
        raise InputError(f"{where}vertex {v} has a non-finite coordinate {V[v].tolist()}", source=source)


def validate_fold_model(model: FoldModel, *, source: str | None = None) -> list[str]:
    """Check a model once at the boundary; raise `InputError` naming the element, return warnings.

    Checks (FOLD reference §1.3 self-validation, plus what a mesh needs): parallel array lengths,
    finite coordinates, indices in range, no repeated edges, assignment letters, fold angles within
    [-180, 180] deg with the sign matching M/V, faces of >= 3 distinct vertices whose sides are edges,
    non-B/C edges on at most 2 faces, data arrays matching their element counts, and every frame
    matching the key frame's sizes. A crease pattern (`creasePattern`, flat in z = 0) must have
    counter-clockwise faces.
    """
    warn: list[str] = []
    n, E, F = model.n_vertices, model.n_edges, model.n_faces
    _check_coords(model.vertices_coords, n, "", source)
    ev = model.edges_vertices
    if ev.ndim != 2 or ev.shape[1] != 2:
        raise InputError(f"edges_vertices has shape {ev.shape}, expected (E, 2)", source=source)
    for name, arr in (("edges_assignment", model.edges_assignment), ("edges_foldAngle", model.edges_fold_angle)):
        if arr.shape != (E,):
            raise InputError(f"{name} has {len(arr)} entries for {E} edges", source=source)
    bad = np.flatnonzero((ev < 0).any(axis=1) | (ev >= n).any(axis=1))
    if len(bad):
        e = int(bad[0])
        raise InputError(f"edge {e} refers to vertex {ev[e].tolist()}, but vertices are numbered 0..{n - 1}",
                         source=source)
    loop = np.flatnonzero(ev[:, 0] == ev[:, 1])
    if len(loop):
        raise InputError(f"edge {int(loop[0])} joins vertex {int(ev[loop[0], 0])} to itself", source=source)
    keys = np.minimum(ev[:, 0], ev[:, 1]) * max(n, 1) + np.maximum(ev[:, 0], ev[:, 1])
    uniq, first, counts = np.unique(keys, return_index=True, return_counts=True)
    if np.any(counts > 1):
        k = int(np.flatnonzero(counts > 1)[0])
        dup = np.flatnonzero(keys == uniq[k])
        raise InputError(f"edges {int(dup[0])} and {int(dup[1])} both join vertices {ev[dup[0]].tolist()}",
                         source=source)
    letters = set(ASSIGNMENTS)
    for e, a in enumerate(model.edges_assignment.tolist()):
        if a not in letters:
            raise InputError(f"edge {e} has assignment {a!r}; FOLD allows B, M, V, F, J, U, C", source=source)
    _check_angles(model.edges_fold_angle, model.edges_assignment, "", source)
    _check_faces(model, keys, uniq, first, source, warn)
    for kind, data, count in (("faces", model.faces_data, F), ("vertices", model.vertices_data, n),
                              ("edges", model.edges_data, E)):
        for name, arr in data.items():
            if arr.ndim == 0 or len(arr) != count:
                size = "a scalar" if arr.ndim == 0 else f"{len(arr)} entries"
                raise InputError(f"{kind}_fabkit:{name} has {size} for {count} {kind}", source=source)
    for i, frame in enumerate(model.frames):
        where = f"frame {i + 1}: "
        _check_coords(frame.vertices_coords, n, where, source)
        if frame.edges_fold_angle is not None:
            if frame.edges_fold_angle.shape != (E,):
                raise InputError(f"{where}edges_foldAngle has {len(frame.edges_fold_angle)} entries for {E} edges",
                                 source=source)
            _check_angles(frame.edges_fold_angle, model.edges_assignment, where, source)
    return warn


def _check_faces(model: FoldModel, keys: np.ndarray, uniq: np.ndarray, first: np.ndarray,
                 source: str | None, warn: list[str]) -> None:
    """Face sizes, indices, sides present as edges, at most 2 faces on a non-B/C edge, CCW crease patterns."""
    n = model.n_vertices
    idx, off = model.face_indices, model.face_offsets
    sizes = np.diff(off)
    if np.any(sizes < 3):
        f = int(np.flatnonzero(sizes < 3)[0])
        raise InputError(f"face {f} has {int(sizes[f])} vertices (a face needs at least 3)", source=source)
    out = np.flatnonzero((idx < 0) | (idx >= n))
    if len(out):
        c = int(out[0])
        f = int(np.searchsorted(off, c, side="right") - 1)
        raise InputError(f"face {f} refers to vertex {int(idx[c])}, but vertices are numbered 0..{n - 1}",
                         source=source)
    for f, poly in enumerate(model.faces_vertices):
        if len(set(poly)) != len(poly):
            rep = next(v for v in poly if poly.count(v) > 1)
            raise InputError(f"face {f} repeats vertex {rep}", source=source)
    if len(idx) == 0:
        return
    corner_face = np.repeat(np.arange(len(sizes)), sizes)
    nxt = np.arange(len(idx)) + 1
    nxt[off[1:] - 1] = off[:-1]
    u, v = idx, idx[nxt]
    side = np.minimum(u, v) * max(n, 1) + np.maximum(u, v)
    pos = np.clip(np.searchsorted(uniq, side), 0, max(len(uniq) - 1, 0))
    present = (uniq[pos] == side) if len(uniq) else np.zeros(len(side), bool)
    if not np.all(present):
        c = int(np.flatnonzero(~present)[0])
        raise InputError(f"face {int(corner_face[c])} has side ({int(u[c])}, {int(v[c])}) that is not in "
                         "edges_vertices", source=source)
    edge_of_side = first[pos]  # model edge index of each face side
    counts = np.bincount(edge_of_side, minlength=model.n_edges)
    assignment = model.edges_assignment
    over = np.flatnonzero((counts > 2) & (assignment != "B") & (assignment != "C"))
    if len(over):
        e = int(over[0])
        fs = sorted(set(corner_face[edge_of_side == e].tolist()))
        raise InputError(f"edge {e} ({assignment[e]}) borders {int(counts[e])} faces {fs} "
                         "(a non-border edge may border at most 2 faces)", source=source)
    lonely = np.flatnonzero(counts == 0)
    if len(lonely):
        warn.append(f"{len(lonely)} edges border no face (first: edge {int(lonely[0])})")
    b_inside = np.flatnonzero((counts == 2) & (assignment == "B"))
    if len(b_inside):
        warn.append(f"{len(b_inside)} border (B) edges have two faces (first: edge {int(b_inside[0])})")
    open_crease = np.flatnonzero((counts == 1) & np.isin(assignment, ["M", "V", "F", "J"]))
    if len(open_crease):
        e = int(open_crease[0])
        warn.append(f"{len(open_crease)} {assignment[e]}-type edges border only one face (first: edge {e})")
    V = model.vertices_coords
    if "creasePattern" in model.classes and n and np.all(V[:, 2] == 0.0):
        x, y = V[idx, 0], V[idx, 1]
        twice = np.add.reduceat(x * y[nxt] - x[nxt] * y, off[:-1])
        cw = np.flatnonzero(twice <= 0)
        if len(cw):
            f = int(cw[0])
            what = "has zero area" if twice[f] == 0 else "is clockwise"
            raise InputError(f"face {f} {what} in the crease pattern (faces must be counter-clockwise "
                             "seen from +z)", source=source)
