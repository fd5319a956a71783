"""`fabkit panels`: the multi-panel workflow (paper §3) with automatic feedback and symmetry (§4)."""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from fabkit.commands._common import add_common, progress, say, write_report
from fabkit.errors import InputError

HELP = """Panelise a surface and make every panel fabricable: subdivide the low-poly (Catmull-Clark), extract
its planar arcs, lay out staggered panels between neighbouring arcs, relax each panel with the
four-panel corners (singularity points) fixed, unfold, measure shared-edge congruency, merge
incongruent edges into target lengths and unfold again until the tolerances hold (automatic
feedback) or --max-rounds is reached.

SURFACE.obj is a quad grid that is one rectangular patch. When its across direction has exactly 3
vertices it is the paper's low-poly and is subdivided --levels times; otherwise it is used as the
high-resolution grid. `fabkit generate canopy -o canopy.obj` writes the preset wave-like canopy.

Writes DIR/panels/<name>.{obj,_flat.obj,fold,dxf,svg}, DIR/band_layout.json, plots and
DIR/report.json. Exit 1 when a panel or a shared edge misses its tolerance (the report says which
and why).

A surface with creases (`fabkit generate pleated`) gets one band per crease, the crease inside its
panels (their middle column of faces crosses it); --rows may then be left out.

Production run (--cell CELL.toml): every panel is also refolded (§3.6, middle-row creases driven),
programmed (robot toolpath) and checked in the MuJoCo cell; the flat patterns are nested on stock
sheets (--sheet) and written as one DXF/SVG per sheet, and DIR/book.html shows it all. Per-panel
status (ok, or the stage and the reason) goes to DIR/manifest.json and DIR/production.json; a rerun
recomputes only panels whose inputs or options changed (content hashes). --scheduler ADDR runs the
per-panel work on a dask.distributed cluster (docs/production.md).

example:
  fabkit generate canopy -o canopy.obj
  fabkit panels canopy.obj -o canopy-panels --rows 14 --cols 7 --jobs 2
  fabkit generate pleated -o pleated.obj
  fabkit panels pleated.obj -o pleated-run --cols 7 --cell cells/ur5e_bench.toml --material 5052-H32 --thickness 1mm
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("surface", metavar="SURFACE.obj", help="quad-grid surface (low-poly with 3 vertices across, or "
                                                       "high-res): .obj, .3dm or .fold")
    from fabkit.commands._loading import add_units

    add_units(p)
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--rows", type=int, default=None,
                   help="bands between arcs, an even number (default 14; a creased surface: one per crease)")
    p.add_argument("--cols", type=int, default=7, help="panels per aligned band (default 7)")
    p.add_argument("--columns-per-panel", type=int, default=6, help="mesh columns per panel, even (default 6)")
    p.add_argument("--levels", type=int, default=4, help="Catmull-Clark levels for a low-poly input (default 4)")
    p.add_argument("--tolerance", type=float, default=1e-4, help="max shared-edge incongruency, relative (default 1e-4)")
    p.add_argument("--unfold-tolerance", type=float, default=1e-3,
                   help="max unfold deviation per panel, relative (default 1e-3)")
    p.add_argument("--max-rounds", type=int, default=12, help="feedback rounds after the first unfold (default 12)")
    p.add_argument("--symmetric", action="store_true", help="solve half (x < 0) and mirror: exactly symmetric result")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                   help="worker processes (default: one per CPU; 1 runs in-process)")
    p.add_argument("--scheduler", metavar="ADDR", help="dask.distributed scheduler address (instead of --jobs)")
    p.add_argument("--free-shared-edges", action="store_true",
                   help="relax panels without keeping their shared boundary edges at the surface's lengths "
                        "(the paper's original scheme: neighbours then disagree and the merge absorbs it)")
    p.add_argument("--no-cut-files", action="store_true", help="skip the DXF/SVG cut files")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    g = p.add_argument_group("production run")
    g.add_argument("--cell", metavar="CELL.toml", help="robot cell: refold, program and check every panel")
    g.add_argument("--frames", type=int, default=8, help="refold states per panel, flat and folded included (default 8)")
    g.add_argument("--overrides", metavar="FILE.json", help='per-panel options, e.g. {"P003_b00_03": {"frames": 12}}')
    g.add_argument("--each-panel", action="store_true",
                   help="refold, program and check every panel, also panels that are the same part as another "
                        "(default: once per part, within 0.1 um; docs/production.md)")
    g.add_argument("--sheet", default="2500x1250", metavar="WxH", help="stock sheet size in mm (default 2500x1250)")
    g.add_argument("--cut", choices=("laser", "waterjet"), default="laser",
                   help="cutting process the sheets are nested for (default laser): its kerf and the spacing rule")
    g.add_argument("--spacing", type=float, default=None,
                   help="web between neighbouring parts' kerfs, mm (default: max(2, 1.5 x sheet thickness), "
                        "fabricators' rule, docs/production.md)")
    g.add_argument("--kerf", type=float, default=None,
                   help="cutting kerf in mm, added to the spacing (default: laser 0.2, waterjet 1.0)")
    g.add_argument("--edge-margin", type=float, default=None,
                   help="part outlines to the sheet edge, mm (default: 5, at least half the gap between parts)")
    g.add_argument("--grain", choices=("none", "x", "y"), default="none",
                   help="keep each panel's arcs along the sheet's grain direction (default: any rotation)")
    g.add_argument("--nester", choices=("rows", "packingsolver", "shelf"), default="rows",
                   help="nesting engine (default rows: parts turned to their least shelf cell, slid together on shelves; "
                        "packingsolver: sparrow; shelf: bounding-box shelf packing)")
    g.add_argument("--nest-seconds", type=float, default=30.0, help="time limit of the nesting solver (default 30)")
    from fabkit.commands._sheet import add_sheet_arguments

    add_sheet_arguments(p, tool_mass=True, material_help=(
        "production run: every program springback-compensated and its fold loads checked for this sheet, as "
        "`fabkit toolpath/check --material` (a name from `fabkit materials` or a .toml; with --thickness). "
        "Without it the programs fold the design angles and the sheets are costed as 1 mm 5052-H32"))
    add_common(p)


#: most faces of the subdivided surface (memory of the panel layout grows with it)
MAX_SURFACE_FACES = 2_000_000


def plan_files(args, plan) -> None:
    plan.input(args.surface, "SURFACE")
    plan.folder(args.out, "-o")
    plan.output(args.report, "--report")


def load_surface(path: str, levels: int, units: str | None = None):
    """A GridSurface from a quad grid (subdivided when it is a 3-vertex-across low-poly), read by the
    panel loader (`fabkit.io.load`: units, welding, winding, split quads merged back)."""
    import sys

    import numpy as np

    from fabkit.io.load import load_panel
    from fabkit.panels.surface import GridSurface, grid_from_topology, subdivide_grid

    mesh, info = load_panel(path, units)
    for note in info.notes:
        print(f"fabkit panels: note: {path}: {note}", file=sys.stderr)
    try:
        index, lowpoly = grid_from_topology(mesh)
    except InputError as exc:
        raise exc.with_source(path)
    if lowpoly:
        nu, nv = index.shape
        grid = np.zeros((mesh.n_vertices, 2))
        grid[index.ravel()] = np.stack(np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij"), axis=-1).reshape(-1, 2)
        if levels < 1:
            raise InputError("a 3-vertex-across low-poly needs --levels >= 1", source=path)
        if mesh.n_faces * 4 ** levels > MAX_SURFACE_FACES:
            raise InputError(f"--levels {levels} would make {mesh.n_faces * 4 ** levels:,} faces, more than the "
                             f"{MAX_SURFACE_FACES:,} this command handles; lower --levels", source=path)
        return subdivide_grid(mesh.with_data(vertex_data={"grid": grid}), levels), True
    return GridSurface(points=mesh.vertices[index], mesh=mesh, index=index), False


def run(args) -> int:
    from fabkit.panels.layout import layout_panels
    from fabkit.panels.output import write_run
    from fabkit.panels.workflow import PanelsOptions, run_panels

    if not Path(args.surface).is_file():
        raise InputError("no such file", source=args.surface)
    if args.jobs < 1:
        raise InputError(f"--jobs must be >= 1, got {args.jobs}")
    if not (args.tolerance > 0 and args.unfold_tolerance > 0):
        raise InputError("tolerances must be positive")
    if args.max_rounds < 0:
        raise InputError(f"--max-rounds must be >= 0, got {args.max_rounds}")
    if not 0 <= args.levels <= 10:
        raise InputError(f"--levels must be in 0..10, got {args.levels}")
    if args.scheduler:
        from fabkit.panels.executor import check_scheduler

        check_scheduler(args.scheduler)
    surface, lowpoly = load_surface(args.surface, args.levels, args.units)
    layout = layout_panels(surface, rows=args.rows, cols=args.cols, columns_per_panel=args.columns_per_panel)
    if args.cell:
        from fabkit.commands.produce import run_production_command

        return run_production_command(args, surface, lowpoly, layout)
    options = PanelsOptions(tol_congruency=args.tolerance, tol_unfold=args.unfold_tolerance,
                            max_rounds=args.max_rounds, symmetric=args.symmetric,
                            keep_shared_edges=not args.free_shared_edges)
    n_tasks = len(layout.panels) // (2 if args.symmetric else 1)
    with progress(args, "panels", total=n_tasks * (1 + args.max_rounds)) as advance:
        result = run_panels(layout, options, jobs=args.jobs, scheduler=args.scheduler, progress=advance)
    from fabkit.io.atomic import staging_path

    report = write_run(result, staging_path(args.out), plots=not args.no_plots, cut_files=not args.no_cut_files,
                       jobs=args.jobs, scheduler=args.scheduler)
    report["input"] = {"surface": args.surface, "lowpoly": lowpoly, "levels": args.levels if lowpoly else 0}
    write_report(args, report)
    last = result.rounds[-1]
    say(args, f"{len(layout.panels)} panels in {len(layout.arcs) - 1} bands, {len(layout.singular_keys)} "
              f"singularity points ({layout.singularity_ratio:.3f} per panel; paper: 1/2)")
    say(args, f"relax converged {report['relax_converged']}/{len(layout.panels)}; after {last['round']} feedback "
              f"rounds: max incongruency {last['max_incongruency']:.3g} (tol {args.tolerance:g}), max unfold "
              f"deviation {last['max_unfold_deviation']:.3g} (tol {args.unfold_tolerance:g})")
    failing = result.failing_panels()
    if failing:
        say(args, f"{len(failing)} panels miss a tolerance, e.g. {layout.panels[failing[0][0]].name}: {failing[0][1]}")
        return 1
    say(args, f"all panels within tolerance -> {args.out}")
    return 0
