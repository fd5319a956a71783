"""Turning a part for a shelf: its least height, its ideal shelf cell, and the turn with the least
cell (`fabkit.nest.rows`, module docstring).

A part's candidate turns put a hull edge on the x axis. Their bounding boxes are found as shapely's
`affinity.rotate` finds them, and their cells (two grown outlines and three slides each) for every
turn at once (`fabkit.nest.outline_math`), so the turn chosen is the one the per-turn computation
chooses, at a fraction of its numpy per-call cost.
"""
from __future__ import annotations

import math

import numpy as np
import shapely
from shapely.geometry import Polygon

from fabkit.nest.outline_math import grow_all, rotate_points, shifts_past

__all__ = ["least_height_angle", "ideal_shelf_cell", "least_cell_angle", "distinct_angles", "TALLER", "ANGLE_STEP"]

#: a part is turned to its least shelf cell only among the angles at most this many times its least
#: height (a long strip standing across the shelves would leave their lengths empty)
TALLER = 1.3


#: [deg] hull edges within this angle of one already tried are not tried again (a curved side's
#: many nearly collinear hull edges; measured on the pleated vault: the same nesting, twice as fast)
ANGLE_STEP = 0.2


def distinct_angles(angles: list[float]) -> list[float]:
    """`angles` less those within `ANGLE_STEP` (mod 360) of an earlier one."""
    kept: list[float] = []
    for a in angles:
        if all(abs((a - k + 180.0) % 360.0 - 180.0) >= ANGLE_STEP for k in kept):
            kept.append(a)
    return kept


def least_cell_angle(part: Polygon, gap: float, angles: list[float] | None = None,
                     room: tuple[float, float] = (math.inf, math.inf)) -> float:
    """The rotation [deg] (a hull edge on the x axis, or one of `angles`) with the least
    `ideal_shelf_cell` among those where the part fits `room` (width, height; else its least
    height): a sheared part can waste less with its slanted sides across the shelf, where the gap
    between neighbours is measured square to them, not along the shelf."""
    angles = _hull_angles(part) if angles is None else angles
    best = _least_height(angles, _turned_bounds(part, angles))
    distinct = distinct_angles(angles)
    bounds = _turned_bounds(part, [best] + distinct).tolist()
    _, lo, _, hi = bounds[0]
    fits = [a for a, (x0, y0, x1, y1) in zip(distinct, bounds[1:])
            if not (x1 - x0 > room[0] + 1e-9 or y1 - y0 > min(room[1], TALLER * (hi - lo)) + 1e-9)]
    best_c = math.inf
    for a, c in zip(fits, _shelf_cells(part, gap, fits) if fits else []):
        if c < best_c * (1 - 1e-9):
            best, best_c = float(a), c
    return best


def _turned_bounds(part: Polygon, angles: list[float]) -> np.ndarray:
    """Bounds (x0, y0, x1, y1) of `part` rotated by each of `angles` [deg] about the origin, one a
    row: the arithmetic of shapely's `affinity.rotate`, so the same numbers, for every angle at once."""
    cs = []
    for a in angles:
        r = a * math.pi / 180.0
        c, s = math.cos(r), math.sin(r)
        cs.append((0.0 if abs(c) < 2.5e-16 else c, 0.0 if abs(s) < 2.5e-16 else s))
    c, s = (np.array(cs).reshape(-1, 2).T)[:, :, None]
    xoff, yoff = 0.0 - 0.0 * c + 0.0 * s, 0.0 - 0.0 * s - 0.0 * c
    x, y = shapely.get_coordinates(part).T
    xp, yp = c * x + (-s) * y + xoff, s * x + c * y + yoff
    return np.stack([xp.min(axis=1), yp.min(axis=1), xp.max(axis=1), yp.max(axis=1)], axis=1)


def _hull_angles(part: Polygon) -> list[float]:
    """The rotations [deg] turning each hull edge of `part` onto the x axis."""
    h = np.asarray(part.convex_hull.exterior.coords)
    return [-math.degrees(math.atan2(y, x)) for x, y in np.diff(h, axis=0) if x or y]


def _least_height(angles: list[float], bounds: np.ndarray) -> float:
    """The first of `angles` with the least bounding-box height (`bounds` per angle), else 0."""
    best, best_h = 0.0, math.inf
    for a, h in zip(angles, (bounds[:, 3] - bounds[:, 1]).tolist()):
        if h < best_h - 1e-9:
            best, best_h = float(a), h
    return best


def least_height_angle(part: Polygon, angles: list[float] | None = None) -> float:
    """The rotation [deg] (about the origin) giving `part` its least bounding-box height: one of
    its hull edges turned onto the x axis, or one of `angles` when given (grain)."""
    angles = _hull_angles(part) if angles is None else angles
    return _least_height(angles, _turned_bounds(part, angles))


def _shelf_cells(part: Polygon, gap: float, angles: list[float]) -> list[float]:
    """`ideal_shelf_cell` of `part` at each of `angles`, their outlines grown and slid all at once."""
    base = np.asarray(part.exterior.coords)
    Ps, Qs = [], []
    for a in angles:
        P, Q = rotate_points(base, a), rotate_points(base, a + 180.0)
        Ps.append(P - P.min(axis=0))
        Qs.append(Q - Q.min(axis=0))
    n = len(angles)
    grown = grow_all(Ps + Qs, gap)
    s = shifts_past(grown[:n] * 2 + grown[n:], Ps + Qs + Ps).tolist()
    return [min(s[k], 0.5 * (s[n + k] + s[2 * n + k])) * (np.ptp(Ps[k][:, 1]) + gap) for k in range(n)]


def ideal_shelf_cell(part: Polygon, gap: float, angle: float | None = None) -> float:
    """Area [mm^2] the part takes in an endless shelf of its own copies, turned by `angle` (default:
    its least height), each the same way up or turned by 180 deg in turn, whichever is shorter:
    its slid pitch times (its height + the gap). The least a shelf nesting can give it."""
    return _shelf_cells(part, gap, [least_height_angle(part) if angle is None else angle])[0]
