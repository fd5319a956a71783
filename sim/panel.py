"""The panel as one thin convex piece per face, posed for each fold state.

MuJoCo collides a mesh as its convex hull, so a folded panel given as one mesh would fill the space
between its wings. Each face therefore becomes its own convex mesh: the face polygon in a local
frame (origin at its centroid, z along its best-fit normal) extruded by +-thickness/2, or to one side
of the face when the face is one surface of a real sheet (a top-face design lies on the sheet). A fold state
moves every face rigidly; the pose of a piece in a state is the best rigid fit (Kabsch) of its
local polygon onto the state's vertex coordinates, and the fit residual says how far the state
departs from a rigid fold (curved-crease states bend a little inside a face).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["PanelPieces", "PanelModel", "panel_pieces", "piece_poses", "interpolate_poses", "panel_model",
           "panel_from_fold", "check_fold_coordinates", "DEFAULT_THICKNESS", "MAX_COORDINATE_M"]

#: Sheet thickness of the panel pieces (m) when the caller does not give one.
DEFAULT_THICKNESS = 0.001
#: Largest vertex coordinate (m) a FOLD file may have: a panel farther out is bad input, not a motion.
MAX_COORDINATE_M = 100.0


def check_fold_coordinates(model, source: str | None = None, limit_m: float = MAX_COORDINATE_M) -> None:
    """`InputError` naming the frame and vertex if any coordinate of a `fabkit.fold.FoldModel`
    (its key frame or any fold state) is non-finite or farther than `limit_m` from the origin."""
    from fabkit.errors import InputError

    frames = [("the crease pattern", model.vertices_coords)] + [
        (f"file_frames[{k}]", f.vertices_coords) for k, f in enumerate(getattr(model, "frames", ()))]
    for where, coords in frames:
        X = np.asarray(coords, dtype=np.float64)
        bad = ~np.isfinite(X).all(axis=-1) | (np.abs(np.nan_to_num(X, nan=np.inf)) > limit_m).any(axis=-1)
        if bad.any():
            v = int(np.flatnonzero(bad)[0])
            raise InputError(f"{where}: vertex {v} has coordinates {X[v].tolist()} (non-finite or beyond "
                             f"{limit_m:g} m)", source=source)


@dataclass(frozen=True, eq=False)
class PanelPieces:
    """Convex pieces of a panel: `local_vertices[f]` (2k, 3) prism corners of face f in its own frame
    (metres), `faces[f]` the vertex ids of face f, `thickness` (m)."""

    local_polygons: tuple[np.ndarray, ...]
    local_vertices: tuple[np.ndarray, ...]
    faces: tuple[np.ndarray, ...]
    thickness: float

    def __len__(self) -> int:
        return len(self.faces)


def _face_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid and rotation (columns x, y, z) of a face's vertices; z is the best-fit plane normal
    (smallest principal direction; its sign matters only for an offset slab, which `panel_pieces` turns
    to the front normal).
    The vertices need no order, so a polygon stored as triangles works as well."""
    c = points.mean(axis=0)
    p = points - c
    _, sv, vt = np.linalg.svd(p, full_matrices=True)
    if len(sv) < 2 or not np.all(np.isfinite(sv)) or sv[1] < 1e-9:
        raise ValueError("degenerate face: zero area")
    x, y = vt[0], vt[1]
    return c, np.column_stack([x, y, np.cross(x, y)])


def panel_pieces(vertices, faces, thickness: float = DEFAULT_THICKNESS, *, normals=None,
                 offset: float = 0.0) -> PanelPieces:
    """Build the pieces from reference vertex coordinates (n, 3) in the panel frame (usually the
    flat crease pattern) and faces (sequences of vertex ids: a polygon, or all the distinct
    vertices of a polygon stored as triangles).

    The slab is `thickness` thick, centred on the face (`offset` 0) or with its centre `offset` [m]
    along each face's front normal (`normals` (F, 3), required then): a sheet whose design surface
    is its top face lies behind it (offset -t/2)."""
    V = np.asarray(vertices, dtype=np.float64)
    if V.ndim != 2 or V.shape[1] != 3 or not np.isfinite(V).all():
        raise ValueError("panel vertices must be a finite (n, 3) array")
    if not thickness > 0:
        raise ValueError("panel thickness must be positive")
    if offset and normals is None:
        raise ValueError("an offset slab needs the faces' front normals")
    polys, prisms, fs = [], [], []
    for f, face in enumerate(faces):
        idx = np.unique(np.asarray(face, dtype=np.int64))
        if len(idx) < 3 or idx.min() < 0 or idx.max() >= len(V):
            raise ValueError(f"panel face {f} has bad vertex ids {idx.tolist()}")
        try:
            c, R = _face_frame(V[idx])
        except ValueError as exc:
            raise ValueError(f"panel face {f}: {exc}") from None
        if normals is not None and float(R[:, 2] @ np.asarray(normals[f], dtype=np.float64)) < 0:
            R = np.column_stack([R[:, 1], R[:, 0], -R[:, 2]])  # z along the front normal, still right-handed
        local = (V[idx] - c) @ R
        local[:, 2] = 0.0  # project onto the face plane (a relaxed face is planar to ~1e-4)
        h = np.array([0.0, 0.0, thickness / 2])
        z = np.array([0.0, 0.0, offset])
        polys.append(local)
        prisms.append(np.vstack([local + z - h, local + z + h]))
        fs.append(idx)
    return PanelPieces(tuple(polys), tuple(prisms), tuple(fs), float(thickness))


def piece_poses(pieces: PanelPieces, vertices) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rigid poses of every piece for one state's vertex coordinates (n, 3), or for a stack of
    states (S, n, 3).

    Returns positions (F, 3), quaternions (F, 4) scalar-first (MuJoCo order) and the fit residual
    (F,): the largest distance between a state vertex and its fitted piece corner (m); with a
    leading state axis for stacked input. Kabsch (SVD of the cross-covariance, determinant fixed to
    +1), vectorised over faces and states: faces are padded to the largest vertex count with zero
    weights.
    """
    V = np.asarray(vertices, dtype=np.float64)
    single = V.ndim == 2
    V = V[None] if single else V
    F = len(pieces)
    kmax = max(len(f) for f in pieces.faces)
    idx = np.zeros((F, kmax), dtype=np.int64)
    w = np.zeros((F, kmax))
    L = np.zeros((F, kmax, 3))
    for f, (face, local) in enumerate(zip(pieces.faces, pieces.local_polygons)):
        idx[f, :len(face)] = face
        w[f, :len(face)] = 1.0
        L[f, :len(face)] = local
    count = w.sum(axis=1)
    Lc = L - (np.einsum("fk,fkj->fj", w, L) / count[:, None])[:, None, :]
    Lc *= w[..., None]
    T = V[:, idx]                                                      # (S, F, kmax, 3)
    c = np.einsum("fk,sfkj->sfj", w, T) / count[None, :, None]         # target centroids
    H = np.einsum("fki,sfkj->sfij", Lc, T - c[:, :, None, :])          # cross-covariance
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.swapaxes(Vt, -1, -2) @ np.swapaxes(U, -1, -2)))
    D = np.zeros_like(H)
    D[..., 0, 0] = D[..., 1, 1] = 1.0
    D[..., 2, 2] = np.where(d == 0, 1.0, d)
    R = np.swapaxes(Vt, -1, -2) @ D @ np.swapaxes(U, -1, -2)          # local -> state
    Lmean = np.einsum("fk,fkj->fj", w, L) / count[:, None]
    t = c - np.einsum("sfij,fj->sfi", R, Lmean)
    fitted = np.einsum("sfij,fkj->sfki", R, L) + t[:, :, None, :]
    res = np.max(np.linalg.norm(fitted - T, axis=-1) * w[None], axis=-1)
    xyzw = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(R.shape[0], F, 4)
    quat = xyzw[..., [3, 0, 1, 2]]
    return (t[0], quat[0], res[0]) if single else (t, quat, res)


def interpolate_poses(pos: np.ndarray, quat: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
    """Piece poses at fractional fold state `s` from per-state poses pos (S, F, 3), quat (S, F, 4).

    Linear in position, normalised-linear in rotation between the two neighbouring states (steps
    between fold states are small rotations, where this equals slerp to second order).
    """
    S = pos.shape[0]
    s = float(np.clip(s, 0, S - 1))
    k = min(int(np.floor(s)), S - 2) if S > 1 else 0
    t = s - k
    if S == 1 or t == 0.0:
        return pos[k], quat[k]
    q0, q1 = quat[k], quat[k + 1]
    sign = np.where(np.sum(q0 * q1, axis=1, keepdims=True) < 0, -1.0, 1.0)
    q = (1 - t) * q0 + t * sign * q1
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return (1 - t) * pos[k] + t * pos[k + 1], q


@dataclass(frozen=True, eq=False)
class PanelModel:
    """The panel for the cell model: convex pieces and their world poses in every fold state.

    `pos` (S, F, 3) and `quat` (S, F, 4, scalar first) are in the world frame (fixture applied);
    `grip_face` the index of the piece the tool holds (its contact with the tool is excluded), or
    None; `fit_residual` (S, F) how far each state departs from a rigid motion of each face (m);
    `face_ids` the panel's id of each piece (polygon id), for names; `grip_by_waypoint` for a
    program in phases that grip different faces: per waypoint the piece the tool holds on the move
    into it (-1: none), its contact with the tool excluded per move instead (`grip_face` None).
    """

    pieces: PanelPieces
    pos: np.ndarray
    quat: np.ndarray
    grip_face: int | None = None
    fit_residual: np.ndarray | None = None
    face_ids: tuple[int, ...] = ()
    grip_by_waypoint: tuple[int, ...] | None = None

    @property
    def n_states(self) -> int:
        return int(self.pos.shape[0])

    @cached_property
    def _steps(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Quaternions with signs aligned state to state, and the per-step differences (computed once:
        the check asks for a new fold state at almost every configuration of a fold move)."""
        q = self.quat.copy()
        for k in range(1, len(q)):
            q[k, np.sum(q[k - 1] * q[k], axis=1) < 0] *= -1.0
        return q, np.diff(self.pos, axis=0), np.diff(q, axis=0)

    def poses_at(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """World poses (F, 3), (F, 4) of the pieces at fractional fold state `s` (as
        `interpolate_poses`: linear in position, normalised-linear in rotation)."""
        S = self.pos.shape[0]
        s = min(max(float(s), 0.0), S - 1.0)
        k = min(int(s), S - 2) if S > 1 else 0
        t = s - k
        if S == 1 or t == 0.0:
            return self.pos[k], self.quat[k]
        q, dp, dq = self._steps
        qt = q[k] + t * dq[k]
        qt /= np.sqrt(np.einsum("ij,ij->i", qt, qt))[:, None]
        return self.pos[k] + t * dp[k], qt


def panel_model(reference_vertices, faces, states_vertices, fixture, *, grip_face: int | None = None,
                thickness: float = DEFAULT_THICKNESS, face_ids=None, normals=None, offset: float = 0.0) -> PanelModel:
    """Pieces from the reference (flat) vertices and faces, posed for each state in the world.

    `states_vertices` (S, n, 3): vertex coordinates of every fold state in the panel frame;
    `fixture` 4x4: panel frame -> world; `face_ids` the id of each face (default 0..F-1), used to
    name the pieces `face_<id>`; `normals`, `offset`: the slab's side (`panel_pieces`).
    """
    pieces = panel_pieces(reference_vertices, faces, thickness, normals=normals, offset=offset)
    S = np.asarray(states_vertices, dtype=np.float64)
    if S.ndim != 3 or S.shape[1:] != np.asarray(reference_vertices).shape:
        raise ValueError(f"fold states must be (S, {len(reference_vertices)}, 3), got {S.shape}")
    if grip_face is not None and not 0 <= int(grip_face) < len(pieces):
        raise ValueError(f"grip face {grip_face} is not a face of the panel ({len(pieces)} faces)")
    Fx = np.asarray(fixture, dtype=np.float64)
    rot_fix = Rotation.from_matrix(Fx[:3, :3])
    p, q, res = piece_poses(pieces, S)
    pos = p @ Fx[:3, :3].T + Fx[:3, 3]
    world = rot_fix * Rotation.from_quat(q.reshape(-1, 4)[:, [1, 2, 3, 0]])
    quat = world.as_quat()[:, [3, 0, 1, 2]].reshape(q.shape)
    ids = np.arange(len(pieces)) if face_ids is None else np.asarray(face_ids, dtype=np.int64)
    return PanelModel(pieces, pos, quat, None if grip_face is None else int(grip_face), res, tuple(int(i) for i in ids))


def panel_from_fold(model, fixture, *, grip_face_id: int | None = None, thickness: float = DEFAULT_THICKNESS,
                    source: str | None = None, offset: float = 0.0) -> PanelModel:
    """The panel of a `fabkit.fold.FoldModel`: one piece per polygon (triangles of one polygon are
    grouped by `faces_fabkit:polygon`, as `fabkit.frames.face_groups` does), reference shape from the
    key frame (the crease pattern), poses for every fold state (`fabkit.frames.fold_positions`,
    the same states the toolpath's `state` indexes). `grip_face_id`: polygon id of the grip face.
    `offset` [m]: the slab's centre along the faces' front normals (`panel_pieces`)."""
    from fabkit.frames import face_groups, fold_positions, group_centroids_normals

    groups = face_groups(model.faces_vertices, model.faces_data, source)
    grip = None
    if grip_face_id is not None:
        try:
            grip = groups.index_of(int(grip_face_id))
        except KeyError:
            from fabkit.errors import InputError

            raise InputError(f"grip face {grip_face_id} is not a face of the panel", source=source) from None
    normals = group_centroids_normals(groups, np.asarray(model.vertices_coords))[1] if offset else None
    return panel_model(model.vertices_coords, groups.vertices, fold_positions(model), fixture, grip_face=grip,
                       thickness=thickness, face_ids=groups.ids, normals=normals, offset=offset)
