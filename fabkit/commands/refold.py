"""`fabkit refold FLAT.obj TARGET.obj -o SEQ.fold`: sequential rigid fold states from flat to target."""
from __future__ import annotations

import contextlib
import sys
from pathlib import Path

from fabkit.commands._common import add_common, progress, say, to_jsonable
from fabkit.commands._loading import add_units, load_panel_for
from fabkit.verdicts import DEFAULT_TARGET_RTOL

HELP = """Fold states a robot walks the sheet through, from the flat pattern to the target (paper §3.6).

Quads are split by a diagonal (a J hinge); rigid-origami kinematics with the fold angles as the
state (Tachi 2009): loop closure at every interior vertex, minimum-norm Newton steps, positions by
rotating faces outward from the clamped face. By default only the crease angles of the middle row
of faces (face_data "middle") are prescribed, moving linearly from 0 to the target; every other
angle follows from the constraints, as close to the same fraction of its target as closure allows.
The last state is the target. The clamped face (--fixed-face, default the middle-row face of the
middle strip) keeps its flat position: states are in the panel frame.

FLAT and TARGET must have the same vertices and faces (FLAT in z = 0, e.g. from 'fabkit unfold').
A TARGET whose edge lengths differ from FLAT's by more than --length-tol is not a fold of it: exit 1
naming the worst edge, nothing written.

--drive FILE: JSON list of FLAT edge ids or [u, v] vertex pairs; a list of such lists (steps folded
one after another); or {"drive": [...], "steps": [[...], ...]}. --steps crease0,crease1 folds the
middle-row creases one crease row at a time (stripK = the creases bounding strip K); --steps FILE
takes a JSON schedule (a list of edge lists, folded in order; they are the driven hinges).

Exit codes: 0 ok; 1 TARGET is not a fold of FLAT, a state did not converge, the last state misses
the target by more than --target-tol, or faces pass through each other (files are still written
and the report says which); 2 bad input.

Example:
  fabkit generate reflect -o panel.obj && fabkit unfold panel.obj -o flat.obj
  fabkit refold flat.obj panel.obj -o seq.fold --frames 20 --png angles.png --glb states.glb
"""


def add_arguments(parser) -> None:
    parser.add_argument("flat", metavar="FLAT.obj", help="flat pattern (z = 0), same faces as TARGET")
    parser.add_argument("target", metavar="TARGET.obj", nargs="?", default=None,
                        help="the folded (relaxed) panel (.obj, .fold, .3dm); left out when FLAT is a .fold "
                             "crease pattern with a folded frame (its last frame is the target)")
    add_units(parser)
    parser.add_argument("-o", "--output", metavar="SEQ.fold", required=True, help="FOLD animation")
    parser.add_argument("--frames", type=int, default=20, metavar="N",
                        help="states per folding step, flat and target included (default 20)")
    parser.add_argument("--drive", default="middle-row", metavar="middle-row|all|FILE",
                        help="prescribed hinges: the middle-row creases (default), all creases, or a JSON file")
    parser.add_argument("--steps", metavar="LIST|FILE",
                        help="fold crease rows one after another (e.g. crease0,crease1), or a JSON schedule file")
    parser.add_argument("--fixed-face", type=int, metavar="F", help="face clamped at the fixture (FLAT face id)")
    parser.add_argument("--glb", metavar="F.glb", help="all states side by side in one GLB scene (viewing)")
    parser.add_argument("--obj-dir", metavar="DIR", help="one OBJ per state (quads and tags kept): DIR/state_000.obj ...")
    parser.add_argument("--png", metavar="F.png", help="plot of crease fold angles against the state")
    parser.add_argument("--length-tol", type=float, default=1e-6, metavar="R",
                        help="largest relative edge-length difference TARGET vs FLAT (default 1e-6)")
    parser.add_argument("--target-tol", type=float, default=DEFAULT_TARGET_RTOL, metavar="R",
                        help="largest distance of the last state to TARGET, relative to the panel size (default "
                             f"{DEFAULT_TARGET_RTOL:g})")
    parser.add_argument("--diagonal", choices=("short", "02", "13"), default="short",
                        help="quad diagonal that becomes the J hinge (default: the shorter one in FLAT)")
    parser.add_argument("--solver", choices=("direct", "lsmr", "dense"), default="direct",
                        help="minimum-norm linear solver: sparse factorisation (default), LSMR, dense pinv")
    parser.add_argument("--no-intersections", action="store_true", help="skip the face interpenetration check")
    add_common(parser)


def plan_files(args, plan) -> None:
    plan.input(args.flat, "FLAT")
    plan.input(args.target, "TARGET")
    for option in ("drive", "steps"):
        value = getattr(args, option)
        if value and Path(value).exists():
            plan.input(value, f"--{option}")
    for option in ("output", "glb", "png", "report"):
        plan.output(getattr(args, option), "-o" if option == "output" else f"--{option}")
    plan.folder(args.obj_dir, "--obj-dir")


def _check_args(args) -> list[Path]:
    from fabkit.errors import InputError
    from fabkit.refold_stage import check_refold_options

    check_refold_options(args.frames, args.length_tol, args.target_tol)
    outputs = [p for p in (args.output, args.glb, args.png, args.report) if p]
    resolved = [Path(p).resolve() for p in outputs]
    if len(set(resolved)) != len(resolved):
        raise InputError("two outputs name the same file", source=", ".join(outputs))
    for inp in (args.flat, args.target):
        if inp is not None and Path(inp).resolve() in resolved:
            raise InputError("an output would overwrite the input", source=inp)
    for p in outputs:
        if not Path(p).parent.is_dir():
            raise InputError("output directory does not exist", source=p)
        if Path(p).is_dir():
            raise InputError("is a directory, not a file name", source=p)
    if args.glb and Path(args.glb).suffix.lower() != ".glb":
        raise InputError("the film strip is written as .glb", source=args.glb)
    if args.obj_dir and not Path(args.obj_dir).is_dir():
        raise InputError("output directory does not exist", source=args.obj_dir)
    return resolved


def run(args) -> int:
    from fabkit.commands._common import write_json
    from fabkit.io.atomic import atomic_path
    from fabkit.io.fold import save_fold
    from fabkit.refold.export import plot_fold_angles, save_glb_strip, save_obj_states
    from fabkit.refold_stage import refold_meshes

    _check_args(args)
    flat, flat_info = load_panel_for(args, args.flat, state="key")
    if args.target is None:
        from fabkit.errors import InputError

        model = flat_info.model
        if model is None or model.n_frames == 0:
            raise InputError("needs TARGET, or a .fold crease pattern with a folded frame as FLAT", source=args.flat)
        args.target = args.flat
        target, _ = load_panel_for(args, args.flat, state="folded")
    else:
        target, _ = load_panel_for(args, args.target)
    with progress(args, "refolding", total=None) as advance:
        folds = refold_meshes(flat, target, frames=args.frames, drive=args.drive, steps=args.steps,
                              fixed_face=args.fixed_face, diagonal=args.diagonal, length_tol=args.length_tol,
                              target_tol=args.target_tol, solver=args.solver, intersections=not args.no_intersections,
                              flat_name=str(args.flat), target_name=str(args.target),
                              title=f"refold of {Path(args.flat).name} to {Path(args.target).name}", progress=advance)
    seq = folds.sequence
    if seq is None:  # not a fold of FLAT: nothing but the report is written
        if args.report:
            write_json(args.report, folds.to_json())
        print(f"fabkit refold: {folds.problems[0]}", file=sys.stderr)
        return 1
    report = {**folds.to_json(), "output": str(args.output),
              "outputs": {k: v for k, v in {"fold": args.output, "glb": args.glb, "png": args.png,
                                            "obj_dir": args.obj_dir}.items() if v}}
    with contextlib.ExitStack() as stack:
        save_fold(folds.model, stack.enter_context(atomic_path(args.output)))
        if args.glb:
            save_glb_strip(seq, stack.enter_context(atomic_path(args.glb)))
        if args.png:
            plot_fold_angles(seq, stack.enter_context(atomic_path(args.png)))
        if args.report:
            write_json(stack.enter_context(atomic_path(args.report)), to_jsonable(report))
    if args.obj_dir:
        save_obj_states(seq, flat, args.obj_dir)

    summary = report["summary"]
    rel = seq.target_distance / seq.panel_size if seq.panel_size > 0 else float("nan")
    say(args, f"refold {args.flat} -> {args.target}: {seq.n_states} states, {len(seq.driven)} driven of "
              f"{summary['hinges']} hinges, fixed face {seq.fixed_face}; max loop residual "
              f"{summary['max_loop_residual_rad']:.2g} rad, max edge-length error "
              f"{summary['max_edge_length_error_rel']:.2g}, last state to target {rel:.2g} of the panel size; "
              f"Newton {summary['newton_iterations_mean']:.1f} iterations/state; {report['seconds']:.2f} s")
    for n in seq.notes:
        say(args, f"note: {n}")
    say(args, "wrote " + ", ".join(v for v in (args.output, args.glb, args.png, args.report, args.obj_dir) if v))
    for p in folds.problems:
        print(f"fabkit refold: FAILED: {p}", file=sys.stderr)
    return 1 if folds.problems else 0
