"""`fabkit unfold IN.obj -o FLAT.obj`: planar development with error metrics and cut files."""
from __future__ import annotations

import contextlib
import sys
from pathlib import Path

from fabkit.commands._common import add_common, progress, say, to_jsonable
from fabkit.commands._loading import add_units, load_panel_for

from fabkit.verdicts import DEFAULT_MAX_ERROR

HELP = """Unfold a panel into its flat pattern (paper §2.8, §3.3) and write cut files.

IN is .obj, .fold (its last fold state), .3dm or .svg, read by the one panel loader (units,
welding, winding, quads re-merged: docs/file-formats.md). FLAT.obj has IN's vertex order, faces
and face/vertex data, with z = 0 (metres); FLAT.fold is the crease pattern with IN as its folded
state (what `fabkit refold FLAT.fold` and `fabkit toolpath` read); FLAT.3dm a Rhino file. The isometric
method minimises the relative length deviation of every edge and face diagonal, starting from an
exact face-by-face layout; conformal (LSCM) and authalic developments are there for comparison.
The error metrics are the paper's: mean and max of |l2D - l3D| / l3D over edges and diagonals.

Cut files are in millimetres: layers CUT (outline), MOUNTAIN and VALLEY (score lines), SCORE
(creases whose sense is unknown: flat input) and LABEL. Creases are the edges between faces of
different face_data "strip" when IN has strip tags, else inferred from the geometry (edges where the
fold angle jumps against the bending beside them, along chains from boundary to boundary; see
'fabkit info'); --crease-angle replaces the inference by a bare dihedral threshold.

With --material and --thickness the flat pattern is the sheet's neutral surface: along every crease
it differs from the design surface's by the K-factor amount BA - 2 (R_i + d) tan(alpha/2), d = 0 for
a valley and t for a mountain when IN is the top face (--design-surface; docs/sheet.md); folds
tighter than the material's minimum radius are refused.

Exit codes: 0 ok; 1 a check failed (--max-error, default 1e-3, exceeded, flipped faces, a self-overlapping
outline or a solver that did not converge: files are still written and the report says which);
2 bad input (nothing written).

Example:
  fabkit generate reflect -o panel.obj
  fabkit unfold panel.obj -o flat.obj --dxf flat.dxf --svg flat.svg --png flat.png --max-error 1e-6
"""


def add_arguments(parser) -> None:
    parser.add_argument("input", metavar="IN", help="the folded (relaxed) panel: .obj, .fold, .3dm or .svg")
    parser.add_argument("-o", "--output", metavar="FLAT", required=True,
                        help="flat pattern (z = 0): .obj, .fold (with IN as its folded state) or .3dm")
    add_units(parser)
    parser.add_argument("--dxf", metavar="F.dxf", help="DXF cut file (millimetres)")
    parser.add_argument("--svg", metavar="F.svg", help="SVG cut file (millimetres)")
    parser.add_argument("--png", metavar="F.png", help="picture of the pattern coloured by length deviation")
    parser.add_argument("--method", choices=("isometric", "conformal", "authalic"), default="isometric",
                        help="development method (default: isometric)")
    parser.add_argument("--norm", type=float, default=2.0, metavar="P",
                        help="isometric only: minimise sum |relative deviation|^P; 2 (default) is the paper's "
                             "least-squares spring energy, P > 2 lowers the max deviation for a slightly larger mean")
    parser.add_argument("--max-error", type=float, metavar="E", default=DEFAULT_MAX_ERROR,
                        help="fail (exit 1) when the max relative edge/diagonal length deviation exceeds E "
                             f"(default {DEFAULT_MAX_ERROR:g})")
    parser.add_argument("--panel-id", metavar="ID", help="label written on the cut files (default: IN's name)")
    parser.add_argument("--crease-angle", type=float, default=None, metavar="DEG",
                        help="untagged panels: edges folded by more than DEG are creases (default: inferred)")
    parser.add_argument("--label-edges", action="store_true", help="write boundary edge ids on the LABEL layer")
    from fabkit.commands._sheet import add_sheet_arguments  # sheet hook: neutral-surface development

    add_sheet_arguments(parser)
    parser.add_argument("--design-surface", choices=("top", "mid", "bottom"), default="top",
                        help="with --material: which surface of the sheet IN is (top = the front face, +z of the "
                             "flat pattern, up on the cutting table; default top)")
    add_common(parser)


def plan_files(args, plan) -> None:
    plan.input(args.input, "IN")
    for option in ("output", "dxf", "svg", "png", "report"):
        plan.output(getattr(args, option), "-o" if option == "output" else f"--{option}")


def _check_args(args) -> None:
    from fabkit.errors import InputError
    from fabkit.verdicts import check_unfold_options

    check_unfold_options(args.method, args.norm, args.max_error, args.crease_angle)
    outputs = [p for p in (args.output, args.dxf, args.svg, args.png, args.report) if p]
    resolved = [Path(p).resolve() for p in outputs]
    if len(set(resolved)) != len(resolved):
        raise InputError("two outputs name the same file", source=", ".join(outputs))
    if Path(args.input).resolve() in resolved:
        raise InputError("an output would overwrite the input", source=args.input)
    for p in outputs:
        if not Path(p).parent.is_dir():
            raise InputError("output directory does not exist", source=p)
        if Path(p).is_dir():
            raise InputError("is a directory, not a file name", source=p)


def run(args) -> int:
    from fabkit.commands._common import write_json
    from fabkit.cutfiles import dxf_document, svg_text
    from fabkit.io.atomic import atomic_path
    from fabkit.pipeline import unfold
    from fabkit.results import Panel
    from fabkit.unfold.plot import plot_unfold_error

    _check_args(args)
    mesh, loaded = load_panel_for(args, args.input)
    with progress(args, f"unfolding ({args.method})", total=None):
        flat = unfold(Panel(mesh=mesh, name=str(args.input), loaded=loaded), method=args.method, norm=args.norm,
                      max_error=args.max_error, crease_angle=args.crease_angle, material=args.material,
                      thickness=args.thickness, crease=args.crease, ligament=args.ligament,
                      bend_radius=args.bend_radius, design_surface=args.design_surface)
    dev, assignment, problems = flat.development, flat.creases, list(flat.problems)
    panel_id = args.panel_id if args.panel_id is not None else Path(args.input).stem
    pattern = flat.cut_pattern(panel_id, label_edges=args.label_edges) if (args.dxf or args.svg) else None
    outputs = {"mesh": args.output, "dxf": args.dxf, "svg": args.svg, "png": args.png}
    report = {**flat.to_json(), "panel_id": panel_id, "outputs": {k: v for k, v in outputs.items() if v}}
    # Every output goes to a temporary file first; all are renamed only when all were written.
    with contextlib.ExitStack() as stack:
        tmp = {k: stack.enter_context(atomic_path(v)) for k, v in outputs.items() if v}
        flat.save(tmp["mesh"], f"flat pattern of {args.input} ({args.method}, metres, z = 0)")
        if args.dxf:
            dxf_document(pattern).saveas(tmp["dxf"])
        if args.svg:
            Path(tmp["svg"]).write_text(svg_text(pattern), encoding="utf-8")
        if args.png:
            plot_unfold_error(mesh, dev, tmp["png"], title=f"{panel_id}: {args.method} development")
        if args.report:
            report_tmp = stack.enter_context(atomic_path(args.report))
            write_json(report_tmp, to_jsonable(report))

    s = dev.summary()
    say(args, f"unfold {args.input}: {mesh.n_vertices} vertices, {args.method}: relative length deviation "
              f"mean {s['mean_relative_deviation']:.3g}, max {s['max_relative_deviation']:.3g} "
              f"(max {s['max_absolute_deviation_m'] * 1000:.3g} mm); {s['flipped_faces']} flipped faces; "
              f"outline {'overlaps itself' if s['outline_self_overlaps'] else 'simple'}; "
              f"creases M {assignment.counts()['M']} V {assignment.counts()['V']} U {assignment.counts()['U']}")
    say(args, "wrote " + ", ".join(v for v in [*outputs.values(), args.report] if v))
    for p in problems:
        print(f"fabkit unfold: FAILED: {p}", file=sys.stderr)
    return 1 if problems else 0
