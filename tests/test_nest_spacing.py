"""The nesting distances from the fabricators' rule: web max(2 mm, 1.5 t), the process's kerf, 5 mm
(at least half the gap) to the sheet edge."""
from __future__ import annotations

import pytest
from shapely.geometry import box

from fabkit.errors import InputError
from fabkit.nest import NestOptions, nest_parts
from fabkit.nest.spacing import cut_spacing


@pytest.mark.parametrize("thickness, process, spacing, kerf, edge", [
    (0.5, "laser", 2.0, 0.2, 5.0),      # thin sheet: the 2 mm least web beyond the kerf
    (1.0, "laser", 2.0, 0.2, 5.0),      # 1.5 t = 1.5 mm < 2 mm
    (2.0, "laser", 3.0, 0.2, 5.0),      # 1.5 t = 3 mm
    (3.0, "waterjet", 4.5, 1.0, 5.0),   # waterjet kerf 1 mm
    (8.0, "laser", 12.0, 0.2, 6.1),     # gap 12.2 mm: the edge is at least half of it
])
def test_cut_spacing_known_answers(thickness, process, spacing, kerf, edge):
    cut = cut_spacing(thickness, process)
    assert (cut.spacing, cut.kerf, cut.edge) == pytest.approx((spacing, kerf, edge), abs=1e-12)
    assert cut.gap == pytest.approx(spacing + kerf, abs=1e-12)


def test_given_values_replace_the_rule_and_the_edge_follows_their_gap():
    cut = cut_spacing(1.0, "laser", spacing=10.0, kerf=0.2)
    assert (cut.spacing, cut.kerf, cut.edge) == pytest.approx((10.0, 0.2, 5.1))
    assert cut_spacing(1.0, "waterjet", edge=0.0).edge == 0.0


def test_the_default_options_are_the_rule_for_the_default_sheet():
    # a run without --material is costed as 1 mm 5052-H32, laser cut
    assert NestOptions() == NestOptions.for_cut(cut_spacing(1.0, "laser"))
    assert (NestOptions().gap, NestOptions().edge) == pytest.approx((2.2, 5.0))


def test_nesting_keeps_the_rule_distances():
    # 100 x 50 mm rectangles held along a 300 x 170 mm sheet, 2 mm sheet laser cut: gap 3.2 mm, edge 5 mm,
    # so 290 x 160 mm inside: 2 a row (203.2 mm; three need 306.4) and 3 rows (3 * 50 + 2 * 3.2 = 156.4 mm):
    # 6 a sheet (at the 10.2 mm gap and 10 mm edge before, 2 rows: 4 a sheet)
    opts = NestOptions.for_cut(cut_spacing(2.0, "laser"), sheet=(300.0, 170.0), grain="x", engine="rows")
    parts = [box(0, 0, 100, 50) for _ in range(7)]
    n = nest_parts(parts, opts)
    assert n.verify(parts) == []
    assert n.n_sheets == 2
    assert max(sum(p.sheet == s for p in n.placements) for s in range(n.n_sheets)) == 6


@pytest.mark.parametrize("kw, word", [(dict(process="plasma"), "plasma"), (dict(thickness=0.0), "thickness"),
                                      (dict(spacing=-1.0), "spacing"), (dict(kerf=-0.1), "kerf"),
                                      (dict(edge=-2.0), "edge")])
def test_bad_values_are_refused(kw, word):
    args = {"thickness": 1.0, "process": "laser", **kw}
    with pytest.raises(InputError, match=word):
        cut_spacing(args.pop("thickness"), args.pop("process"), **args)
