"""Where the panel sits on the clamp: the clamped face on the clamp's footprint, for any vertex order.

The panel frame is the frame the fold states live in (the flat pattern, z = 0, with the clamped
face at its flat position in every state: refold's fixed face). A clamp is a pose in the world (its
z axis out of the jaw, toward the panel) and a footprint polygon in that pose's xy plane.

`clamped_face_frame` gives the face a frame from its geometry alone: origin at the polygon's area
centroid, z along the front normal (+z of the flat pattern), x along the principal axis of the
polygon's second moment of area (the long direction of the face), the sign chosen toward the
panel's area centroid (then by the face's third moment). So permuting vertices or faces gives the
same frame. `place_on_clamp` returns the fixture (panel frame -> world) that puts that frame on the
clamp pose; `check_clamp_footprint` says whether the footprint stays inside the clamped face.
Shapely does the polygon work; the second moments of a polygon are written out (shapely has none).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry import Point, Polygon

__all__ = ["ClampCheck", "clamped_face_frame", "place_on_clamp", "check_clamp_footprint", "choose_clamp_face",
           "face_polygon"]

#: Footprint and face may disagree by this much (m) at their boundaries (round-off of the poses).
BOUNDARY_TOL = 1e-7
#: Directions whose projection is shorter than this (m, or m^4 / m^5 for moments) are undefined.
_TINY = 1e-12


def face_polygon(flat_vertices, face) -> Polygon:
    """Shapely polygon of one flat face (vertex ids in order; z ignored)."""
    P = np.asarray(flat_vertices, np.float64)[np.asarray(face, np.int64)][:, :2]
    poly = Polygon(P)
    if not poly.is_valid or poly.area <= 0:
        raise ValueError(f"face {list(map(int, face))} is not a simple polygon with area")
    return poly


def _second_moments(P: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, float]:
    """Area second-moment tensor (2x2) about c, and the triangle-fan areas' sign-free sum."""
    Q = P - c
    a, b = Q, np.roll(Q, -1, axis=0)
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    ixx = np.sum(cross * (a[:, 0] ** 2 + a[:, 0] * b[:, 0] + b[:, 0] ** 2)) / 12.0
    iyy = np.sum(cross * (a[:, 1] ** 2 + a[:, 1] * b[:, 1] + b[:, 1] ** 2)) / 12.0
    ixy = np.sum(cross * (a[:, 0] * b[:, 1] + 2 * a[:, 0] * a[:, 1] + 2 * b[:, 0] * b[:, 1] + b[:, 0] * a[:, 1])) / 24.0
    sign = 1.0 if cross.sum() >= 0 else -1.0
    return sign * np.array([[ixx, ixy], [ixy, iyy]]), float(abs(cross.sum()) / 2)


def clamped_face_frame(flat_vertices, face, panel_centroid=None) -> np.ndarray:
    """4x4 frame of a flat face in the panel frame, from its geometry only (module docstring)."""
    poly = face_polygon(flat_vertices, face)
    P = np.asarray(poly.exterior.coords)[:-1]
    c = np.array(poly.centroid.coords[0])
    M, _ = _second_moments(P, c)
    w, vec = np.linalg.eigh(M)
    x = vec[:, int(np.argmax(w))]
    if panel_centroid is not None:
        d = np.asarray(panel_centroid, np.float64)[:2] - c
        s = float(d @ x)
    else:
        s = 0.0
    if abs(s) <= 1e-9:  # the panel centroid does not decide: the face's third moment along x
        s = float(np.sum(((P - c) @ x) ** 3))
    if s < -_TINY:
        x = -x
    T = np.eye(4)
    T[:2, 0] = x
    T[:2, 1] = [-x[1], x[0]]
    T[:2, 3] = c
    return T


def place_on_clamp(flat_vertices, face, clamp_pose, panel_centroid=None) -> np.ndarray:
    """Fixture 4x4 (panel frame -> world) putting `face`'s frame on `clamp_pose` (4x4, world)."""
    return np.asarray(clamp_pose, np.float64) @ np.linalg.inv(clamped_face_frame(flat_vertices, face, panel_centroid))


@dataclass(frozen=True)
class ClampCheck:
    """`ok` iff the clamp footprint lies inside the clamped face, in its plane. `outside_area_m2`
    footprint area outside the face, `outside_m` the farthest footprint corner from the face,
    `off_plane_m` the footprint's largest distance from the face plane, `problems` one line each."""

    ok: bool
    face: int
    outside_area_m2: float
    outside_m: float
    off_plane_m: float
    problems: tuple[str, ...]


def check_clamp_footprint(flat_vertices, face, face_id: int, fixture, clamp_pose, footprint,
                          tol: float = BOUNDARY_TOL, where: str = "") -> ClampCheck:
    """Does the clamp footprint (k, 2) in the clamp pose's xy plane stay on the clamped face, with the
    panel placed by `fixture`? Fails naming the face and how far the footprint leaves it. `face` may
    be the outline of the sheet the jaw can hold around face `face_id` (`fabkit.clamp_region`);
    `where` then names it in the problem."""
    fp = np.asarray(footprint, np.float64)
    if fp.ndim != 2 or fp.shape[1] != 2 or len(fp) < 3:
        raise ValueError("a clamp footprint is a polygon of at least 3 (x, y) points")
    pts = np.column_stack([fp, np.zeros(len(fp)), np.ones(len(fp))])
    world = pts @ np.asarray(clamp_pose, np.float64).T
    local = world @ np.linalg.inv(np.asarray(fixture, np.float64)).T
    off_plane = float(np.abs(local[:, 2]).max())
    face_poly = face_polygon(flat_vertices, face)
    foot = Polygon(local[:, :2])
    if not foot.is_valid or foot.area <= 0:
        raise ValueError("the clamp footprint is not a simple polygon with area")
    outside_area = float(foot.difference(face_poly).area)
    outside = float(max(face_poly.distance(Point(p)) for p in local[:, :2])) \
        if not face_poly.buffer(tol).contains(foot) else 0.0
    problems = []
    if outside > tol or outside_area > tol * tol:
        problems.append(f"the clamp footprint leaves clamped face {face_id}: {outside * 1000:.1f} mm outside "
                        f"({outside_area * 1e6:.0f} mm^2 of {foot.area * 1e6:.0f} mm^2){where}")
    if off_plane > tol:
        problems.append(f"the clamp footprint is {off_plane * 1000:.1f} mm off the plane of clamped face {face_id}")
    return ClampCheck(ok=not problems, face=int(face_id), outside_area_m2=outside_area, outside_m=outside,
                      off_plane_m=off_plane, problems=tuple(problems))


def choose_clamp_face(flat, footprint=None, strip: int | None = None) -> int:
    """The face to clamp: of the faces (of `strip`, default the middle strip when the panel has strip
    tags; its middle-row faces first when tagged, refold's default fixed face) that hold the footprint
    (k, 2) centred on their frame, the one whose area centroid is nearest the panel's; ties broken by
    the centroid's coordinates, never by vertex or face order. Raises ValueError when no face holds
    the footprint."""
    V = np.asarray(flat.vertices, np.float64)
    faces = [flat.face(f) for f in range(flat.n_faces)]
    polys = [face_polygon(V, f) for f in faces]
    areas = np.array([p.area for p in polys])
    cents = np.array([p.centroid.coords[0] for p in polys])
    pc = (areas[:, None] * cents).sum(0) / areas.sum()
    cand = np.arange(flat.n_faces)
    if "strip" in flat.face_data:
        tags = np.asarray(flat.face_data["strip"], np.int64)
        want = (int(tags.min()) + int(tags.max())) // 2 if strip is None else int(strip)
        cand = cand[tags == want]
    def holding(cs):
        if footprint is None:
            return cs
        fp = np.asarray(footprint, np.float64)
        keep = []
        for f in cs:
            T = clamped_face_frame(V, faces[f], pc)
            pts = fp @ T[:2, :2].T + T[:2, 3]
            if polys[f].buffer(BOUNDARY_TOL).contains(Polygon(pts)):
                keep.append(f)
        return np.array(keep, np.int64)

    if "middle" in flat.face_data:
        mid = holding(cand[np.asarray(flat.face_data["middle"])[cand] != 0])
        cand = mid if len(mid) else holding(cand)
    else:
        cand = holding(cand)
    if len(cand) == 0:
        raise ValueError("no face holds the clamp footprint" + (f" in strip {want}" if "strip" in flat.face_data else ""))
    d = np.linalg.norm(cents[cand] - pc, axis=1)
    key = np.lexsort((np.round(cents[cand, 1], 9), np.round(cents[cand, 0], 9), np.round(d, 9)))
    return int(cand[key[0]])
