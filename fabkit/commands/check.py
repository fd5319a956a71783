"""`fabkit check PATH.json --cell CELL.toml -o CHECK.json`: the MuJoCo check of a robot program."""
from __future__ import annotations

import time
from pathlib import Path

from fabkit.commands._common import add_common, progress, say, write_json, write_report
from fabkit.errors import InputError

HELP = """Check every waypoint of a toolpath and the motion between them in a MuJoCo model of the cell.

The cell model is the UR arm built from its DH parameters with collision capsules, the tool, the
obstacles and the panel (one thin convex piece per face, posed for each fold state; the FOLD file
is the one the toolpath's source names, or --fold; either way its sha256 must be the one the
toolpath was planned from). Configurations are checked at least every 1 deg
of joint motion and 5 mm of TCP travel, with the fold state interpolated alongside, for:
reachability, joint limits, singularities, collisions (named pairs), clearance below the cell's
limit, and joint speeds at the planned TCP speed. Writes CHECK.json (format fabkit.check/2) with
the toolpath's sha256, the cell file's sha256 and the FOLD file used (path and sha256) - the very
report `sim.check.check_toolpath` returns; exit 1 if there is any problem, 2 for bad input
(including a PATH.json whose stored sha256 does not match the document, a changed FOLD file, and
non-finite or absurd coordinates).

A toolpath planned with --material (fabkit toolpath) is also checked for its fold loads: for every
crease the arm folds, per fold state, the fold moment against the arm's wrist torque and rated
payload and the vacuum cup's holding force (CHECK.json `loads`: moment, demand, capacity, ratio,
verdict per state); an exceeded load is a problem naming the crease and the remedy (groove the
crease, a bigger arm, push instead of pull, two arms), and the panel is posed in the
springback-compensated states with the sheet's thickness (docs/sheet.md).

Renders (offscreen, EGL or OSMesa): --render F.png draws waypoint K (default: the first problem,
else the middle of the fold) with an offending pair in red; --render F.mp4 plays the whole program.

example:
  fabkit check out/PATH.json --cell cells/ur5e_bench.toml -o out/CHECK.json --render out/check.png
"""


def add_arguments(parser) -> None:
    parser.add_argument("toolpath", metavar="PATH.json", help="toolpath (fabkit.toolpath/2)")
    parser.add_argument("--cell", required=True, metavar="CELL.toml", help="robot cell description")
    parser.add_argument("-o", "--output", required=True, metavar="CHECK.json", help="check report to write")
    parser.add_argument("--fold", metavar="SEQ.fold", help="fold states of the panel (default: the FOLD file "
                        "the toolpath's source names)")
    parser.add_argument("--no-panel", action="store_true", help="check against the cell's obstacles only")
    from fabkit.commands._sheet import add_sheet_arguments

    add_sheet_arguments(parser, material_help=(
        "check the fold loads for this sheet (a name from `fabkit materials` or a .toml file); only for a "
        "toolpath planned without one - a toolpath planned with --material is checked for its own sheet, "
        "and a different one is refused. Without --material, --thickness alone sets the panel pieces' "
        "thickness (default 1mm, or the toolpath's sheet)"))
    parser.add_argument("--render", metavar="F.png|F.mp4", action="append", default=[],
                        help="write a picture of one waypoint or a movie (repeat for both)")
    parser.add_argument("--waypoint", type=int, metavar="K", help="waypoint to render (PNG)")
    parser.add_argument("--size", default="640x480", metavar="WxH", help="render size (default 640x480)")
    parser.add_argument("--frames", type=int, default=240, metavar="N",
                        help="most frames in an MP4 (30 fps; longer programs play faster; default 240)")
    parser.add_argument("--view", action="store_true", help="play the program in MuJoCo's viewer (needs a display)")
    add_common(parser)


def plan_files(args, plan) -> None:
    plan.input(args.toolpath, "PATH.json")
    plan.input(args.cell, "--cell")
    plan.input(args.fold, "--fold")
    plan.output(args.output, "-o")
    plan.output(args.render, "--render")
    plan.output(args.report, "--report")


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"expected WIDTHxHEIGHT, got {text!r}", source="--size") from None
    return w, h


def run(args) -> int:
    import os

    from fabkit.pipeline import check_render, check_sheet

    renders = [Path(r) for r in args.render]
    size = _size(args.size) if renders else None
    for render in renders:
        check_render(render, size)  # the GL backend is chosen before anything imports mujoco
        if render.resolve() == Path(args.output).resolve():
            raise InputError("would overwrite the check report", source="--render")
    if args.view and not os.environ.get("DISPLAY"):
        raise InputError("no display for the viewer (DISPLAY is not set)", source="--view")
    if not 2 <= args.frames <= 10000:
        raise InputError(f"must be in 2..10000, got {args.frames}", source="--frames")
    sheet, slab = check_sheet(args.material, args.thickness, args.crease, args.ligament, args.bend_radius)
    out = Path(args.output)
    if not out.parent.is_dir():
        raise InputError("output directory does not exist", source=str(out))
    if out.resolve() == Path(args.toolpath).resolve():
        raise InputError("would overwrite the toolpath", source=str(out))

    from robot.cell import load_cell
    from sim.check import CheckSettings, run_toolpath_check

    cell = load_cell(args.cell)

    t0 = time.perf_counter()
    with progress(args, "checking") as advance:
        seen = [0]

        def on_progress(done, total):
            advance(done - seen[0], total=total)
            seen[0] = done

        # the library check: refuses an edited PATH.json, loads and verifies the FOLD it names (or --fold)
        result = run_toolpath_check(args.toolpath, cell, fold=args.fold, use_panel=not args.no_panel,
                                    thickness=slab, settings=CheckSettings(), on_progress=on_progress, sheet=sheet)
    elapsed = time.perf_counter() - t0
    report, dense, prog, panel, fold_path = result.report, result.dense, result.program, result.panel, result.fold_path
    write_json(out, report.to_json())

    if not args.quiet:
        _summary(args, report, elapsed, fold_path)
    rendered = [_render(args, render, size, result, cell) for render in renders]
    rendered = rendered[0] if len(rendered) == 1 else (rendered or None)
    write_report(args, {"command": "check", "toolpath": str(args.toolpath), "cell": str(args.cell),
                        "fold": None if fold_path is None else str(fold_path), "output": str(out),
                        "ok": report.ok, "problems": len(report.problems), "waypoints": report.waypoints,
                        "configs_checked": report.configs_checked, "check_seconds": elapsed,
                        "configs_per_second": report.configs_checked / elapsed if elapsed > 0 else None,
                        "min_clearance_m": report.min_clearance_m, "cycle_time_s": report.cycle_time_s,
                        "toolpath_sha256": report.toolpath_sha256, "render": rendered,
                        "clearance_window_m": report.clearance_window_m})
    if args.view:
        from sim.model import build_cell_model
        from sim.render import view

        m, _ = build_cell_model(cell, panel)
        view(m, cell, dense.q, panel=panel, states=dense.state, dt=dense.dt)
    return 0 if report.ok else 1


def _summary(args, report, elapsed: float, fold_path) -> None:
    clear = ("—" if report.min_clearance_m is None else
             f"{report.min_clearance_m * 1e3:.1f} mm ({' × '.join(report.min_clearance_pair)})")
    panel = f"panel {report.panel_faces} faces from {fold_path}" if report.panel_faces else "no panel"
    head = "ok" if report.ok else f"{len(report.problems)} problem(s)"
    say(args, f"check: {head} — {report.waypoints} waypoints, {report.configs_checked} configurations in "
              f"{elapsed:.2f} s, {panel}, min clearance {clear}, cycle ≈ {report.cycle_time_s:.1f} s")
    if report.loads is not None:
        worst = max((c["ratio"] for st in report.loads["states"] for c in st["checks"] if c["ratio"] is not None),
                    default=None)
        say(args, f"  fold loads ({report.loads['sheet']['material']}, {report.loads['sheet']['crease']}) on the "
                  f"{report.loads['arm']}: {'ok' if report.loads['ok'] else 'EXCEEDED'}"
                  + ("" if worst is None else f", worst {worst:.0%} of a rating"))
    for p in report.problems[:20]:
        say(args, f"  waypoint {p.waypoint}: {p.kind}: {p.detail}")
    if len(report.problems) > 20:
        say(args, f"  … {len(report.problems) - 20} more in {args.output}")


def _render(args, path: Path, size, run, cell) -> dict:
    from sim.render_check import render_movie, render_waypoint

    if path.suffix.lower() == ".png":
        drawn = render_waypoint(run, cell, path, size, waypoint=args.waypoint)
        where = " (where the problem starts, on the move to it)" if drawn.pop("inside_move") else ""
        say(args, f"rendered waypoint {drawn['waypoint']}{where} to {path}")
        return drawn
    with progress(args, "rendering", total=None) as advance:
        drawn = render_movie(run, cell, path, size, max_frames=args.frames, advance=advance)
    say(args, f"rendered {drawn['frames']} frames to {path} ({drawn['speedup']:.1f}x real time)")
    return drawn
