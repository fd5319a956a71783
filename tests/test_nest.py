"""Nesting on stock sheets (row nesting, sparrow and the shelf baseline) and the per-sheet cut files."""
from __future__ import annotations

import math

import ezdxf
import numpy as np
import pytest
from shapely.geometry import LineString, Point, Polygon, box

from fabkit.errors import InputError
from fabkit.nest import NestOptions, nest_parts
from fabkit.nest.engines import place
from nest_shapes import bowed_parts


def _parts(n=24, seed=0):
    return bowed_parts(n, seed, width=(150, 420), height=(100, 300), skew=(-60, 60), bow=(0, 30), top_points=7)


def _independent_check(parts, nesting, sheet, gap, margin):
    """Every part exactly once, inside its sheet's margin, no two closer than the gap (shapely only)."""
    assert sorted(p.part for p in nesting.placements) == list(range(len(parts)))
    inner = box(margin - 1e-6, margin - 1e-6, sheet[0] - margin + 1e-6, sheet[1] - margin + 1e-6)
    placed = {}
    for p in nesting.placements:
        g = place(parts[p.part], p)
        assert inner.contains(g), p
        assert g.area == pytest.approx(parts[p.part].area, rel=1e-9)  # moved rigidly, not mirrored or scaled
        placed.setdefault(p.sheet, []).append(g)
    assert sorted(placed) == list(range(nesting.n_sheets))
    for geoms in placed.values():
        for i, a in enumerate(geoms):
            for b in geoms[i + 1:]:
                assert a.distance(b) >= gap - 1e-6


@pytest.mark.parametrize("engine", ["shelf", "rows", "packingsolver"])
def test_nesting_places_every_part_once_without_overlap(engine):
    parts = _parts()
    opts = NestOptions(sheet=(1500.0, 800.0), spacing=8.0, kerf=0.5, engine=engine, time_limit=3)
    n = nest_parts(parts, opts)
    assert n.verify(parts) == []
    _independent_check(parts, n, opts.sheet, opts.gap, opts.edge)
    assert 0 < n.utilisation <= n.used_length_utilisation(parts) <= 1


def test_grain_keeps_parts_along_the_sheet():
    parts = _parts(10, seed=1)
    for grain, allowed in (("x", {0.0, 180.0}), ("y", {90.0, 270.0})):
        n = nest_parts(parts, NestOptions(sheet=(1500.0, 800.0), grain=grain, engine="packingsolver", time_limit=2))
        assert {round(p.angle % 360, 6) for p in n.placements} <= allowed
        assert n.verify(parts) == []
        for engine in ("shelf", "rows"):
            s = nest_parts(parts, NestOptions(sheet=(1500.0, 800.0), grain=grain, engine=engine))
            assert {round(p.angle % 360, 6) % 360 for p in s.placements} <= allowed and s.verify(parts) == []


def test_rows_nest_sheared_parts_into_each_other():
    """60 parallelograms (base 200, height 100, sheared by 150 mm, turned at random), gap 5 mm: slid
    against each other, 8 fit a 1990 mm row (9 rows): one sheet; their bounding rectangles (350 x 100)
    take 5 a row on the shelf baseline: two sheets."""
    rng = np.random.default_rng(4)
    base = Polygon([(0, 0), (200, 0), (350, 100), (150, 100)])
    from shapely import affinity

    parts = [affinity.rotate(base, float(a), origin=(0, 0)) for a in rng.uniform(0, 360, 60)]
    opts = dict(sheet=(2000.0, 1000.0), spacing=5.0, kerf=0.0)
    rows = nest_parts(parts, NestOptions(engine="rows", **opts))
    shelf = nest_parts(parts, NestOptions(engine="shelf", **opts))
    _independent_check(parts, rows, (2000.0, 1000.0), 5.0, 5.0)
    assert rows.n_sheets == 1 and shelf.n_sheets == 2
    assert rows.utilisation == pytest.approx(60 * 20000 / 2e6)


def _curved_strips(n=40, seed=7):
    """Bands between two concentric arcs (a developed curved strip), 300-900 mm long, 60-150 mm wide,
    bent to radii 0.8-3 m, tapered by up to 30 %."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        length, width, radius = rng.uniform(300, 900), rng.uniform(60, 150), rng.uniform(800, 3000)
        taper = rng.uniform(0.7, 1.0)
        t = np.linspace(-0.5, 0.5, 13) * length / radius
        w = width * np.linspace(1.0, taper, 13)
        inner = np.column_stack([radius * np.sin(t), radius * np.cos(t)])
        outer = np.column_stack([(radius + w) * np.sin(t), (radius + w) * np.cos(t)])
        out.append(Polygon(np.vstack([inner, outer[::-1]])))
    return out


def test_rows_beat_the_shelf_baseline_on_curved_strips():
    """Curved, tapered strips: rows nesting needs no more sheets than the bounding-rectangle shelves
    and uses a quarter less sheet length (measured: 55.7 % against 43.3 % of the length used), places
    each strip once without overlap, gives the same placements again, and leaves the last sheet's
    offcut at its right end."""
    parts = _curved_strips()
    opts = dict(sheet=(2000.0, 1000.0), spacing=5.0, kerf=0.2)
    rows = nest_parts(parts, NestOptions(engine="rows", **opts))
    shelf = nest_parts(parts, NestOptions(engine="shelf", **opts))
    _independent_check(parts, rows, opts["sheet"], 5.2, 5.0)
    assert rows.n_sheets <= shelf.n_sheets
    assert rows.used_length_utilisation(parts) > 1.2 * shelf.used_length_utilisation(parts)
    assert nest_parts(parts, NestOptions(engine="rows", **opts)).placements == rows.placements
    assert rows.used_length_utilisation(parts) > rows.utilisation  # the last sheet is not used to its end


def test_rows_last_sheet_nested_across_keeps_grain():
    """A few parts on one long sheet: nested across from the left end (shorter used length than one
    shelf along the sheet), with the grain still along the sheet's y."""
    parts = _parts(12, seed=3)
    for grain, allowed in (("none", None), ("y", {90.0, 270.0})):
        n = nest_parts(parts, NestOptions(sheet=(3000.0, 1000.0), spacing=5.0, grain=grain, engine="rows"))
        _independent_check(parts, n, (3000.0, 1000.0), 5.2, 5.0)
        assert any("nested across" in note for note in n.notes)
        if allowed:
            assert {round(p.angle % 360, 6) for p in n.placements} <= allowed
    long = [box(0, 0, 1400, 100), box(0, 0, 300, 200)]  # 1400 mm fits only along the sheet: kept so
    n = nest_parts(long, NestOptions(engine="rows"))
    assert n.verify(long) == [] and not any("nested across" in note for note in n.notes)


def test_verify_catches_overlap_and_refusals():
    parts = [box(0, 0, 100, 100), box(0, 0, 100, 100)]
    n = nest_parts(parts, NestOptions(engine="shelf"))
    from dataclasses import replace

    bad = replace(n, placements=(n.placements[0], replace(n.placements[1], x=n.placements[0].x + 50,
                                                          y=n.placements[0].y)))
    assert any("apart" in p for p in bad.verify(parts))
    with pytest.raises(InputError, match="does not fit"):
        nest_parts([box(0, 0, 3000, 100)], NestOptions())
    with pytest.raises(InputError, match="not a valid polygon"):
        nest_parts([Polygon([(0, 0), (1, 1), (1, 0), (0, 1)])], NestOptions())


@pytest.fixture(scope="module")
def sheets(tmp_path_factory):
    from fabkit.generate.pleated import pleated_vault
    from fabkit.nest import nest_panels, write_sheets
    from fabkit.panels.layout import layout_panels
    from fabkit.panels.production import stock
    from fabkit.panels.surface import GridSurface, grid_from_topology
    from fabkit.panels.workflow import PanelsOptions, run_panels

    mesh = pleated_vault(rows=4, length=1.0, radius=0.6, arc=math.radians(60), columns=16, rows_per_band=8)
    index, _ = grid_from_topology(mesh)
    layout = layout_panels(GridSurface(points=mesh.vertices[index], mesh=mesh, index=index), cols=2,
                           columns_per_panel=8)
    run = run_panels(layout, PanelsOptions())
    nest = nest_panels(run, NestOptions(sheet=(1250.0, 1000.0), engine="packingsolver", time_limit=3))
    out = tmp_path_factory.mktemp("sheets")
    mat = stock("5052-H32", 1.5e-3)
    info = write_sheets(run, nest, out / "sheets", mat)
    return run, nest, out, info, mat


def test_sheet_dxf_has_layers_labels_reliefs_and_spline_creases(sheets):
    from fabkit.nest.sheets import spline_allowance

    run, nest, out, info, mat = sheets
    layout = run.layout
    names = {p.name for p in layout.panels}
    on_sheets = []
    for s in info:
        doc = ezdxf.readfile(out / s["dxf"])
        assert doc.header["$INSUNITS"] == 4
        msp = doc.modelspace()
        texts = [e.dxf.text for e in msp.query("TEXT[layer=='LABEL']")]
        on_sheets += s["panels"]
        for name in s["panels"]:
            assert name in texts
        # neighbours' ids on the shared sides: every neighbour of a panel on this sheet is named on it
        for pa, _, pb, _ in layout.shared_edges:
            for me, other in ((pa, pb), (pb, pa)):
                if layout.panels[me].name in s["panels"]:
                    assert layout.panels[other].name in texts
        splines = msp.query("SPLINE")
        assert {e.dxf.layer for e in splines} <= {"MOUNTAIN", "VALLEY"} and len(splines) == len(s["panels"])
        grooves = msp.query("LWPOLYLINE[layer=='GROOVE_TOP' | layer=='GROOVE_BOTTOM']")
        assert len(grooves) == len(splines)
        for sp, gr in zip(splines, grooves):  # read back: the spline stays within tolerance of the crease
            curve = np.array([tuple(p)[:2] for p in sp.construction_tool().approximate(400)])
            poly = np.array([tuple(p)[:2] for p in gr.get_points()])
            assert LineString(curve).hausdorff_distance(LineString(poly)) <= spline_allowance(poly)
            curve_line = LineString(np.array([tuple(p)[:2] for p in sp.construction_tool().approximate(4000)]))
            assert max(curve_line.distance(Point(*v)) for v in poly) < 0.01  # through every crease vertex
        circles = msp.query("CIRCLE[layer=='RELIEF']")
        assert len(circles) == 2 * len(s["panels"])  # each crease meets the outline at both ends
        cut = [Polygon([tuple(p[:2]) for p in e.get_points()]) for e in msp.query("LWPOLYLINE[layer=='CUT']")]
        for c in circles:
            assert 2 * c.dxf.radius >= 0.5 * mat.thickness * 1000  # width >= t/2
            centre = Point(c.dxf.center[0], c.dxf.center[1])
            assert min(o.exterior.distance(centre) for o in cut) < 1e-6  # on the outline: a notch
        assert {"GROOVE_TOP", "GROOVE_BOTTOM"} & {e.dxf.layer for e in grooves}
        assert "depth" in doc.layers.get("GROOVE_TOP").description
    assert sorted(on_sheets) == sorted(names)
    # mountains and valleys both appear over the run (the vault alternates)
    layers = set()
    for s in info:
        layers |= {e.dxf.layer for e in ezdxf.readfile(out / s["dxf"]).modelspace().query("SPLINE")}
    assert layers == {"MOUNTAIN", "VALLEY"}


def test_sheet_svg_matches_dxf(sheets):
    import xml.etree.ElementTree as ET

    run, nest, out, info, mat = sheets
    ns = {"s": "http://www.w3.org/2000/svg"}
    for s in info:
        root = ET.parse(out / s["svg"]).getroot()
        assert root.get("width") == "1250mm"
        cut = root.find("s:g[@id='CUT']", ns)
        assert len(cut.findall("s:polygon", ns)) == len(s["panels"])
        labels = [t.text for t in root.find("s:g[@id='LABEL']", ns).findall("s:text", ns)]
        assert set(s["panels"]) <= set(labels)


def test_a_nesting_that_fails_its_verification_is_refused(monkeypatch):
    """An engine's result is verified before anything uses it: two parts on one spot is an error."""
    from fabkit.errors import ToleranceError
    from fabkit.nest import engines

    parts = [box(0, 0, 100, 50), box(0, 0, 80, 40)]
    fine = engines.nest_parts(parts, engines.NestOptions(engine="shelf"))
    assert fine.verify(parts) == []
    same_spot = [engines.Placement(part=i, sheet=0, angle=0.0, x=20.0, y=20.0) for i in range(2)]
    monkeypatch.setattr(engines, "_shelf", lambda parts, options: (same_spot, 1))
    with pytest.raises(ToleranceError, match=r"shelf nesting fails its verification .*parts 0 and 1 on sheet 0"):
        engines.nest_parts(parts, engines.NestOptions(engine="shelf"))
