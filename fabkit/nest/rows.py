"""Row nesting: every part turned to its least shelf cell, packed on shelves and slid against its neighbour.

The flat patterns of a panelled surface are mostly sheared quadrilaterals and bands (the pleated
vault: parallelograms, their developed bounding rectangles only 63 % full). A shelf packing of
bounding rectangles wastes the shear; sparrow (`engine="packingsolver"`) nests the true outlines
but, measured on the 494 panels of the pleated vault, reaches only 65 % strip density even in
120 s for one strip (it needs far longer for so many parts). This engine keeps the shelves and
wastes no shear: each part is slid along its shelf until it is exactly the gap from the parts
already there, so slanted sides nest into each other.

Turning: each part goes a hull edge on the shelf's floor (or that turned by 180 deg), the one with
the least `ideal_shelf_cell` (its pitch in an endless shelf of its own copies times its height
plus the gap) among the turns at most `TALLER` times its least height: the gap between sheared
neighbours is measured square to their sides, so the least height is not always the least area
(`fabkit.nest.turns`).

The sliding is exact for polygons: the parts already on the shelf are grown by the gap with
mitred corners (shapely `buffer`, never closer than the gap), and the least shift that puts the
new part right of them is the largest difference of the two piecewise-linear outlines, which lies
at one of their vertices' heights. Written here because no well-kept library does shelf sliding;
the result is verified with shapely like every nesting (`Nesting.verify`).

Parts go by decreasing height, each onto the shelf (of any sheet) where it wastes least. A part
sits on a shelf's floor or, when the band left above or below it is tall enough for another part,
hangs from its top too, so two low parts share a tall shelf. The waste of a spot is judged on the
shelf's profile (the rightmost grown outline at every millimetre of its height): the area between
the profile and the part's left side, plus the band beside the part when no part is low enough to
use it. A spot wasting more than `WASTE_NEW` times the part's area (e.g. a part leaning the other
way, which leaves a triangle) gives way to a new shelf when a sheet has room for one. Shelves are
stacked with the gap between them; a new shelf goes on the first sheet with room for it above its
shelves, a new sheet only when no sheet has.

Then the last sheet's parts, largest first, are dropped into the holes the shelves left on the
earlier sheets where they fit, turned upright or across too (`fabkit.nest.fill`); the last sheet
goes when all of them move, else its rest is nested again on its own when that is shorter. Last,
the last sheet's parts are nested again with the shelves across the sheet (along its short side,
from its left end) when that leaves a longer offcut at its right end: the offcut
(`Nesting.used_length_utilisation`) can go back to stock.

Speed: the outlines have ~15-30 vertices, so one at a time the packing spends its time in numpy's
per-call cost. The cells of all turns of a part are found at once (`fabkit.nest.turns`), and per
part all its spots (shelf, either way up, on the floor or from the top) at once: first a lower
bound of each spot's slide from the shelf's profile (`_slide_bounds`), so a spot the part cannot
fit at is not slid (on the pleated vault 2130 of 17652 spots are), then the exact slides of the
rest (`_slides`) and their wastes (`_wastes`) with the arithmetic of one outline at a time
(`fabkit.nest.outline_math`), so the same placements bit for bit. Measured on the pleated vault's
494 parts, the two alternated in one process: the shelf packing ~2.9x faster in CPU time than spot
by spot (8.7-9.7 -> 3.0-3.2 s).
"""
from __future__ import annotations

import itertools
import math

import numpy as np
from shapely.geometry import Polygon

from fabkit.nest.engines import NestOptions, Placement, grain_angles
from fabkit.nest.outline_math import edges, extremes, grow, least, padded, rotate_points, shifts_past
from fabkit.nest.turns import TALLER, ideal_shelf_cell, least_cell_angle, least_height_angle

__all__ = ["nest_rows", "least_height_angle", "least_cell_angle", "ideal_shelf_cell", "SHELF_SLACK", "TALLER", "WASTE_NEW"]


#: a spot on a shelf wasting more than this times the part's area gives way to a new shelf on a
#: sheet with room for it (measured on the pleated vault: the last sheet 49 % -> 37 % full, the sheets the same)
WASTE_NEW = 0.45
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


#: [mm] height step of a shelf's profile (the rightmost grown outline at each height), used to
#: judge the waste of a placement; the placement itself is exact (`_shift_past`)
PROFILE_STEP = 1.0


class _Shelf:
    """A band of the sheet, `height` tall from `y`; parts sit on its floor or hang from its top."""

    def __init__(self, sheet: int, y: float, height: float, left: float):
        self.sheet, self.y, self.height = sheet, y, height
        self.grown: list[tuple[np.ndarray, float]] = []  # outlines of its parts grown by the gap, right end
        self.reach = np.empty((0, 3))  # per grown outline: its lowest y, highest y, right end
        self.right = -math.inf
        self.ys = y + np.arange(0.5 * PROFILE_STEP, height, PROFILE_STEP)  # profile heights
        self.profile = np.full(len(self.ys), left)  # where a part's left side may start, per height

    def add(self, grown: np.ndarray) -> None:
        """Keeps a placed part's grown outline (and its reach), and the profile right of it."""
        right = float(grown[:, 0].max())
        self.grown.append((grown, right))
        self.reach = np.vstack([self.reach, [grown[:, 1].min(), grown[:, 1].max(), right]])
        self.profile = np.fmax(self.profile, np.nan_to_num(_outline_x_at(grown, self.ys, True), nan=-np.inf))

#: [mm] outlines are simplified (Douglas-Peucker) by this for the sliding, and grown by twice this
#: more than the gap (both sides of a pair simplified), so the simplification can only add distance
COARSE_TOL = 0.05


def _coarse(P: np.ndarray) -> np.ndarray:
    """The outline with (nearly) collinear vertices removed, within `COARSE_TOL` of it."""
    return np.asarray(Polygon(P).simplify(COARSE_TOL, preserve_topology=True).exterior.coords)


#: a part is tried on the floor of shelves at most this many gaps taller than itself unless the band
#: left beside it holds another part (on a much taller shelf it wastes more than on one of its own)
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


def _slides(spots, x0: float) -> list[float]:
    """Per spot (shelf, item variant, y): the least x >= x0 at which the item's outlines (lower left
    at (0, y)) clear every grown outline on the shelf (exact).

    Part by part and newest grown outline first, a grown outline pushes x to its `_shift_past` unless
    it ends left of x (it cannot push the part, whose left side is at x), so mostly the first one
    decides. The spots go in rounds, each taking the next 1, 2, 4... outlines of every spot that
    can still push it, all slid in one `shifts_past`, then applied in order with that same test: the
    same x as one shift at a time. Outlines sharing no height with a part cannot push it."""
    xs = [x0] * len(spots)
    queues = []  # per spot: (grown outline, its right end, part outline), in the order they are applied
    for shelf, group in itertools.groupby(spots, key=lambda spot: spot[0]):
        pts = [[C + [0.0, y] for *_, C in members] for _, (_, members, _, _), y in group]
        flat = [P[:, 1] for ps in pts for P in ps]
        at = np.cumsum([0] + [len(P) for P in flat[:-1]])
        low, high = np.minimum.reduceat(np.concatenate(flat), at), np.maximum.reduceat(np.concatenate(flat), at)
        lo, hi, right = shelf.reach[::-1].T  # newest first
        near = (right > x0) & (np.maximum(lo, low[:, None]) <= np.minimum(hi, high[:, None]))
        rows, cols = np.nonzero(near)
        cols = (len(right) - 1 - cols).tolist()
        bounds = np.searchsorted(rows, np.arange(len(flat) + 1)).tolist()
        k = 0
        for ps in pts:
            q = []
            for P in ps:
                q += [shelf.grown[j] + (P,) for j in cols[bounds[k]:bounds[k + 1]]]
                k += 1
            queues.append(q)
    at, take = [0] * len(spots), 1
    while True:
        batch = []  # (spot, grown outline, right end, part outline)
        for i, q in enumerate(queues):
            batch += [(i, *e) for e in q[at[i]:at[i] + take] if e[1] > xs[i]]
            at[i] += take
        if not batch:
            return xs
        for (i, _, right, _), s in zip(batch, shifts_past([b[1] for b in batch], [b[3] for b in batch]).tolist()):
            if right > xs[i]:
                xs[i] = max(xs[i], s)
        take *= 2


#: [mm] taken off a slide's bound from the shelf's profile (`_slide_bounds`): far more than the
#: rounding of the outlines' interpolation (~1e-12 mm), so the bound is never right of the slide
BOUND_SLACK = 1e-6
#: profile heights per spot at which that bound is taken
BOUND_HEIGHTS = 16


def _slide_bounds(spots) -> np.ndarray:
    """Per spot (shelf, item variant, y): a lower bound of its `_slides` x, so a spot the item cannot
    fit at needs no exact slide. The slide puts each part right of every grown outline by at least
    their difference at any height both span (its largest lies at their vertices' heights), and
    right of x0; so at each profile height (the rightmost grown outline there, or the shelf's left
    end) in the part's span, x >= profile - the part's left side, taken at `BOUND_HEIGHTS` of
    them, less `BOUND_SLACK`."""
    shelves = list(dict.fromkeys(shelf for shelf, _, _ in spots))
    first = dict(zip(shelves, np.cumsum([0] + [len(shelf.ys) for shelf in shelves]).tolist()))
    outlines = list({id(C): C for _, (_, members, _, _), _ in spots for *_, C in members}.values())
    which = {id(C): i for i, C in enumerate(outlines)}
    rows = [(k, which[id(C)], first[shelf], len(shelf.ys), shelf.y, y, h)
            for k, (shelf, (_, members, _, h), y) in enumerate(spots) if len(shelf.ys) for *_, C in members]
    out = np.full(len(spots), -np.inf)
    if not rows:
        return out
    owner, ci, start, n, sy, y, h = (np.array(c) for c in zip(*rows))
    # any profile heights give a bound; these are spread over the part's span (outside it: none)
    a = np.clip(np.ceil((y - sy) / PROFILE_STEP - 0.5), 0, n - 1).astype(int)
    b = np.clip(np.floor((y + h - sy) / PROFILE_STEP - 0.5), a, n - 1).astype(int)
    at = start[:, None] + a[:, None] + np.arange(BOUND_HEIGHTS) * (b - a)[:, None] // (BOUND_HEIGHTS - 1)
    heights = np.concatenate([shelf.ys for shelf in shelves])[at]
    profile = np.concatenate([shelf.profile for shelf in shelves])[at]
    C = padded(outlines)[ci]
    left = least(heights, edges(C[:, :, 0] + 0.0, C[:, :, 1] + y[:, None]))  # parts at (0, y); inf: none there
    np.maximum.at(out, owner, (profile - left).max(axis=1))
    return out - BOUND_SLACK


def _wastes(spots, xs: list[float], h: float, low: float) -> list[float]:
    """Per spot (shelf, item variant, y) with the item at x: the area [mm^2] the placement leaves
    unusable on the shelf: between the shelf's profile and the item's left side over the heights it
    spans, and the band above or below it when that band is too low for any part (`low`: the least
    part height) to use later. The item's sides at the profile heights are found for every spot at
    once (`outline_math.extremes`, the numbers of `_outline_x_at`)."""
    spans = [(shelf.ys >= y) & (shelf.ys <= y + h) for shelf, _, y in spots]
    rows = [(C + [x, y], shelf.ys[span]) for (shelf, (_, members, _, _), y), x, span in zip(spots, xs, spans)
            if span.any() for *_, C in members]
    if rows:
        P = padded([pts for pts, _ in rows])
        Y = np.full((len(rows), max(len(ys) for _, ys in rows)), np.nan)  # no outline has a NaN height
        for r, (_, ys) in enumerate(rows):
            Y[r, :len(ys)] = ys
        tops, bottoms = extremes(Y, edges(P[:, :, 0], P[:, :, 1]))
    out, r = [], 0
    for (shelf, (_, members, _, _), y), x, span in zip(spots, xs, spans):
        if not span.any():
            out.append(0.0)
            continue
        n = int(span.sum())
        lefts, rights = np.full(n, np.inf), np.full(n, -np.inf)
        for _ in members:
            lefts, rights = np.fmin(lefts, bottoms[r, :n]), np.fmax(rights, tops[r, :n])
            r += 1
        base = shelf.profile[span]
        lefts = np.where(np.isfinite(lefts), lefts, rights)
        waste = float(np.clip(lefts - base, 0.0, None).sum()) * PROFILE_STEP
        band = shelf.height - h
        if 1e-9 < band < low:  # a band too low for any part: wasted along the item's length
            right = float(np.nanmax(rights)) if np.isfinite(rights).any() else x
            rest = ~span
            waste += float(np.clip(right - shelf.profile[rest], 0.0, None).sum()) * PROFILE_STEP
        out.append(waste)
    return out


def _pack(items: list[list[tuple[int, float, np.ndarray]]], parts: list[Polygon], options: NestOptions,
          grain) -> tuple[list[Placement], int, int]:
    """Shelf packing with sliding of items, each a rigid group of parts [(part id, angle of the part
    in the item [deg], outline in item coordinates)]: each item turned to its least height (or
    that + 180 deg), by decreasing height, onto the shelf where it wastes least (module docstring)."""
    W, H = options.sheet
    m, gap = options.edge, options.gap
    variants = []  # per item: [(turn, [(pid, angle, outline at lower left)], width, height)]
    for item in items:
        hull = Polygon(np.vstack([P for _, _, P in item])).convex_hull
        a = least_cell_angle(hull, gap, grain, (W - 2 * m, H - 2 * m))
        vs = []
        for turn in (a, a + 180.0):
            rot = [(pid, ang + turn, rotate_points(P, turn)) for pid, ang, P in item]
            allp = np.vstack([P for _, _, P in rot])
            lo = allp.min(axis=0)
            w, h = np.ptp(allp[:, 0]), np.ptp(allp[:, 1])
            vs.append((turn, [(pid, ang, P - lo, _coarse(P - lo)) for pid, ang, P in rot], w, h))
        variants.append(vs)
    low = min((v[0][3] for v in variants), default=0.0) + gap  # the least band a part can use
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
        best = None  # (waste, shelf, x, y, variant): the placement that wastes least
        spots = []  # (shelf, variant, y) the item may take
        for shelf in shelves:
            if shelf.height < h - 1e-9:
                continue
            stacked = shelf.height >= h + low - 1e-9  # room for another part above or below it
            if not stacked and shelf.height > h + SHELF_SLACK * step:
                continue
            free = W - m - float(shelf.profile.min())
            spots += [(shelf, var, y) for var in variants[i] if var[2] <= free + 1e-9
                      for y in ((shelf.y, shelf.y + shelf.height - h) if stacked else (shelf.y,))]
        spots = [spot for spot, x in zip(spots, _slide_bounds(spots).tolist()) if x + spot[1][2] <= W - m + 1e-9]
        xs = _slides(spots, m)
        fits = [(spot, x) for spot, x in zip(spots, xs) if x + spot[1][2] <= W - m + 1e-9]
        for ((shelf, var, y), x), waste in zip(fits, _wastes([f[0] for f in fits], [f[1] for f in fits], h, low)):
            if best is None or waste < best[0] - 1e-9:
                best = (waste, shelf, x, y, var)
        room = next(((k, tops[k]) for k in range(n_sheets) if tops[k] + h <= H - m + 1e-9), None)
        area = sum(parts[pid].area for pid, _, _ in items[i])
        if best is not None and room is not None and best[0] > WASTE_NEW * area:
            best = None
        if best is None:  # a new shelf: on the first sheet with room above its shelves, else a new sheet
            sheet, y = room or (n_sheets, m)
            if sheet == n_sheets:
                n_sheets += 1
                tops.append(m)
            tops[sheet] = y + h + gap
            shelf = _Shelf(sheet, y, h, m)
            shelves.append(shelf)
            best = (0.0, shelf, m, y, variants[i][0])
        _, shelf, x, y, (_, members, w, _) = best
        for pid, ang, P, C in members:
            placed = P + [x, y]
            shelf.add(grow(C + [x, y], gap + 2 * COARSE_TOL))
            shelf.right = max(shelf.right, float(placed[:, 0].max()))
            out.append(_placement(pid, shelf.sheet, np.asarray(parts[pid].exterior.coords), placed))
    return sorted(out, key=lambda p: p.part), n_sheets, len(shelves)


def nest_rows(parts: list[Polygon], options: NestOptions) -> tuple[list[Placement], int, list[str]]:
    """Placements of `parts` on sheets by row nesting (module docstring)."""
    from fabkit.nest.fill import fill_holes
    from fabkit.nest.last_sheet import last_sheet_across, last_sheet_again, used_length

    items = [[(i, 0.0, np.asarray(g.exterior.coords))] for i, g in enumerate(parts)]
    grain = grain_angles(options)
    placements, n, shelves = _pack(items, parts, options, grain)
    notes = [f"row nesting: {shelves} shelves, parts turned to their least shelf cell and slid to the gap"]
    placements, moved = fill_holes(placements, n, parts, options, grain)
    if moved:
        left = sum(p.sheet == n - 1 for p in placements)
        notes.append(f"{moved} part{'s' if moved > 1 else ''} of the last sheet moved into holes of the others")
        if not left:
            n -= 1
        else:
            placements = last_sheet_again(placements, n, parts, options, grain)
    if n:
        across = last_sheet_across(placements, n, parts, options, grain)
        if across is not None:
            notes.append(f"last sheet nested across from its left end: used to "
                         f"{used_length([p for p in across if p.sheet == n - 1], parts) + options.edge:.0f} mm "
                         f"of {options.sheet[0]:g} mm")
            placements = across
    return placements, n, notes
