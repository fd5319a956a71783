"""Nesting the 494-panel pleated vault's flat patterns on 2500 x 1250 mm sheets, every engine.

The flat patterns come from the production run's geometry path (layout, relax, unfold,
congruency: `fabkit.panels.workflow.run_panels` on 2 workers, ~10-15 s), built once per run; the
relax/unfold results are cached in a temporary folder (`fabkit.panels.cache.ResultCache`) and
the part outlines written there as JSON, which every engine then nests. So nesting is measured
without the ~30-minute refold/program/check of `python -m bench production`.

Utilisation = total panel (flat pattern) area / area of the sheets used, every sheet counted whole
(`Nesting.utilisation`, the strict number; target >= 75 %), and also with the last sheet counted
only up to its used length (`Nesting.used_length_utilisation`, the rest an offcut). The baseline in
the same run is the bounding-rectangle shelf packing (`shelf`); every nesting is verified with
shapely (each part once, inside the margin, no two parts closer than spacing + kerf).

Every engine runs twice: at the default distances (`fabkit.nest.spacing.cut_spacing` for the 1 mm
sheet the bench vault is costed as, laser cut: the fabricators' rules in docs/production.md) and at
the 10 mm spacing and edge used before, so the effect of the distances is never read as the engine's.

Bounds printed with it (not nestings): the sheets the parts would need at 100 %, the sheets their
outlines grown by half the gap need (no nesting can use fewer), the sheets of the ideal shelf
cells (each part, at the turn row nesting gives it, in an endless shelf of its own copies: its
slid pitch times its height plus the gap), and those cells plus the ends of the rows: a row of
sheared parts is longer than its pitches by the part's width less its pitch (the two triangles at
its ends, one part's shear), shared here by the copies that fill a sheet's length. That last is an
estimate of what any nesting in rows needs, not a proof. "sheets by length" is the sheets used, the
last counted by its used length.

The row nesting's time is also split: its first shelf packing (`rows._pack` as `nest_rows` calls it,
the baseline in the same run) and its hole filling (`fill.fill_holes`), each wall and CPU seconds of this process (the machine
is shared, so CPU time is the steadier number), and the filling's ratio to the packing.

FABKIT_BENCH_NEST_SECONDS sets sparrow's time limit per strip solve (default 10, as in the production
bench); FABKIT_BENCH_NEST_SPARROW=0 leaves sparrow out (while trying things; the reported numbers
include it). FABKIT_BENCH_NEST_PARTS=FILE keeps the part outlines (JSON) in FILE between runs.
"""
from __future__ import annotations

import json
import math
import os
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from bench.common import report

SHEET = (2500.0, 1250.0)


def _build_parts(folder: Path) -> list[list[list[float]]]:
    from fabkit.generate.pleated import pleated_vault
    from fabkit.nest import panel_parts
    from fabkit.panels.cache import ResultCache
    from fabkit.panels.layout import layout_panels
    from fabkit.panels.surface import GridSurface, grid_from_topology
    from fabkit.panels.workflow import PanelsOptions, run_panels

    mesh = pleated_vault(rows=30, columns=96)  # as bench/bench_production.py
    index, _ = grid_from_topology(mesh)
    layout = layout_panels(GridSurface(points=mesh.vertices[index], mesh=mesh, index=index), cols=16,
                           columns_per_panel=6)
    run = run_panels(layout, PanelsOptions(), jobs=2, cache=ResultCache(folder / "geometry", salt="bench-nesting"))
    parts, _ = panel_parts(run)
    return [np.asarray(g.exterior.coords).tolist() for g in parts]


def _bounds(parts, gap: float, edge: float) -> dict:
    from shapely import affinity

    from fabkit.nest.rows import ideal_shelf_cell, least_cell_angle

    W, H = SHEET
    area = sum(g.area for g in parts)
    grown = sum(g.buffer(gap / 2).area for g in parts)
    # grown by gap/2, they may reach gap/2 into the margin
    usable_grown = (W - 2 * (edge - gap / 2)) * (H - 2 * (edge - gap / 2))
    room = (W - 2 * edge, H - 2 * edge)
    cells = ends = 0.0
    for g in parts:
        a = least_cell_angle(g, gap, None, room)
        c = ideal_shelf_cell(g, gap, a)
        x0, y0, x1, y1 = affinity.rotate(g, a, origin=(0.0, 0.0)).bounds
        pitch = c / (y1 - y0 + gap)
        per_row = max(1, math.floor((room[0] + gap - (x1 - x0)) / pitch) + 1)
        cells += c
        ends += (x1 - x0 - pitch + gap) * (y1 - y0 + gap) / per_row
    cell_sheet = room[0] * (room[1] + gap)
    return {"sheets at 100 %": area / (W * H), "sheets of the outlines grown by gap/2 (lower bound)":
            grown / usable_grown, "sheets of ideal shelf cells": cells / cell_sheet,
            "sheets of ideal shelf cells and row ends (estimate for rows)": (cells + ends) / cell_sheet,
            "sheets for 75 %": area / (0.75 * W * H)}


@contextmanager
def _timed(module, name: str, spent: dict):
    """`module.name` timed while inside: spent[name] = [wall s, CPU s] summed over its calls."""
    fn = getattr(module, name)
    spent[name] = [0.0, 0.0]

    def timed(*args, **kw):
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            return fn(*args, **kw)
        finally:
            spent[name][0] += time.perf_counter() - t0
            spent[name][1] += time.process_time() - c0

    setattr(module, name, timed)
    try:
        yield spent
    finally:
        setattr(module, name, fn)


def _settings():
    """(label, NestOptions keywords): the default distances (1 mm sheet, laser cut, sourced:
    `fabkit.nest.spacing`) and the 10 mm spacing and edge used before, so neither is read alone."""
    from fabkit.nest.spacing import cut_spacing

    cut = cut_spacing(1.0, "laser")
    return [(f"default (1 mm laser: spacing {cut.spacing:g} + kerf {cut.kerf:g} mm, edge {cut.edge:g} mm)",
             dict(spacing=cut.spacing, kerf=cut.kerf, edge=cut.edge)),
            ("10 mm spacing + kerf 0.2 mm, edge 10 mm", dict(spacing=10.0, kerf=0.2, edge=10.0))]


def main() -> dict:
    from shapely.geometry import Polygon

    from fabkit.nest import NestOptions, nest_parts
    from fabkit.nest import fill as fill_module
    from fabkit.nest import last_sheet  # noqa: F401  (imported before `_timed`: it keeps its own `_pack`)
    from fabkit.nest import rows as rows_module
    from fabkit.nest.engines import place

    limit = float(os.environ.get("FABKIT_BENCH_NEST_SECONDS", 10))
    keep = os.environ.get("FABKIT_BENCH_NEST_PARTS")
    rows = []
    with tempfile.TemporaryDirectory(prefix="fabkit-bench-nesting-") as tmp:
        path = Path(keep) if keep else Path(tmp) / "parts.json"
        t0 = time.perf_counter()
        if not path.is_file():
            path.write_text(json.dumps(_build_parts(Path(tmp))))
        t_geometry = time.perf_counter() - t0
        parts = [Polygon(p) for p in json.loads(path.read_text())]
    engines = ("shelf", "rows") if os.environ.get("FABKIT_BENCH_NEST_SPARROW") == "0" else ("shelf", "rows", "packingsolver")
    extra = {}
    for label, dist in _settings():
        nests = {}
        for engine in engines:
            opts = NestOptions(sheet=SHEET, engine=engine, time_limit=limit, **dist)
            spent: dict = {}
            c0 = time.process_time()
            with _timed(rows_module, "_pack", spent), _timed(fill_module, "fill_holes", spent):
                nests[engine] = n = nest_parts(parts, opts)
            cpu = time.process_time() - c0
            again = nest_parts(parts, opts) if engine != "packingsolver" else None
            rows.append({"case": f"nesting {engine}" + (f" ({limit:g} s per strip solve)" if engine == "packingsolver" else ""),
                         "distances": label, "parts": len(parts), "sheets": n.n_sheets, "seconds": n.seconds,
                         "CPU s (this process)": cpu,
                         "utilisation (whole sheets)": n.utilisation,
                         "utilisation (last sheet by length)": n.used_length_utilisation(parts),
                         "sheets by length": n.n_sheets - 1 + min(1.0, (max(place(parts[p.part], p).bounds[2] for p in
                                                                      n.placements if p.sheet == n.n_sheets - 1)
                                                                  + opts.edge) / SHEET[0]),
                         "ratio to shelf (whole sheets)": n.utilisation / nests["shelf"].utilisation,
                         "verified (each once, inside, gap)": not n.verify(parts),
                         "same placements on a rerun": "not deterministic (time-limited)" if again is None
                         else again.placements == n.placements, "target": 0.75})
            if engine == "rows":
                (pack_s, pack_cpu), (fill_s, fill_cpu) = spent["_pack"], spent["fill_holes"]
                rows[-1].update({"shelf packing s": pack_s, "shelf packing CPU s": pack_cpu, "hole filling s": fill_s,
                                 "hole filling CPU s": fill_cpu, "hole filling / shelf packing (CPU)": fill_cpu / pack_cpu})
        gap = dist["spacing"] + dist["kerf"]
        bounds = _bounds(parts, gap, dist["edge"])
        print(f"   {label}, gap {gap:g} mm:")
        for k, v in bounds.items():
            print(f"     {k}: {v:.2f}")
        extra[label] = {"gap mm": gap, "edge mm": dist["edge"], **bounds}
    print("   " + "; ".join(f"{r['case']} [{r['distances'].split(' (')[0].split(' +')[0]}]: {r['seconds']:.1f} s, "
                            f"{r['sheets by length']:.2f} sheets by length" for r in rows))
    return report("nesting", rows, {"panels": len(parts), "sheet mm": list(SHEET), "geometry s": t_geometry,
                                    "bounds": extra})


if __name__ == "__main__":
    main()
