"""The shelf packing's batched arithmetic against the per-call computation it stands for, bit for bit:
the slides of `outline_math.shifts_past` and `rows._slides` against `rows._shift_past` one pair at a
time, and the turns' cells against grown outlines slid one by one and shapely's `affinity.rotate`."""
from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from shapely import affinity
from shapely.geometry import Polygon

from fabkit.nest import rows as R
from fabkit.nest import turns as T
from fabkit.nest.outline_math import grow, rotate_points, shifts_past

#: hand-written parts [mm], some concave (L, U, notched), one with a curved (many-vertex) side
PARTS = [Polygon(p) for p in [
    [(0, 0), (300, 0), (240, 180), (0, 180)],                                        # trapezoid
    [(0, 0), (250, 0), (250, 60), (80, 60), (80, 200), (0, 200)],                    # L, concave
    [(0, 0), (100, 0), (100, 80), (70, 80), (70, 30), (30, 30), (30, 80), (0, 80)],  # U, concave
    [(0, 0), (140, 0), (180, 50), (40, 50)],                                         # parallelogram
    [(0, 0), (120, 0), (0, 90)],                                                     # triangle
    [(0, 0), (200, 0), (230, 40), (200, 45), (215, 110), (10, 100), (30, 50)],       # notched both sides
    [(0, 0), (260, 0)] + [(260 - 2.6 * k, 60 + 25 * math.sin(math.pi * k / 100)) for k in range(0, 101, 5)],
]]
GAP = 2.2


def _bits(values) -> list[bytes]:
    return [struct.pack("<d", float(v)) for v in values]


def _outline(part: Polygon, angle: float, coarse: bool = False) -> np.ndarray:
    P = rotate_points(np.asarray(part.exterior.coords), angle)
    P = P - P.min(axis=0)
    return R._coarse(P) if coarse else P


def _pairs():
    """(grown outline, part outline) pairs: every part grown beside every part, turned and raised
    so some share all their heights, some a part and some none."""
    out = []
    for i, a in enumerate(PARTS):
        G = grow(_outline(a, 17.0 * i), GAP) + [40.0 * i, 0.0]
        for j, b in enumerate(PARTS):
            for dy in (-150.0, -37.5, 0.0, 63.25, 260.0):
                out.append((G, _outline(b, 90.0 * j + 7.0, coarse=j % 2 == 1) + [0.0, dy]))
    return out


def test_batched_shifts_equal_the_per_pair_shift_bit_for_bit():
    pairs = _pairs()
    want = [R._shift_past(G, P) for G, P in pairs]
    got = shifts_past([G for G, _ in pairs], [P for _, P in pairs])
    assert sum(math.isinf(w) for w in want) >= 10 and sum(math.isfinite(w) for w in want) >= 150  # both kinds
    assert _bits(got) == _bits(want)


def _slide_one_by_one(shelf, members, y: float, x0: float) -> float:
    """The per-call slide the batched one stands for: each part, newest grown outline first."""
    x = x0
    for *_, C in members:
        for grown, right in reversed(shelf.grown):
            if right > x:
                x = max(x, R._shift_past(grown, C + [0.0, y]))
    return x


def test_batched_slides_equal_the_one_by_one_slides_bit_for_bit():
    # a 300 mm shelf holding four parts placed by hand (the U hanging from its top), then every part,
    # both ways up, slid along it on its floor and from its top
    shelf = R._Shelf(0, 5.0, 300.0, 5.0)
    for k, (x, y) in zip((0, 2, 1, 3), ((5.0, 5.0), (330.0, 225.0), (470.0, 5.0), (760.0, 5.0))):
        shelf.add(grow(R._coarse(_outline(PARTS[k], 0.0)) + [x, y], GAP + 2 * R.COARSE_TOL))
    spots = []
    for part in PARTS:
        for turn in (0.0, 180.0):
            P = _outline(part, turn)
            h = float(np.ptp(P[:, 1]))
            var = (turn, [(0, turn, P, R._coarse(P))], float(np.ptp(P[:, 0])), h)
            spots += [(shelf, var, 5.0), (shelf, var, 5.0 + 300.0 - h)]
    want = [_slide_one_by_one(shelf, var[1], y, 5.0) for shelf, var, y in spots]
    assert len(set(want)) >= 10 and min(want) > 5.0  # the parts are pushed to different places
    assert _bits(R._slides(spots, 5.0)) == _bits(want)
    bounds = R._slide_bounds(spots)
    assert all(b <= x for b, x in zip(bounds, want))  # never right of the slide: no spot skipped wrongly
    assert np.median(np.array(want) - bounds) < 20.0  # and close enough to skip most spots that cannot fit
    h = max(v[3] for _, v, _ in spots)
    for low in (40.0, 150.0):  # the band above or below the item: usable later, or wasted
        got = R._wastes(spots, want, h, low)
        one_by_one = [_waste_one_by_one(shelf, v[1], x, y, h, low) for (shelf, v, y), x in zip(spots, want)]
        assert _bits(got) == _bits(one_by_one)
        assert sum(w > 0 for w in got) >= 10


def _waste_one_by_one(shelf, members, x: float, y: float, h: float, low: float) -> float:
    """The waste of one spot with `rows._outline_x_at`, part by part (`rows._wastes`)."""
    span = (shelf.ys >= y) & (shelf.ys <= y + h)
    if not span.any():
        return 0.0
    lefts, rights = np.full(int(span.sum()), np.inf), np.full(int(span.sum()), -np.inf)
    for *_, C in members:
        lefts = np.fmin(lefts, R._outline_x_at(C + [x, y], shelf.ys[span], False))
        rights = np.fmax(rights, R._outline_x_at(C + [x, y], shelf.ys[span], True))
    lefts = np.where(np.isfinite(lefts), lefts, rights)
    waste = float(np.clip(lefts - shelf.profile[span], 0.0, None).sum()) * R.PROFILE_STEP
    if 1e-9 < shelf.height - h < low:
        right = float(np.nanmax(rights)) if np.isfinite(rights).any() else x
        waste += float(np.clip(right - shelf.profile[~span], 0.0, None).sum()) * R.PROFILE_STEP
    return waste


def _cell_one_by_one(part: Polygon, gap: float, angle: float) -> float:
    """`ideal_shelf_cell` grown and slid one outline at a time."""
    P, Q = _outline(part, angle), _outline(part, angle + 180.0)
    G, GQ = grow(P, gap), grow(Q, gap)
    pitch = min(R._shift_past(G, P), 0.5 * (R._shift_past(G, Q) + R._shift_past(GQ, P)))
    return pitch * (np.ptp(P[:, 1]) + gap)


def _least_cell_one_by_one(part: Polygon, gap: float, room) -> float:
    """`least_cell_angle` with shapely's `affinity.rotate` bounds and one cell at a time."""
    h = np.asarray(part.convex_hull.exterior.coords)
    angles = [-math.degrees(math.atan2(y, x)) for x, y in np.diff(h, axis=0) if x or y]
    best, best_h = 0.0, math.inf
    for a in angles:
        _, y0, _, y1 = affinity.rotate(part, a, origin=(0.0, 0.0)).bounds
        if y1 - y0 < best_h - 1e-9:
            best, best_h = float(a), y1 - y0
    _, lo, _, hi = affinity.rotate(part, best, origin=(0.0, 0.0)).bounds
    best_c = math.inf
    for a in T.distinct_angles(angles):
        x0, y0, x1, y1 = affinity.rotate(part, a, origin=(0.0, 0.0)).bounds
        if x1 - x0 > room[0] + 1e-9 or y1 - y0 > min(room[1], T.TALLER * (hi - lo)) + 1e-9:
            continue
        c = _cell_one_by_one(part, gap, a)
        if c < best_c * (1 - 1e-9):
            best, best_c = float(a), c
    return best


@pytest.mark.parametrize("gap", [GAP, 10.2])
def test_the_turns_cells_equal_the_one_by_one_cells_bit_for_bit(gap):
    for part in PARTS:
        angles = T._hull_angles(part)
        assert _bits(T._shelf_cells(part, gap, angles)) == _bits(_cell_one_by_one(part, gap, a) for a in angles)
        for room in ((math.inf, math.inf), (250.0, 190.0)):
            want = _least_cell_one_by_one(part, gap, room)
            assert _bits([T.least_cell_angle(part, gap, None, room)]) == _bits([want])
    chosen = {T.least_cell_angle(part, gap) for part in PARTS}
    assert len(chosen) >= 3  # not all the same turn


def test_the_turned_bounds_are_shapely_rotates_bit_for_bit():
    for part in PARTS:
        angles = T._hull_angles(part) + [0.0, 90.0, -90.0, 180.0, 270.0, 33.3]  # quarter turns: cos, sin snapped to 0
        want = [b for a in angles for b in affinity.rotate(part, a, origin=(0.0, 0.0)).bounds]
        assert _bits(T._turned_bounds(part, angles).ravel()) == _bits(want)
