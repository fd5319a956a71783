"""The hole filling (`fabkit.nest.fill`): its placements on hand-written parts pinned, and its batched
drop against the per-part shifts of `rows._shift_past` it stands for."""
from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import Polygon, box

from fabkit.nest import NestOptions
from fabkit.nest import rows as R
from fabkit.nest.engines import Placement, place
from fabkit.nest.fill import _Sheet, fill_holes
from fabkit.nest.outline_math import rotate_points

#: 800 x 500 mm sheets, a 5.2 mm gap, 10 mm to the edge
OPTS = NestOptions(sheet=(800.0, 500.0), spacing=5.0, kerf=0.2, edge=10.0)

PARTS = [Polygon(p) for p in [
    [(0, 0), (300, 0), (240, 180), (0, 180)],                                        # 0 trapezoid
    [(0, 0), (250, 0), (250, 60), (80, 60), (80, 200), (0, 200)],                    # 1 L, concave
    [(0, 0), (200, 0), (200, 120), (0, 60)],                                         # 2 sloped top
    [(0, 0), (120, 0), (0, 90)],                                                     # 3 triangle
    [(0, 0), (100, 0), (100, 80), (70, 80), (70, 30), (30, 30), (30, 80), (0, 80)],  # 4 U, concave
    [(0, 0), (140, 0), (180, 50), (40, 50)],                                         # 5 parallelogram
    [(0, 0), (400, 0), (400, 400), (0, 400)],                                        # 6 fits no hole
    [(0, 0), (90, 0), (90, 20), (20, 20), (20, 70), (0, 70)],                        # 7 small L, concave
]]

#: sheet 0 holds parts 0-2 with room between them; the last sheet (1) holds the rest
START = [Placement(0, 0, 0.0, 10.0, 10.0), Placement(1, 0, 0.0, 540.0, 10.0), Placement(2, 0, 0.0, 10.0, 300.0),
         Placement(3, 1, 0.0, 10.0, 10.0), Placement(4, 1, 0.0, 200.0, 10.0), Placement(5, 1, 0.0, 350.0, 10.0),
         Placement(6, 1, 0.0, 10.0, 90.0), Placement(7, 1, 0.0, 600.0, 10.0)]


def test_fill_holes_places_hand_written_parts_where_it_always_has():
    placements, moved = fill_holes(START, 2, PARTS, OPTS, None)
    assert moved == 4
    by = {p.part: p for p in placements}
    assert [by[k] for k in (0, 1, 2, 6)] == [START[k] for k in (0, 1, 2, 6)]  # the full sheet's parts and the square stay
    # (sheet, turn [deg], x, y [mm]) as the search finds them: the largest first, each as low, then as far
    # left (on the 5 mm x steps), as it goes; the small L stands in the L's bay, right of its leg
    pinned = {3: (0, 180.0, 430.0, 152.05554887152977),
              4: (0, 270.0, 440.0, 110.0),
              5: (0, 308.6598082540901, 280.0, 119.32163332202431),
              7: (0, 270.0, 630.0, 165.3)}
    for k, (sheet, angle, x, y) in pinned.items():
        assert by[k].sheet == sheet
        assert by[k].angle == pytest.approx(angle, abs=1e-9)
        assert (by[k].x, by[k].y) == pytest.approx((x, y), abs=1e-6)
    on_first = [place(PARTS[k], by[k]) for k in by if by[k].sheet == 0]
    inside = box(OPTS.edge, OPTS.edge, OPTS.sheet[0] - OPTS.edge, OPTS.sheet[1] - OPTS.edge)
    assert all(inside.contains(g) for g in on_first)
    assert min(a.distance(b) for i, a in enumerate(on_first) for b in on_first[i + 1:]) >= OPTS.gap - 1e-9


def _drop_one_x(sheet: _Sheet, P: np.ndarray, x: float, lo: float, hi: float) -> float:
    """The lowest clear y at one x from each near part's interval of `rows._shift_past` (NaN: none)."""
    Q = (P + [x, 0.0])[:, ::-1]
    x1, top = x + float(np.ptp(P[:, 0])), hi + float(np.ptp(P[:, 1]))
    b = sheet.bx
    blocked = []
    for k in np.nonzero((b[:, 1] >= x) & (b[:, 0] <= x1) & (b[:, 3] > lo) & (b[:, 2] < top))[0]:
        up = R._shift_past(sheet.grown[k], Q)
        down = -R._shift_past(Q, sheet.grown[k])
        if math.isfinite(up) and down < up:
            blocked.append((down, up))
    y = lo
    for down, up in sorted(blocked):
        if up > y:
            if down >= y:
                break
            y = up
    return y if y <= hi + 1e-9 else math.nan


@pytest.mark.parametrize("part, angle", [(3, 0.0), (4, 270.0), (5, 308.6598082540901), (7, 90.0), (0, 90.0)])
def test_the_batched_drop_gives_the_per_part_shifts_bit_for_bit(part, angle):
    sheet = _Sheet([place(PARTS[p.part], p) for p in START if p.sheet == 0], OPTS)
    P = rotate_points(np.asarray(PARTS[part].exterior.coords), angle)
    P = R._coarse(P - P.min(axis=0))
    W, H = OPTS.sheet
    lo, hi = OPTS.edge, H - OPTS.edge - float(np.ptp(P[:, 1]))
    xs = np.arange(OPTS.edge, W - OPTS.edge - float(np.ptp(P[:, 0])) + 1e-9, 2.5)
    got = sheet.drops(P, xs, lo, hi)
    want = np.array([_drop_one_x(sheet, P, float(x), lo, hi) for x in xs])
    assert (want[np.isfinite(want)] > lo + 1.0).sum() >= 5  # spots on top of parts, not only the floor
    assert np.isnan(want).any() == (part in (0, 4, 5))  # the larger ones find no spot at some x
    assert np.array_equal(got, want, equal_nan=True)
