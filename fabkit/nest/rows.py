"""Row nesting: every part turned to its least height, packed on shelves and slid against its neighbour.

The flat patterns of a panelled surface are mostly sheared quadrilaterals and bands (the pleated
vault: parallelograms, their developed bounding rectangles only 63 % full). A shelf packing of
bounding rectangles wastes the shear; sparrow (`engine="packingsolver"`) nests the true outlines
but, measured on the 494 panels of the pleated vault, reaches only 62–68 % strip density within
the tens of seconds a production run can give it (it needs minutes for so many parts). This
engine keeps the shelves and wastes no shear: each part is turned to the angle of least height
(a hull edge on the shelf's floor, or that turned by 180°), then slid along its shelf until it is
exactly the gap from the parts already there, so slanted sides nest into each other.

The sliding is exact for polygons: the parts already on the shelf are grown by the gap with
mitred corners (shapely `buffer`, never closer than the gap), and the least shift that puts the
new part right of them is the largest difference of the two piecewise-linear outlines, which lies
at one of their vertices' heights. Written here because no well-kept library does shelf sliding;
the result is verified with shapely like every nesting (`Nesting.verify`).

Parts go by decreasing height, each onto the shelf (of any sheet) where it wastes least: the shelf
area it adds (its length increase times the shelf height) less its own area; so a part follows a
neighbour it nests with, and small parts fill the shelves of earlier sheets. Shelves are stacked
with the gap between them; a new shelf goes on the first sheet with room for it above its shelves
(so the low shelves of later, shorter parts fill the tops of earlier sheets), a new sheet only
when no sheet has (measured on the pleated vault: 9 sheets -> 8).
"""
from __future__ import annotations

import math

import numpy as np
from shapely import affinity
from shapely.geometry import Polygon

from fabkit.nest.engines import NestOptions, Placement, grain_angles

__all__ = ["nest_rows", "least_height_angle", "SHELF_SLACK"]


def least_height_angle(part: Polygon, angles: list[float] | None = None) -> float:
    """The rotation [deg] (about the origin) giving `part` its least bounding-box height: one of
    its hull edges turned onto the x axis, or one of `angles` when given (grain)."""
    if angles is None:
        h = np.asarray(part.convex_hull.exterior.coords)
        d = np.diff(h, axis=0)
        angles = [-math.degrees(math.atan2(y, x)) for x, y in d if x or y]
    best, best_h = 0.0, math.inf
    for a in angles:
        _, y0, _, y1 = affinity.rotate(part, a, origin=(0.0, 0.0)).bounds
        if y1 - y0 < best_h - 1e-9:
            best, best_h = float(a), y1 - y0
    return best


def _outline_x_at(coords: np.ndarray, ys: np.ndarray, rightmost: bool) -> np.ndarray:
    """Rightmost (or leftmost) x of a closed outline at each height in `ys` (NaN where it has none)."""
    a, b = coords[:-1], coords[1:]
    y0, y1 = a[:, 1], b[:, 1]
    lo, hi = np.minimum(y0, y1), np.maximum(y0, y1)
    Y = ys[:, None]
    cross = (Y >= lo) & (Y <= hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(y1 != y0, (Y - y0) / (y1 - y0), 0.0)
        x = a[:, 0] + t * (b[:, 0] - a[:, 0])
    flat = (y1 == y0)  # a horizontal edge at that height: both its ends count
    x_flat = np.maximum(a[:, 0], b[:, 0]) if rightmost else np.minimum(a[:, 0], b[:, 0])
    x = np.where(flat, x_flat, x)
    fill = -np.inf if rightmost else np.inf
    x = np.where(cross, x, fill)
    out = x.max(axis=1) if rightmost else x.min(axis=1)
    return np.where(np.isfinite(out), out, np.nan)


def _shift_past(grown: np.ndarray, part: np.ndarray) -> float:
    """Least x shift that puts outline `part` right of outline `grown` at every common height
    (-inf when they share no height)."""
    lo = max(grown[:, 1].min(), part[:, 1].min())
    hi = min(grown[:, 1].max(), part[:, 1].max())
    if lo > hi:
        return -math.inf
    ys = np.concatenate([grown[:, 1], part[:, 1], [lo, hi]])
    ys = ys[(ys >= lo) & (ys <= hi)]
    d = _outline_x_at(grown, ys, True) - _outline_x_at(part, ys, False)
    d = d[np.isfinite(d)]
    return float(d.max()) if len(d) else -math.inf


def _lean(outline: np.ndarray) -> int:
    """+1 when the outline's upper half lies right of its lower half, -1 when left, 0 when neither."""
    y = outline[:, 1]
    mid = 0.5 * (y.min() + y.max())
    up, down = outline[y >= mid, 0].mean(), outline[y <= mid, 0].mean()
    return int(np.sign(round(up - down, 6)))


def _slant(outline: np.ndarray) -> float:
    """Angle [deg] of the line from the lower half's mean to the upper half's mean, from vertical."""
    y = outline[:, 1]
    mid = 0.5 * (y.min() + y.max())
    up, down = outline[y >= mid].mean(axis=0), outline[y <= mid].mean(axis=0)
    return math.degrees(math.atan2(up[0] - down[0], up[1] - down[1]))


class _Shelf:
    def __init__(self, sheet: int, y: float, height: float):
        self.sheet, self.y, self.height = sheet, y, height
        self.grown: list[tuple[np.ndarray, float]] = []  # outlines of its parts grown by the gap, right end
        self.right = -math.inf


#: [mm] outlines are simplified (Douglas-Peucker) by this for the sliding, and grown by twice this
#: more than the gap (both sides of a pair simplified), so the simplification can only add distance
COARSE_TOL = 0.05


def _coarse(P: np.ndarray) -> np.ndarray:
    """The outline with (nearly) collinear vertices removed, within `COARSE_TOL` of it."""
    return np.asarray(Polygon(P).simplify(COARSE_TOL, preserve_topology=True).exterior.coords)


def _grow(P: np.ndarray, gap: float) -> np.ndarray:
    return np.asarray(Polygon(P).buffer(gap, join_style="mitre", mitre_limit=10.0).exterior.coords)


def _rotate_pts(P: np.ndarray, angle: float) -> np.ndarray:
    a = math.radians(angle)
    R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return P @ R.T


#: a part is tried on shelves at most this many gaps taller than itself (on a much taller shelf it
#: wastes more than on one of its own; measured on the pleated vault: the same sheets, 5 times faster)
SHELF_SLACK = 6.0


def _placement(pid: int, sheet: int, base: np.ndarray, placed: np.ndarray) -> Placement:
    """The rigid placement taking the part's outline `base` onto `placed` (same vertices; Kabsch)."""
    cb, cp = base.mean(axis=0), placed.mean(axis=0)
    U, _, Vt = np.linalg.svd((base - cb).T @ (placed - cp))
    D = np.diag([1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    t = cp - R @ cb
    if np.abs(base @ R.T + t - placed).max() > 1e-6:
        raise ValueError(f"part {pid}: its outline was not moved rigidly")
    angle = math.degrees(math.atan2(R[1, 0], R[0, 0]))
    return Placement(part=pid, sheet=sheet, angle=angle, x=float(t[0]), y=float(t[1]))


def _pack(items: list[list[tuple[int, float, np.ndarray]]], parts: list[Polygon], options: NestOptions,
          grain) -> tuple[list[Placement], int, int]:
    """Shelf packing with sliding of items, each a rigid group of parts [(part id, angle of the part
    in the item [deg], outline in item coordinates)]: each item turned to its least height (or
    that + 180 deg), by decreasing height, onto the shelf where it wastes least (module docstring)."""
    W, H = options.sheet
    m, gap = options.spacing, options.gap
    variants = []  # per item: [(turn, [(pid, angle, outline at lower left)], width, height)]
    for item in items:
        hull = Polygon(np.vstack([P for _, _, P in item])).convex_hull
        a = least_height_angle(hull, grain)
        vs = []
        for turn in (a, a + 180.0):
            rot = [(pid, ang + turn, _rotate_pts(P, turn)) for pid, ang, P in item]
            allp = np.vstack([P for _, _, P in rot])
            lo = allp.min(axis=0)
            w, h = np.ptp(allp[:, 0]), np.ptp(allp[:, 1])
            vs.append((turn, [(pid, ang, P - lo, _coarse(P - lo)) for pid, ang, P in rot], w, h))
        variants.append(vs)
    step = max(gap, 1.0)  # by decreasing height in steps of the gap; parts leaning alike together
    order = sorted(range(len(items)), key=lambda i: (-round(variants[i][0][3] / step),
                                                     _lean(variants[i][0][1][0][3]),
                                                     round(_slant(variants[i][0][1][0][3]) / 5.0),
                                                     -variants[i][0][2], i))
    shelves: list[_Shelf] = []
    tops: list[float] = []  # per sheet: where its next shelf would start
    n_sheets = 0
    out: list[Placement] = []
    for i in order:
        h = variants[i][0][3]
        area = sum(parts[pid].area for pid, _, _ in items[i])  # noqa: E501
        best = None  # (waste, shelf, x, variant): the shelf where the item wastes least
        for shelf in shelves:
            if not h - 1e-9 <= shelf.height <= h + SHELF_SLACK * max(gap, 1.0) + 1e-9:
                continue
            for var in variants[i]:
                _, members, w, _ = var
                x = m
                for _, _, _, C in members:
                    pts = C + [0.0, shelf.y]
                    for grown, right in reversed(shelf.grown):
                        if right > x:  # a grown outline left of x cannot push the part (its left side is at x)
                            x = max(x, _shift_past(grown, pts + [0.0, 0.0]))
                if x + w > W - m + 1e-9:
                    continue
                waste = (max(x + w, shelf.right) - max(shelf.right, m)) * shelf.height - area
                if best is None or waste < best[0] - 1e-9:
                    best = (waste, shelf, x, var)
        if best is None:  # a new shelf: on the first sheet with room above its shelves, else a new sheet
            sheet, y = next(((k, tops[k]) for k in range(n_sheets) if tops[k] + h <= H - m + 1e-9), (n_sheets, m))
            if sheet == n_sheets:
                n_sheets += 1
                tops.append(m)
            tops[sheet] = y + h + gap
            shelf = _Shelf(sheet, y, h)
            shelves.append(shelf)
            best = (0.0, shelf, m, variants[i][0])
        _, shelf, x, (_, members, w, _) = best
        for pid, ang, P, C in members:
            placed = P + [x, shelf.y]
            grown = _grow(C + [x, shelf.y], gap + 2 * COARSE_TOL)
            shelf.grown.append((grown, float(grown[:, 0].max())))
            shelf.right = max(shelf.right, float(placed[:, 0].max()))
            out.append(_placement(pid, shelf.sheet, np.asarray(parts[pid].exterior.coords), placed))
    return sorted(out, key=lambda p: p.part), n_sheets, len(shelves)


def nest_rows(parts: list[Polygon], options: NestOptions) -> tuple[list[Placement], int, list[str]]:
    """Placements of `parts` on sheets by row nesting (module docstring)."""
    items = [[(i, 0.0, np.asarray(g.exterior.coords))] for i, g in enumerate(parts)]
    placements, n, shelves = _pack(items, parts, options, grain_angles(options))
    return placements, n, [f"row nesting: {shelves} shelves, parts turned to their least height and slid to the gap"]
