"""`fabkit relax IN.obj -o OUT.obj`: dynamic relaxation toward zero angle defect and planar faces."""
from __future__ import annotations

import argparse
import dataclasses

from fabkit.commands._common import add_common, progress, say, write_report
from fabkit.commands._loading import add_units, load_panel_for
from fabkit.errors import InputError

from fabkit.verdicts import DEFAULT_MAX_MOVE

HELP = """Relax a quad mesh toward a developable, planar-quad panel (paper §2.2-2.7): zero angle defect
(2π − Σθ) at every interior vertex and every face vertex on its face's best-fit plane.

Dynamic relaxation with kinetic damping does the bulk of the work; a damped minimum-norm
Gauss–Newton finish takes the panel to round-off. Crease fairing (on by default, --crease-fairness 0
turns it off) picks, among the panels that meet the tolerances, the one closest to IN with the
smoothest crease curves, so input noise does not end up in the fold angles. An input already within
tolerance is left as it is. OUT has IN's vertex order, faces and data.

IN is read by the one panel loader (docs/file-formats.md): its unit (or --units), coincident
vertices welded, faces wound consistently, triangle pairs of split quads merged back; each of these
is said in a note. A relax that moves a vertex more than --max-move of the panel size has made a
different shape and fails.

Exit codes: 0 converged; 1 did not converge or moved the panel more than --max-move (the measures
reached are printed and reported; OUT is not written unless --write-unconverged); 2 bad input (non-manifold, NaN, a single face, no interior
vertex) or bad options.

examples:
  fabkit relax panel.obj -o relaxed.obj --report relax.json
  fabkit relax panel.obj -o relaxed.obj --boundary row-in-plane --tol-defect 1e-6
  fabkit relax panel.obj -o relaxed.obj --method newton --closeness 1 --fixed 0,12
  fabkit relax panel.obj -o relaxed.obj --crease-fairness 0   # no crease fairing
"""


def _ids(text: str) -> list[int]:
    try:
        return [int(t) for t in text.replace(" ", "").split(",") if t]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated vertex ids, got {text!r}") from None


def add_arguments(p: argparse.ArgumentParser) -> None:
    from fabkit.relax.options import BOUNDARIES, METHODS, RelaxOptions

    d = RelaxOptions()
    p.add_argument("input", metavar="IN", help="input mesh: .obj, .fold (its last fold state), .3dm or .svg")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="relaxed mesh: .obj (metres, tags kept), .fold or .3dm")
    add_units(p)
    p.add_argument("--max-move", type=float, default=DEFAULT_MAX_MOVE, metavar="SHARE",
                   help=f"fail (exit 1) when a vertex moved more than this share of the panel size "
                        f"(bounding-box diagonal; default {DEFAULT_MAX_MOVE:g}): the result would be another "
                        "shape, not the input made developable")
    p.add_argument("--method", choices=METHODS, default=d.method,
                   help="dr: dynamic relaxation + Gauss-Newton finish (default); newton: Gauss-Newton "
                        "only; lbfgs: scipy L-BFGS + finish")
    p.add_argument("--tol-defect", type=float, default=d.tol_defect, metavar="RAD",
                   help=f"max |angle defect| at interior vertices [rad] (default {d.tol_defect:g})")
    p.add_argument("--tol-planarity", type=float, default=d.tol_planarity, metavar="REL",
                   help=f"max plane distance / mean face edge (default {d.tol_planarity:g})")
    p.add_argument("--tol-force", type=float, default=d.tol_force, metavar="REL",
                   help=f"max residual force |grad E| * mean edge (default {d.tol_force:g})")
    p.add_argument("--max-iter", type=int, default=d.max_iter, help=f"DR / L-BFGS iterations (default {d.max_iter})")
    p.add_argument("--newton-max-iter", type=int, default=d.newton_max_iter,
                   help=f"Gauss-Newton steps (default {d.newton_max_iter})")
    p.add_argument("--boundary", choices=BOUNDARIES, default=d.boundary,
                   help="free (default): boundary vertices move under planarity and their interior "
                        "neighbours' developability; fixed; row-*: an extra fixed row of faces (Fig. 9)")
    p.add_argument("--row-width", type=float, default=d.row_width,
                   help="width of the extra boundary row in mean boundary edges (default 1)")
    p.add_argument("--fixed", type=_ids, default=[], metavar="I,J,..",
                   help="vertex ids held fixed (vertex_data 'fixed' in the OBJ is honoured too)")
    p.add_argument("--stage", action="store_true", help="developability first, then planarity (§2.7)")
    p.add_argument("--stage-defect", type=float, default=d.stage_defect,
                   help=f"stage-1 threshold on max |defect| (default {d.stage_defect:g})")
    p.add_argument("--closeness", type=float, default=d.closeness,
                   help="weight pulling toward the input positions (default 0)")
    p.add_argument("--crease-fairness", type=float, default=d.crease_fairness, metavar="W",
                   help=f"smooth the crease curves with weight W while meeting the tolerances (default "
                        f"{d.crease_fairness:g}; 0: off, the nearest developable panel; docs/relax.md 'Crease fairing')")
    p.add_argument("--edge-lengths", metavar="FILE.json", default=None,
                   help='keep these edges at these lengths: {"edges": [[u, v], ...], "lengths": [m, ...]} '
                        "(0-based OBJ vertex ids, metres)")
    p.add_argument("--keep-boundary-lengths", action="store_true",
                   help="keep every boundary edge at its input length (e.g. a panel that must fit its frame)")
    p.add_argument("--planarity-weight", type=float, default=d.planarity_weight,
                   help=f"planarity weight w_p (default {d.planarity_weight:g})")
    p.add_argument("--plane", choices=("cross", "covariance"), default=d.plane_method,
                   help="best-fit plane: sum of corner cross products (default) or covariance eigenvector")
    p.add_argument("--damping", type=float, default=d.damping, help="nominal DR velocity damping in [0,1)")
    p.add_argument("--no-finish", action="store_true", help="no Gauss-Newton finish after DR / L-BFGS")
    p.add_argument("--no-fallback", action="store_true", help="do not try the other route when the first fails")
    p.add_argument("--max-seconds", type=float, default=None, help="wall-clock budget [s]")
    p.add_argument("--write-unconverged", action="store_true",
                   help="write OUT even when the tolerances are missed (exit code stays 1)")
    add_common(p)


def plan_files(args, plan) -> None:
    plan.input(args.input, "IN")
    plan.input(args.edge_lengths, "--edge-lengths")
    plan.output(args.output, "-o")
    plan.output(args.report, "--report")


def run(args) -> int:
    from fabkit.io.edge_lengths import kept_edge_lengths
    from fabkit.io.save import save_panel
    from fabkit.pipeline import relax
    from fabkit.results import Panel

    if not (args.max_move > 0):
        raise InputError(f"must be a positive share of the panel size, got {args.max_move}", source="--max-move")
    mesh, loaded = load_panel_for(args, args.input)
    options = dict(
        method=args.method, tol_defect=args.tol_defect, tol_planarity=args.tol_planarity,
        tol_force=args.tol_force, max_iter=args.max_iter, newton_max_iter=args.newton_max_iter,
        boundary=args.boundary, row_width=args.row_width, fixed=tuple(args.fixed), stage=args.stage,
        stage_defect=args.stage_defect, closeness=args.closeness, planarity_weight=args.planarity_weight,
        plane_method=args.plane, damping=args.damping, finish=not args.no_finish,
        fallback=not args.no_fallback, max_seconds=args.max_seconds, crease_fairness=args.crease_fairness,
        edge_lengths=kept_edge_lengths(mesh, args.edge_lengths, args.keep_boundary_lengths))
    with progress(args, f"relaxing {args.input}") as advance:
        relaxed = relax(Panel(mesh=mesh, name=str(args.input), loaded=loaded), max_move=args.max_move, **options)
        advance(1)
    result, problems, ok = relaxed.result, relaxed.problems, relaxed.ok
    written = ok or args.write_unconverged
    if written:
        save_panel(result.mesh, args.output)
    write_report(args, {**relaxed.to_json(), "output": str(args.output) if written else None,
                        "options": dataclasses.asdict(result.options)})
    phases = ", ".join(f"{k} {v}" for k, v in result.phase_iterations.items()) or "none needed"
    summary = (f"max |angle defect| {result.max_defect:.3g} rad, max planarity {result.max_planarity:.3g}, "
               f"moved max {result.max_displacement * 1e3:.3g} mm / mean {result.mean_displacement * 1e3:.3g} mm, "
               f"{result.seconds:.2f} s ({phases})")
    if ok:
        say(args, f"relaxed {args.input} -> {args.output}: converged, {summary}")
        return 0
    import sys

    note = "" if written else "; no output written (--write-unconverged keeps it)"
    message = problems[0]
    print(f"fabkit relax: {args.input}: {message}{note}", file=sys.stderr)
    return 1
