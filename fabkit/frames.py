"""Face frames of a folding panel: where a gripper holds each middle-row face in every fold state.

A face frame is a 4x4 pose in the panel frame (the frame the fold states are expressed in):

- origin: the face centroid (mean of its distinct vertices, as `PolyMesh.face_centroids`);
- z: the unit face normal on the front side (faces are counter-clockwise seen from the front, so
  this is the normalised sum of corner cross products, the Newell normal);
- x: along the middle row, i.e. toward the centroid of the next strip's middle-row face (across the
  creases), projected into the face plane; the last face of the row uses the direction from the
  previous face to itself; a row of one face uses its first edge;
- y = z cross x (right-handed).

Faces may be polygons or triangles of a triangulated FOLD file: when `faces_data["polygon"]` maps
each FOLD face to its polygon (as `fabkit refold` writes it), the triangles of one polygon form one
face here and the polygon id is the face id. Files without middle-row tags get the middle row of
the panel structure inferred from their last fold state (`structure_tags`). No robot knowledge lives here (layering: fabkit never
imports robot/).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabkit.errors import InputError
from fabkit.mesh import faces_to_csr

__all__ = ["FaceGroups", "FaceFrames", "face_groups", "group_centroids_normals", "row_frames", "middle_row",
           "middle_row_frames", "face_frames_of", "frames_from_axes", "fold_positions", "structure_tags",
           "face_motion", "check_grip_face_moves"]

#: Directions shorter than this (m) are treated as undefined.
_TINY = 1e-12


@dataclass(frozen=True, eq=False)
class FaceGroups:
    """Faces as groups of FOLD faces: group g is made of FOLD faces `members[g]` and has the distinct
    vertices `vertices[g]`; `ids` the face id of each group (polygon id, or FOLD face id when the file
    has no polygon map); `strip`/`column`/`middle` per group (-1 / 0 where the file has no tags)."""

    ids: np.ndarray
    members: tuple[np.ndarray, ...]
    vertices: tuple[np.ndarray, ...]
    strip: np.ndarray
    column: np.ndarray
    middle: np.ndarray
    face_indices: np.ndarray
    face_offsets: np.ndarray

    def index_of(self, face_id: int) -> int:
        hits = np.flatnonzero(self.ids == int(face_id))
        if len(hits) == 0:
            raise KeyError(face_id)
        return int(hits[0])


def _tag(faces_data: dict, name: str, n: int, default: int) -> np.ndarray:
    if name not in faces_data:
        return np.full(n, default, dtype=np.int64)
    return np.asarray(faces_data[name]).astype(np.int64)


def face_groups(faces_vertices, faces_data: dict | None = None, source: str | None = None) -> FaceGroups:
    """Group FOLD faces into panel faces (by `faces_data["polygon"]` if present) with their tags.

    Raises `InputError` if the faces of one polygon disagree on strip/column/middle.
    """
    faces_data = dict(faces_data or {})
    idx, off = faces_to_csr(faces_vertices)
    n = len(off) - 1
    poly = _tag(faces_data, "polygon", n, -1)
    if "polygon" not in faces_data:
        poly = np.arange(n, dtype=np.int64)
    tags = {name: _tag(faces_data, name, n, default) for name, default in
            (("strip", -1), ("column", 0), ("middle", 0))}
    ids, inverse = np.unique(poly, return_inverse=True)
    members, verts = [], []
    out = {name: np.empty(len(ids), dtype=np.int64) for name in tags}
    order = np.argsort(inverse, kind="stable")
    starts = np.searchsorted(inverse[order], np.arange(len(ids) + 1))
    for g in range(len(ids)):
        m = order[starts[g]:starts[g + 1]]
        members.append(m)
        verts.append(np.unique(np.concatenate([idx[off[f]:off[f + 1]] for f in m])))
        for name, arr in tags.items():
            vals = np.unique(arr[m])
            if len(vals) != 1:
                raise InputError(f"faces of polygon {int(ids[g])} disagree on faces_fabkit:{name} "
                                 f"({vals.tolist()})", source=source)
            out[name][g] = vals[0]
    return FaceGroups(ids=ids.astype(np.int64), members=tuple(members), vertices=tuple(verts),
                      strip=out["strip"], column=out["column"], middle=out["middle"],
                      face_indices=idx, face_offsets=off)


def group_centroids_normals(groups: FaceGroups, positions: np.ndarray, which=None) -> tuple[np.ndarray, np.ndarray]:
    """Centroids `(S, k, 3)` and unit front normals `(S, k, 3)` of groups `which` (default all) for
    vertex positions `(S, n, 3)` (or `(n, 3)`, giving `(k, 3)`)."""
    P = np.asarray(positions, dtype=np.float64)
    single = P.ndim == 2
    P = P[None] if single else P
    which = range(len(groups.ids)) if which is None else which
    idx, off = groups.face_indices, groups.face_offsets
    C, N = [], []
    for g in which:
        C.append(P[:, groups.vertices[g]].mean(axis=1))
        nsum = np.zeros((P.shape[0], 3))
        for f in groups.members[g]:
            ring = idx[off[f]:off[f + 1]]
            a, b = P[:, ring], P[:, np.roll(ring, -1)]
            nsum += np.cross(a, b).sum(axis=1)
        N.append(nsum)
    C = np.stack(C, axis=1) if C else np.zeros((P.shape[0], 0, 3))
    N = np.stack(N, axis=1) if N else np.zeros((P.shape[0], 0, 3))
    length = np.linalg.norm(N, axis=-1, keepdims=True)
    if np.any(length < _TINY):
        s, k = np.argwhere(length[..., 0] < _TINY)[0]
        raise InputError(f"face {int(groups.ids[list(which)[k]])} has zero area in fold state {int(s)}")
    N = N / length
    return (C[0], N[0]) if single else (C, N)


def frames_from_axes(origin: np.ndarray, z: np.ndarray, x_hint: np.ndarray) -> np.ndarray:
    """Right-handed frames `(..., 4, 4)` with origin, unit z, and x = x_hint projected off z."""
    z = z / np.linalg.norm(z, axis=-1, keepdims=True)
    x = x_hint - np.sum(x_hint * z, axis=-1, keepdims=True) * z
    xn = np.linalg.norm(x, axis=-1, keepdims=True)
    if np.any(xn < _TINY):
        raise ValueError("x direction is parallel to the face normal")
    x = x / xn
    y = np.cross(z, x)
    T = np.zeros(origin.shape[:-1] + (4, 4))
    T[..., :3, 0], T[..., :3, 1], T[..., :3, 2], T[..., :3, 3] = x, y, z, origin
    T[..., 3, 3] = 1.0
    return T


def row_frames(groups: FaceGroups, positions: np.ndarray, row) -> np.ndarray:
    """Frames `(S, k, 4, 4)` of the faces `row` (group indices ordered along the row, e.g. by strip)
    for vertex positions `(S, n, 3)`; x runs toward the next face of the row (module docstring)."""
    P = np.asarray(positions, dtype=np.float64)
    P = P[None] if P.ndim == 2 else P
    row = list(row)
    C, N = group_centroids_normals(groups, P, row)
    if len(row) >= 2:
        D = np.empty_like(C)
        D[:, :-1] = C[:, 1:] - C[:, :-1]
        D[:, -1] = C[:, -1] - C[:, -2]
    else:  # a row of one face: its first edge
        g = row[0]
        f = groups.members[g][0]
        ring = groups.face_indices[groups.face_offsets[f]:groups.face_offsets[f + 1]]
        D = (P[:, ring[1]] - P[:, ring[0]])[:, None]
    try:
        return frames_from_axes(C, N, D)
    except ValueError:
        raise InputError("a middle-row face points straight at its neighbour (the row direction is along "
                         "the face normal); face frames are undefined") from None


def middle_row(groups: FaceGroups, source: str | None = None) -> np.ndarray:
    """Group indices of the middle row ordered by strip (one face per strip), from the `middle` tags."""
    mid = np.flatnonzero(groups.middle == 1)
    if len(mid) == 0:
        raise InputError("no middle-row faces: the file has no faces_fabkit:middle tags (pass a grip face)",
                         source=source)
    strips = groups.strip[mid]
    values, counts = np.unique(strips, return_counts=True)
    if np.any(counts > 1):
        s = int(values[np.flatnonzero(counts > 1)[0]])
        raise InputError(f"more than one middle-row face in strip {s}", source=source)
    return mid[np.argsort(strips, kind="stable")]


@dataclass(frozen=True, eq=False)
class FaceFrames:
    """Frames of the middle-row faces in every fold state.

    `faces` (k,) face ids (polygon ids) ordered along the row, `strips` (k,), `frames` (S, k, 4, 4)
    in the panel frame (metres), one per fold state (`model.frames`; the key frame when the model
    has none).
    """

    faces: np.ndarray
    strips: np.ndarray
    frames: np.ndarray

    @property
    def n_states(self) -> int:
        return self.frames.shape[0]

    def of_face(self, face_id: int) -> np.ndarray:
        """Frames `(S, 4, 4)` of one face (by face id)."""
        hits = np.flatnonzero(self.faces == int(face_id))
        if len(hits) == 0:
            raise KeyError(face_id)
        return self.frames[:, int(hits[0])]


def fold_positions(model) -> np.ndarray:
    """Vertex positions `(S, n, 3)` of every fold state of a `FoldModel` (the key frame if none).

    A flat crease pattern whose frames do not start flat (a panel's flat + folded file) gets the
    key frame as its first state: folding starts from the flat sheet."""
    if model.n_frames == 0:
        return np.asarray(model.vertices_coords)[None]
    states = [np.asarray(f.vertices_coords) for f in model.frames]
    key = np.asarray(model.vertices_coords)
    if len(key) and np.all(key[:, 2] == 0.0) and not np.all(states[0][:, 2] == 0.0):
        states.insert(0, key)
    return np.stack(states)


def structure_tags(model) -> dict:
    """The model's faces_data with the structure's strip/middle tags where the file has no middle
    row: `fabkit.structure.panel_structure` of the last fold state (the folded geometry; strip tags
    the file has are kept), so files from other tools get a middle row too."""
    fd = dict(model.faces_data)
    if "middle" in fd:
        return fd
    from fabkit.structure import panel_structure

    mesh = model.frame_mesh(-1) if model.n_frames else model.mesh(validate=False)
    s = panel_structure(mesh)
    fd.update(strip=s.strip, middle=s.middle)
    if "polygon" in fd:  # triangles of one polygon: the polygon is in the middle row if one of them is
        poly = np.asarray(fd["polygon"])
        mid = np.zeros(int(poly.max()) + 1, np.int64)
        np.maximum.at(mid, poly, s.middle)
        fd["middle"] = mid[poly]
    return fd


def face_motion(frames: FaceFrames, face_id: int) -> tuple[float, float]:
    """(largest distance [m], largest turn [rad]) of a face's frame from its first state."""
    T = frames.of_face(face_id)
    C, Z = T[:, :3, 3], T[:, :3, 2]
    turn = np.arccos(np.clip(np.einsum("si,i->s", Z, Z[0]), -1.0, 1.0))
    return float(np.linalg.norm(C - C[0], axis=1).max()), float(turn.max())


#: A grip face that moves less than this [m] and turns less than MOTIONLESS_RAD folds nothing (the
#: clamped face of a relaxed noisy panel drifts by ~1e-6 m and 4e-5 rad: its quad is planar only to the
#: relax tolerance, so its second triangle turns a little about the diagonal).
MOTIONLESS_M, MOTIONLESS_RAD = 1e-4, 1e-3


def check_grip_face_moves(frames: FaceFrames, face_id: int, source: str | None = None,
                          clamped: int | None = None) -> None:
    """Refuse (InputError) the clamped face (`clamped`, e.g. a refold file's `fabkit:fixed_face`) or a
    grip face that does not move through the fold states: its program would fold nothing."""
    dist, turn = face_motion(frames, face_id)
    if face_id == clamped or (dist <= MOTIONLESS_M and turn <= MOTIONLESS_RAD):
        raise InputError(f"face {face_id} does not move in the fold states (it is the clamped face: moved "
                         f"{dist:.2g} m, turned {np.degrees(turn):.2g} deg); gripping it folds nothing",
                         source=source or "--grip-face")


def middle_row_frames(model, source: str | None = None) -> FaceFrames:
    """Face frames of the middle row of a `fabkit.fold.FoldModel` in every fold state (the middle row
    from the tags, or inferred: `structure_tags`)."""
    groups = face_groups(model.faces_vertices, structure_tags(model), source)
    row = middle_row(groups, source)
    frames = row_frames(groups, fold_positions(model), row)
    return FaceFrames(faces=groups.ids[row], strips=groups.strip[row], frames=frames)


def face_frames_of(model, face_id: int, source: str | None = None) -> FaceFrames:
    """Frames of one face (by face id) in every fold state, for files without middle-row tags:
    x runs along the face's first edge (a row of one face)."""
    groups = face_groups(model.faces_vertices, model.faces_data, source)
    try:
        g = groups.index_of(face_id)
    except KeyError:
        raise InputError(f"face {face_id} does not exist (faces {int(groups.ids.min())}..{int(groups.ids.max())})",
                         source=source) from None
    frames = row_frames(groups, fold_positions(model), [g])
    return FaceFrames(faces=groups.ids[[g]], strips=groups.strip[[g]], frames=frames)


def planning_frames(model, grip_face: int | None = None, source: str | None = None) -> FaceFrames:
    """The face frames a toolpath is planned on: for a file without middle-row tags and a given
    `grip_face`, that face's own frames; else the middle row's (tagged or inferred). A given grip
    face must move (not the clamped face): `InputError` otherwise."""
    if grip_face is not None and "middle" not in model.faces_data:
        frames = face_frames_of(model, grip_face, source=source)
    else:
        frames = middle_row_frames(model, source=source)
    if grip_face is not None and grip_face in frames.faces.tolist():
        check_grip_face_moves(frames, grip_face, clamped=model.file_data.get("fabkit:fixed_face"))
    return frames
