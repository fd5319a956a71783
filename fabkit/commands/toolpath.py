"""fabkit toolpath: fold states -> TCP poses, joint solutions, motion parameters, URScript."""
from __future__ import annotations

import math
import sys
from pathlib import Path

from fabkit.commands._common import add_common, progress, say, write_report
from fabkit.errors import InputError

HELP = """Turn a fold sequence into a Universal Robots toolpath for one cell.

The gripper holds one middle-row face (chosen automatically, or --grip-face) and follows its frame
through every fold state: home -> approach (movej) -> grip (movel onto the face, gripper output on)
-> fold (movel through the states, subdivided so no joint moves more than 5 deg between waypoints)
-> release (gripper off) -> retract -> home. Every joint solution is verified by forward kinematics;
one arm configuration (shoulder/elbow/wrist branch) is kept through all linear moves.

Writes PATH.json (format fabkit.toolpath/2, with one sha256 over the whole document: robot, cell
name and cell file sha256, TCP, gripper, the FOLD file's sha256, every waypoint) and, with --script,
a URScript program (def ... end) with set_tcp, movej/movel with a/v/r, gripper outputs and progress
in an output integer register.

With --material (and --thickness), the path follows the springback-compensated fold states: every
crease is overbent so that it springs back to the design angle on release (the FOLD keeps the
design angles); PATH.json gains `sheet` (per fold state and crease: design and programmed angles)
and `payload` (tool, and tool + panel while held, with the CoG in the flange frame), and the program
sets the payload (set_payload). The fold loads of the creases the arm folds (between the clamped and
the gripped face) are checked against the arm's wrist torque and rated payload and the cup's holding
force, per state; exceeded loads are warnings naming the crease and the remedy, or exit 1 with
--check-loads. Folds tighter than the material's minimum radius are refused
(exit 2, naming the crease). Models and limits: docs/sheet.md.

Exit codes: 0 ok; 1 the path is unreachable, singular or discontinuous (the message names the
waypoint and the reason; nothing is written); 2 bad input.

Example:
  fabkit toolpath seq.fold --cell cells/ur5e_bench.toml -o path.json --script fold.script
"""


def add_arguments(parser) -> None:
    parser.add_argument("fold", metavar="SEQ.fold", help="fold sequence (FOLD file with fold states as frames)")
    from fabkit.commands._loading import add_units

    add_units(parser)
    parser.add_argument("--cell", required=True, metavar="CELL.toml", help="robot cell description")
    parser.add_argument("-o", "--output", required=True, metavar="PATH.json", help="toolpath to write")
    parser.add_argument("--script", metavar="PROG.script", help="also write the URScript program")
    parser.add_argument("--grip-face", type=int, metavar="F",
                        help="face id to grip (default: automatic among the middle-row faces, tagged or "
                             "inferred from the last fold state; never the clamped face)")
    parser.add_argument("--approach", type=float, default=None, metavar="M",
                        help="approach/retract distance in front of the face [m] (default 0.08; when not given "
                             "and the grip face is chosen, 0.048 and 0.128 are tried too)")
    parser.add_argument("--standoff", type=float, default=0.0, metavar="M",
                        help="TCP distance from the face when gripping [m] (default 0)")
    parser.add_argument("--tool-yaw", type=float, default=None, metavar="DEG",
                        help="turn of the tool about its axis [deg] (default: automatic for axial tools)")
    parser.add_argument("--fold-speed", type=float, default=0.05, metavar="M/S",
                        help="TCP speed while folding [m/s] (default 0.05, capped by the cell)")
    parser.add_argument("--max-joint-step", type=float, default=5.0, metavar="DEG",
                        help="largest joint change between fold waypoints [deg] (default 5)")
    parser.add_argument("--progress-register", type=int, default=None, metavar="N",
                        help="output integer register for progress in the program (default 3)")
    from fabkit.commands._sheet import add_sheet_arguments  # sheet hook: --material, --thickness, ...

    add_sheet_arguments(parser, tool_mass=True)
    parser.add_argument("--design-surface", choices=("top", "mid", "bottom"), default="top",
                        help="with --material: which surface of the sheet the FOLD's faces are (default top: the "
                             "face the cup grips); the grip standoff grows by 0, t/2 or t so the cup sits on the "
                             "sheet's top face")
    parser.add_argument("--check-loads", action="store_true",
                        help="with --material: fail (exit 1, nothing written) when a fold load exceeds the arm's "
                             "or the cup's rating (default: record the verdicts and warn)")
    add_common(parser)


def plan_files(args, plan) -> None:
    plan.input(args.fold, "SEQ.fold")
    plan.input(args.cell, "--cell")
    plan.output(args.output, "-o")
    plan.output(args.script, "--script")
    plan.output(args.report, "--report")


def _check_args(args) -> None:
    if args.approach is not None and not (math.isfinite(args.approach) and 0.0 < args.approach <= 0.5):
        raise InputError(f"{args.approach} m is not in (0, 0.5]", source="--approach")
    if not (math.isfinite(args.standoff) and 0.0 <= args.standoff <= 0.1):
        raise InputError(f"{args.standoff} m is not in [0, 0.1]", source="--standoff")
    if not (math.isfinite(args.fold_speed) and args.fold_speed > 0):
        raise InputError(f"{args.fold_speed} m/s must be > 0", source="--fold-speed")
    if not (math.isfinite(args.max_joint_step) and 0.1 <= args.max_joint_step <= 30):
        raise InputError(f"{args.max_joint_step} deg is not in [0.1, 30]", source="--max-joint-step")
    if args.tool_yaw is not None and not math.isfinite(args.tool_yaw):
        raise InputError("must be a finite angle", source="--tool-yaw")
    if args.tool_mass is not None and not (math.isfinite(args.tool_mass) and 0 <= args.tool_mass <= 20):
        raise InputError(f"{args.tool_mass} kg is not in [0, 20]", source="--tool-mass")
    if args.progress_register is not None and not 0 <= args.progress_register <= 47:
        raise InputError(f"{args.progress_register} is outside 0..47", source="--progress-register")
    if args.output and args.script and Path(args.output).resolve() == Path(args.script).resolve():
        raise InputError("the program and the toolpath would overwrite each other", source="--script")


def run(args) -> int:
    from dataclasses import replace

    from fabkit.frames import planning_frames
    from fabkit.pipeline import fold_source
    from fabkit.results import plan_report
    from fabkit.io.atomic import atomic_write
    from fabkit.commands._loading import load_fold_for
    from robot.cell import load_cell
    from robot.motion import MotionParams
    from robot.holds_record import clamped_faces_of
    from robot.panel_placement import placed_cell, placement_for
    from sim.grip_search import checked_acceptor
    from robot.grip_choice import approach_variants
    from robot.toolpath import PlanningError, PlanOptions, plan_panel
    from robot.urscript import PROGRESS_REGISTER, write_urscript
    from sim.panel import check_fold_coordinates

    _check_args(args)
    cell = load_cell(args.cell)
    model, _ = load_fold_for(args, args.fold)
    check_fold_coordinates(model, source=args.fold)  # a vertex at 1e300 is bad input, not a motion
    if model.n_frames == 0:
        raise InputError("has no fold states (no file_frames)", source=args.fold)
    # ---- sheet hook: plan on the springback-compensated states (fabkit.sheet, docs/sheet.md) ----
    from fabkit.commands._sheet import sheet_from_args

    spec = sheet_from_args(args)
    if spec.rigid and args.design_surface != "top":
        raise InputError("needs a --material other than none", source="--design-surface")
    design_model, compensated = model, None
    if not spec.rigid:
        from fabkit.sheet.compensate import compensate_sequence

        compensated = compensate_sequence(model, spec, source=args.fold)
        model = compensated.model
    # ---- end of sheet hook ----
    frames = planning_frames(model, args.grip_face, source=args.fold)
    source = fold_source(args.fold, frames.n_states)
    from fabkit.sheet import front_face_offset  # sheet hook: the cup grips the sheet's top face

    standoff = args.standoff + (0.0 if spec.rigid else front_face_offset(spec, args.design_surface))
    options = PlanOptions(approach_distance=PlanOptions().approach_distance if args.approach is None else args.approach,
                          grip_standoff=standoff,
                          tool_yaw=None if args.tool_yaw is None else math.radians(args.tool_yaw),
                          max_joint_step=math.radians(args.max_joint_step),
                          params=replace(MotionParams(), fold_speed=args.fold_speed))
    report = {"command": "toolpath", "input": args.fold, "cell": cell.name, "robot": cell.model.name,
              "states": int(frames.n_states), "middle_row": frames.faces.tolist()}
    with progress(args, "planning", total=None):
        try:
            placement = placement_for(cell, model)   # the clamped face on the cell's clamp
            res = plan_panel(placed_cell(cell, placement), frames, grip_face=args.grip_face, options=options,
                             source=source, clamped_faces=clamped_faces_of(model), placement=placement,
                             accept=None if compensated is not None else checked_acceptor(cell, args.fold),
                             variants=approach_variants(options) if args.approach is None else ())
        except PlanningError as exc:
            print(f"fabkit toolpath: {args.fold}: {exc}", file=sys.stderr)
            write_report(args, {**report, "ok": False, "problems": [exc.as_problem()]})
            return 1
    from robot.jig_holds import with_jig_holds

    tp = with_jig_holds(res.toolpath, cell, model)   # the faces the cell's jigs hold (PATH.json holds.jigs)
    if compensated is not None:  # ---- sheet hook: angles, payload and fold loads into PATH.json ----
        from fabkit.commands._sheet import toolpath_sheet_record

        tp, loads = toolpath_sheet_record(args, spec, design_model, compensated, cell, tp, res.grip_face)
        report["loads"] = loads.summary()
        if args.check_loads and not loads.ok:
            write_report(args, {**report, "ok": False, "problems": loads.summary()["problems"]})
            return 1
    script = None
    if args.script:
        reg = PROGRESS_REGISTER if args.progress_register is None else args.progress_register
        script = write_urscript(tp, program_name=f"fold_{cell.name}", progress_register=reg)
    tp.save(args.output)
    if script is not None:
        with atomic_write(args.script) as fh:
            fh.write(script)
    checks = tp.extra["checks"]
    report.update({"ok": True, "output": args.output, "script": args.script, **plan_report(res, tp), "problems": []})
    write_report(args, report)
    say(args, f"{args.output}: {len(tp)} waypoints for {cell.model.name} in {cell.name}, grip face {res.grip_face} "
              f"({res.branch}), cycle time ~{res.cycle_time:.1f} s, largest fold step "
              f"{math.degrees(checks['max_fold_joint_step_rad']):.2f} deg, sha256 {tp.sha256[:12]}")
    if args.script:
        say(args, f"{args.script}: URScript program")
    return 0
