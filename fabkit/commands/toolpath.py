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
    parser.add_argument("--script", metavar="PROG.script", help="also write the URScript program (a program for "
                        "several arms: one per arm, PROG_a.script, PROG_b.script, meeting at every sync waypoint "
                        "through standard digital I/O)")
    parser.add_argument("--grip-face", type=int, metavar="F",
                        help="face id to grip (default: automatic among the middle-row faces, tagged or "
                             "inferred from the last fold state; never the clamped face)")
    parser.add_argument("--grip-side", choices=("any", "front", "back"), default="any",
                        help="side of the sheet the cup grips: front (the side the face normals point to), "
                             "back, or any (default: every candidate face's front first, then the back)")
    parser.add_argument("--approach", type=float, default=None, metavar="M",
                        help="approach/retract distance in front of the face [m] (default 0.08; when not given "
                             "and the grip face is chosen, 0.048 and 0.128 are tried too)")
    parser.add_argument("--standoff", type=float, default=None, metavar="M",
                        help="TCP distance from the face when gripping [m] (default 0)")
    parser.add_argument("--tool-yaw", type=float, default=None, metavar="DEG",
                        help="turn of the tool about its axis [deg] (default: automatic for axial tools)")
    parser.add_argument("--fold-speed", type=float, default=None, metavar="M/S",
                        help="TCP speed while folding [m/s] (default 0.05, capped by the cell)")
    parser.add_argument("--max-joint-step", type=float, default=None, metavar="DEG",
                        help="largest joint change between fold waypoints [deg] (default 5)")
    parser.add_argument("--progress-register", type=int, default=None, metavar="N",
                        help="output integer register for progress in the program (default 3)")
    parser.add_argument("--handshake-timeout", type=float, default=None, metavar="S",
                        help="program for several arms: longest wait at a sync waypoint for the other arm before "
                             "the program halts [s] (default: the longest segment between sync waypoints + 2 s)")
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


def run(args) -> int:
    from fabkit.commands._loading import print_notes
    from fabkit.io.atomic import atomic_write
    from fabkit.toolpath_stage import PlanSettings, check_progress_register, plan_fold_file
    from robot.arms_urscript import HANDSHAKE_OUTPUT

    # every option named like a PlanSettings field (--grip-face: grip_face) goes into the one record
    settings = PlanSettings(**{name: getattr(args, name) for name in PlanSettings.field_names() if hasattr(args, name)})
    settings.check()
    check_progress_register(args.progress_register)
    if args.handshake_timeout is not None and not (math.isfinite(args.handshake_timeout) and args.handshake_timeout > 0):
        raise InputError(f"{args.handshake_timeout:g} s is not a positive time", source="--handshake-timeout")
    if args.output and args.script and Path(args.output).resolve() == Path(args.script).resolve():
        raise InputError("the program and the toolpath would overwrite each other", source="--script")
    with progress(args, "planning", total=None):
        program = plan_fold_file(args.fold, args.cell, settings, units=args.units)
    print_notes(args, program.loaded)
    for note in program.notes:
        print(f"fabkit toolpath: note: {note}", file=sys.stderr)
    if program.loads is not None:
        for line in program.loads.failure_lines():
            print(f"fabkit toolpath: {'FAILED' if args.check_loads else 'warning'}: {line}", file=sys.stderr)
    if not program.ok:
        if program.plan is None and program.loads is None:
            print(f"fabkit toolpath: {args.fold}: {program.problems[0]}", file=sys.stderr)
        write_report(args, program.report())
        return 1
    tp, cell, res = program.toolpath, program.cell, program.plan
    if program.refused_by_check is not None:  # kept for `fabkit check` and renders; no URScript for the pendant
        tp.save(args.output)
        write_report(args, program.report(args.output))
        print(f"fabkit toolpath: FAILED: {program.refusal_line}; {args.output} is written for `fabkit check` to "
              f"show{', no URScript' if args.script else ''}", file=sys.stderr)
        return 1
    scripts = program.urscripts(args.script, args.progress_register, args.handshake_timeout) if args.script else {}
    clash = next((p for p in scripts if args.output and Path(args.output).resolve() == p.resolve()), None)
    if clash is not None:
        raise InputError(f"the program {clash} and the toolpath would overwrite each other", source="--script")
    tp.save(args.output)
    for path, text in scripts.items():
        with atomic_write(path) as fh:
            fh.write(text)
    write_report(args, program.report(args.output, list(scripts) if len(scripts) > 1 else args.script))
    checks = tp.extra["checks"]
    say(args, f"{args.output}: {len(tp)} waypoints for {cell.model.name} in {cell.name}, grip face {res.grip_face}"
              f"{' (back side)' if tp.extra.get('grip', {}).get('side') == 'back' else ''} "
              f"({res.branch}), cycle time ~{res.cycle_time:.1f} s, largest fold step "
              f"{math.degrees(checks['max_fold_joint_step_rad']):.2f} deg, sha256 {tp.sha256[:12]}")
    for arm, path in zip(getattr(tp, "arm_names", ()), scripts):
        say(args, f"{path}: URScript program of arm {arm} (handshake on standard DO/DI {HANDSHAKE_OUTPUT}, see "
                  "docs/robot.md)")
    if len(scripts) == 1:
        say(args, f"{args.script}: URScript program")
    return 0
