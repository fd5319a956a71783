"""Where the clamp jaw can sit: the sheet around the clamped face that the fold states keep still.

A panel's faces are a discretisation of a smooth sheet: on a ruled strip the faces are slivers
between rulings (on the pleated vault 11.6-29 mm wide, median 15.7 mm, under a 24 x 16 mm jaw), and
the rulings bend by a fraction of a degree. The jaw clamps a patch of that sheet, not one face. The
fold states are expressed in the frame of one clamped face (refold's fixed face: at its flat
position in every state); a neighbouring face whose sheet, where the jaw can reach it, stays within
`tol` of its flat position in every state can be clamped with it: the jaw holds it where the
states put it (the pad takes the difference).

`clamp_region` grows that region from the clamped face's triangles across hinges that are not
creases or the outline (rulings and polygon diagonals), keeping each neighbouring triangle's part
within the jaw's reach (the face grown by the footprint's circumradius: the jaw's centre stays on
the clamped face) when that part's displacement from the flat pattern is at most `tol` in every
state. A triangle moves rigidly, so its displacement is an affine field and the largest value over
a convex piece is at the piece's vertices (exact, not sampled). `best_jaw_pose` then puts the
footprint in that region at an in-plane pose (yaw and offset): the smallest turn from the face's
long axis at which the jaw has `PLACEMENT_TOL` of slack (the distance the jaw may be misplaced in
any direction and still lie in the region with its centre on the clamped face), centred on the
face's area centroid when that leaves the slack, else at the offset of most slack (the pole of
inaccessibility of the centres that fit); when no turn gives the slack, the turn of most slack.
Both are from geometry alone (no vertex or face order enters: yaws are measured from `fabkit.placement.clamped_face_frame`'s axis; ties go to the smallest turn).

What is in: the sheet's position under the jaw in every fold state (rigid faces), the jaw's
outline. What is out: how hard the jaw presses, friction, and the sheet's elastic flattening under
the jaw (on the pleated vault the sheet under a 24 mm jaw is within 0.02 mm of a plane).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry import MultiPoint, Point, Polygon
from shapely.ops import polylabel, unary_union

__all__ = ["ClampRegion", "JawPose", "clamp_region", "best_jaw_pose", "region_joins", "JAW_TOL", "PLACEMENT_TOL"]

#: The sheet under the jaw may leave the position the fold states give it by this much [m] (as the
#: clamped face itself: `sim.check_holds.CLAMP_MOTION_TOL`), well inside a padded jaw's compliance.
JAW_TOL = 1e-4
#: Slack [m] the jaw pose should leave: how far the panel may be laid off its place on the fixture
#: (by hand against stops, about 1 mm; an assumption, not measured).
PLACEMENT_TOL = 1e-3
#: Yaws tried (deg from the face frame's x axis), the smallest turn first; refined by 1/8 step about the
#: best when none leaves `PLACEMENT_TOL`.
_STEP = 2.0
_YAWS = np.array([0.0] + [s * k for k in np.arange(_STEP, 180.0 + 1e-9, _STEP) for s in (1, -1)][:-1])


@dataclass(frozen=True, eq=False)
class ClampRegion:
    """`polygon` (shapely, flat pattern [m]) where the jaw may lie; `faces` the polygon ids it
    covers (the clamped face first, then by id); `worst_m` the largest displacement from the flat
    pattern of the sheet in it over all fold states; `refused` {face: displacement [m]} of the
    neighbouring faces left out because they move more than the tolerance within the jaw's reach."""

    polygon: Polygon
    faces: tuple[int, ...]
    worst_m: float
    refused: dict


@dataclass(frozen=True)
class JawPose:
    """The jaw on the flat pattern: `frame` 3x3 (2D homogeneous: x axis, y axis, origin [m]), `yaw_deg`
    from the face frame's x axis, `slack_m` how far it may shift in any direction and stay on the
    region with its centre on the clamped face (negative: no pose fits; then the face frame)."""

    frame: np.ndarray
    yaw_deg: float
    slack_m: float

    @property
    def fits(self) -> bool:
        return self.slack_m >= 0.0


def _displacement(flat: np.ndarray, positions: np.ndarray, tri: np.ndarray, pts: np.ndarray) -> float:
    """Largest distance over states of points `pts` (k, 2) of triangle `tri` from their flat position."""
    A, B, C = flat[tri, :2]
    M = np.array([B - A, C - A]).T
    uv = np.linalg.solve(M, (pts - A).T).T
    bary = np.column_stack([1 - uv.sum(1), uv])
    d = positions[:, tri] - flat[tri][None]                       # (S, 3, 3) vertex displacements
    return float(np.linalg.norm(np.einsum("kc,scd->skd", bary, d), axis=2).max()) if len(pts) and len(d) else 0.0


def clamp_region(flat_vertices, tris, tri_face, tri_joins, positions, face: int, reach: float,
                 tol: float = JAW_TOL) -> ClampRegion:
    """The region the jaw may clamp around polygon `face` (module docstring). `flat_vertices` (n, 3)
    the flat pattern, `tris` (T, 3) with `tri_face` (T,) polygon ids, `tri_joins` (k, 2) pairs of
    triangles sharing a hinge that is not a crease or the outline, `positions` (S, n, 3) the fold
    states, `reach` [m] the footprint's circumradius about the jaw centre."""
    V = np.asarray(flat_vertices, np.float64)
    T = np.asarray(tris, np.int64)
    owner = np.asarray(tri_face, np.int64)
    X = np.asarray(positions, np.float64).reshape(-1, *V.shape)
    own = np.flatnonzero(owner == int(face))
    if len(own) == 0:
        raise ValueError(f"face {face} is not a face of the panel")
    face_poly = unary_union([Polygon(V[t, :2]) for t in T[own]]).buffer(0)
    zone = face_poly.buffer(reach, quad_segs=8)
    nbr: dict[int, set[int]] = {}
    for a, b in np.asarray(tri_joins, np.int64).reshape(-1, 2):
        nbr.setdefault(int(a), set()).add(int(b))
        nbr.setdefault(int(b), set()).add(int(a))
    keep = {int(t): Polygon(V[T[t], :2]) for t in own}
    worst = max(_displacement(V, X, T[t], V[T[t], :2]) for t in own)
    refused: dict[int, float] = {}
    front = sorted(keep)
    while front:
        nxt = []
        for t in front:
            for u in sorted(nbr.get(t, ())):
                if u in keep or u in refused:
                    continue
                piece = Polygon(V[T[u], :2]).intersection(zone)
                if piece.is_empty or piece.area <= 0:
                    continue
                pts = np.vstack([np.asarray(g.exterior.coords)[:-1] for g in getattr(piece, "geoms", [piece])
                                 if g.geom_type == "Polygon"])
                d = _displacement(V, X, T[u], pts)
                if d <= tol:
                    keep[u] = piece
                    worst = max(worst, d)
                    nxt.append(u)
                else:
                    refused[u] = d
        front = sorted(nxt)
    region = unary_union(list(keep.values())).buffer(0)
    if region.geom_type != "Polygon":  # the piece that holds the clamped face
        region = max(region.geoms, key=lambda g: g.intersection(face_poly).area)
    faces = sorted({int(owner[t]) for t, p in keep.items() if p.intersection(region).area > 0} - {int(face)})
    out_faces: dict[int, float] = {}
    for t, d in refused.items():
        f = int(owner[t])
        if f not in faces and f != int(face):
            out_faces[f] = max(out_faces.get(f, 0.0), d)
    return ClampRegion(polygon=region, faces=(int(face), *faces), worst_m=float(worst), refused=out_faces)


def _erosion(region: Polygon, foot: np.ndarray):
    """Centres c where c + `foot` (convex, (k, 2), the origin inside) lies in `region`."""
    rings = [np.asarray(region.exterior.coords)] + [np.asarray(r.coords) for r in region.interiors]
    hulls = []
    for ring in rings:
        for a, b in zip(ring[:-1], ring[1:]):
            hulls.append(MultiPoint(np.vstack([a - foot, b - foot])).convex_hull)
    return region.difference(unary_union(hulls))


def best_jaw_pose(region: Polygon, face_polygon: Polygon, footprint, face_frame,
                  need: float = PLACEMENT_TOL) -> JawPose:
    """The jaw pose on `region` with its centre on `face_polygon` (module docstring): the footprint
    (k, 2) [m] in the jaw frame (its convex hull is what must fit), turned by the smallest yaw from
    the x axis of `face_frame` (4x4 or 3x3, `fabkit.placement.clamped_face_frame`) at which it has
    `need` [m] of slack, centred on the frame's origin when that leaves `need`, else at the offset of
    most slack; when no yaw gives `need`, the yaw of most slack.
    No fit at all: the face frame, slack -1."""
    fp = np.asarray(footprint, np.float64)
    hull = np.asarray(MultiPoint(fp).convex_hull.exterior.coords)[:-1]
    F = np.asarray(face_frame, np.float64)
    x0 = F[:2, 0] / np.linalg.norm(F[:2, 0])
    base = float(np.degrees(np.arctan2(x0[1], x0[0])))
    if not Polygon(hull).buffer(1e-12).contains(Point(0.0, 0.0)):
        raise ValueError("the clamp footprint must contain its pose's origin (the jaw centre)")

    origin = Point(F[0, -1], F[1, -1])

    def slack(yaw: float):
        a = np.radians(base + yaw)
        R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        feas = _erosion(region, hull @ R.T).intersection(face_polygon)
        if feas.contains(origin) and feas.boundary.distance(origin) >= need:  # the face frame's origin
            return float(feas.boundary.distance(origin)), np.asarray(origin.coords[0]), R
        best = (-1.0, None, R)
        for g in getattr(feas, "geoms", [feas]):
            if g.geom_type != "Polygon" or g.is_empty or g.area <= 0:
                continue
            p = polylabel(g, tolerance=1e-5)
            d = float(g.boundary.distance(p))
            if d > best[0]:
                best = (d, np.array(p.coords[0]), R)
        return best

    def pose(yaw, s, c, R):
        frame = np.eye(3)
        frame[:2, :2], frame[:2, 2] = R, c
        return JawPose(frame=frame, yaw_deg=float(yaw), slack_m=float(s))

    tried = []
    for yaw in _YAWS:
        s, c, R = slack(float(yaw))
        if c is not None and s >= need:
            return pose(yaw, s, c, R)
        tried.append((s, yaw))
    s0, y0 = max(tried, key=lambda t: (round(t[0], 7), -abs(t[1]), t[1]))
    if s0 < 0:
        fallback = np.array([[x0[0], -x0[1], F[0, -1]], [x0[1], x0[0], F[1, -1]], [0.0, 0.0, 1.0]])
        return JawPose(frame=fallback, yaw_deg=0.0, slack_m=-1.0)
    best = (s0, y0)
    for yaw in y0 + np.arange(-_STEP, _STEP + 1e-9, _STEP / 8):
        s, c, R = slack(float(yaw))
        if c is not None and (round(s, 7), -abs(yaw)) > (round(best[0], 7), -abs(best[1])):
            best = (s, float(yaw))
    s, c, R = slack(best[1])
    return pose(best[1], s, c, R)


def region_joins(tris, tri_face, edges, edge_kind) -> np.ndarray:
    """(k, 2) pairs of triangles that share an edge whose kind is a ruling or a polygon diagonal, or
    that belong to one polygon (a fan diagonal the FOLD file does not list)."""
    T = np.asarray(tris, np.int64)
    owner = np.asarray(tri_face, np.int64)
    E = np.sort(np.asarray(edges, np.int64), axis=1)
    kind = dict(zip(map(tuple, E.tolist()), np.asarray(edge_kind).tolist()))
    first: dict[tuple, int] = {}
    out = []
    for t, tri in enumerate(T.tolist()):
        for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
            e = (a, b) if a < b else (b, a)
            if e in first:
                u = first[e]
                if kind.get(e) in ("ruling", "diagonal") or (e not in kind and owner[u] == owner[t]):
                    out.append((u, t))
            else:
                first[e] = t
    return np.array(out, np.int64).reshape(-1, 2)

