"""Row nesting: known sheet counts of identical parts, order independence, and the hole filling."""
from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import Polygon, box

from fabkit.nest import NestOptions, nest_parts
from fabkit.nest.engines import Placement, place
from fabkit.nest.fill import fill_holes
from nest_shapes import bowed_parts


#: the distances these known answers are worked out for: a 10.2 mm gap and 10 mm to the sheet edge
TEN = dict(spacing=10.0, kerf=0.2, edge=10.0)


def _rect(w, h):
    return Polygon([(0, 0), (w, 0), (w, h), (0, h)])


def _parallelogram(b, h, s):
    return Polygon([(0, 0), (b, 0), (b + s, h), (s, h)])


@pytest.mark.parametrize("count, sheets", [(60, 2), (61, 3)])
def test_identical_rectangles_held_along_the_sheet_fill_the_grid(count, sheets):
    # 150 x 80 mm with a 10.2 mm gap in the 980 x 480 mm inside of a 1000 x 500 mm sheet: 6 x 5 = 30 a
    # sheet, the most identical rectangles held in one orientation can give
    opts = NestOptions(sheet=(1000.0, 500.0), grain="x", **TEN)
    parts = [_rect(150.0, 80.0) for _ in range(count)]
    n = nest_parts(parts, opts)
    assert n.verify(parts) == []
    assert n.n_sheets == sheets
    assert max(sum(p.sheet == s for p in n.placements) for s in range(n.n_sheets)) == 30


def test_identical_parallelograms_fill_the_lattice_of_rows():
    # base 200, height 100, leaning 45 deg: slid to the 10.2 mm gap square to the slanted sides their
    # pitch is 200 + 10.2 / sin 45 = 214.4 mm, so 6 on a 1480 mm row (300 + 5 * 214.4 = 1372), and
    # 6 rows of 100 + 10.2 in 680 mm: 36 a sheet where shelves of their bounding boxes (300 x 100) give 4 x 6 = 24
    opts = NestOptions(sheet=(1500.0, 700.0), grain="x", **TEN)
    parts = [_parallelogram(200.0, 100.0, 100.0) for _ in range(72)]
    n = nest_parts(parts, opts)
    assert n.verify(parts) == []
    assert n.n_sheets == 2
    pitch = 200.0 + opts.gap / math.sin(math.radians(45.0))
    assert 300.0 + 5 * pitch <= 1480.0 < 300.0 + 6 * pitch
    shelf = nest_parts(parts, NestOptions(sheet=(1500.0, 700.0), grain="x", engine="shelf", **TEN))
    assert shelf.n_sheets == 3  # 24 a sheet


def _mixed(n=40, seed=3):
    return bowed_parts(n, seed, width=(120, 380), height=(60, 220), skew=(-150, 150), bow=(0, 25), top_points=6)


def test_rows_give_the_same_sheets_for_a_permuted_input():
    parts = _mixed()
    opts = NestOptions(sheet=(1500.0, 800.0), **TEN)
    a = nest_parts(parts, opts)
    perm = np.random.default_rng(7).permutation(len(parts))
    moved = [parts[i] for i in perm]
    b = nest_parts(moved, opts)
    assert a.verify(parts) == [] and b.verify(moved) == []
    assert a.n_sheets == b.n_sheets
    assert b.utilisation == pytest.approx(a.utilisation, rel=1e-12)


def test_a_part_no_shelf_holds_is_dropped_into_a_hole(monkeypatch):
    # a 600 x 400 mm sheet, parts held along it: a 200 x 380 mm block fills the height, two 360 x 100 mm
    # bars and a 120 mm square beside it; shelves put parts only on a shelf's floor or under its top,
    # so one of them needs a second sheet, and the hole filling drops it into the band between the others
    opts = NestOptions(sheet=(600.0, 400.0), grain="x", **TEN)
    parts = [_rect(200.0, 380.0), _rect(360.0, 100.0), _rect(360.0, 100.0), _rect(120.0, 120.0)]
    n = nest_parts(parts, opts)
    assert n.verify(parts) == []
    assert n.n_sheets == 1
    assert any("moved into holes" in note for note in n.notes)
    import fabkit.nest.fill as fill

    monkeypatch.setattr(fill, "fill_holes", lambda placements, n, *a: (placements, 0))
    assert nest_parts(parts, opts).n_sheets == 2


def test_fill_holes_moves_only_parts_that_clear_the_gap():
    # two 580 x 100 mm bars leave a band 380 - 200 - 2 * 10.2 = 159.6 mm high between them
    opts = NestOptions(sheet=(600.0, 400.0), **TEN)
    parts = [_rect(580.0, 100.0), _rect(580.0, 100.0), _rect(170.0, 170.0), _rect(120.0, 120.0)]
    start = [Placement(0, 0, 0.0, 10.0, 10.0), Placement(1, 0, 0.0, 10.0, 290.0),
             Placement(2, 1, 0.0, 10.0, 10.0), Placement(3, 1, 0.0, 300.0, 10.0)]
    placements, moved = fill_holes(start, 2, parts, opts, None)
    assert moved == 1  # the 170 mm square cannot stand in the band at any turn; the 120 mm one can
    by = {p.part: p for p in placements}
    assert by[2].sheet == 1 and by[3].sheet == 0
    g = place(parts[3], by[3])
    assert box(10.0, 110.0, 590.0, 290.0).contains(g)
    assert min(g.distance(place(parts[k], by[k])) for k in (0, 1)) >= opts.gap - 1e-6
    x0, y0, _, _ = g.bounds
    assert (x0, y0) == pytest.approx((10.0, 110.0 + opts.gap), abs=0.2)  # as low, then as far left, as it goes
