"""`fabkit ursim`: run the UR controller stand-in in the foreground."""
from __future__ import annotations

from fabkit.commands._common import add_common

HELP = """Run the UR controller stand-in in the foreground.

It speaks the controller's protocols on one loopback address: RTDE (30004), dashboard (29999),
script ports (30001-30003), plus a fault-injection admin channel (30020), so that the unmodified
ur_rtde client connects, uploads its control script and drives a simulated arm (MuJoCo cell model
for collisions when --cell is given). Stop it with Ctrl-C or the admin command `shutdown`.

Example:
  fabkit ursim --host 127.0.0.2 --cell cells/ur5e_bench.toml
  fabkit ursim --host 127.0.0.3 --version 3.15.7 --fault protective_stop@progress=20
"""


def add_arguments(parser) -> None:
    parser.add_argument("--host", default="127.0.0.1", help="loopback address to listen on (default 127.0.0.1)")
    parser.add_argument("--cell", metavar="CELL.toml", help="robot cell: model, home pose, TCP, obstacles "
                        "(collisions cause a protective stop)")
    parser.add_argument("--model", choices=("ur5e", "ur10e"), help="robot model without a cell (default ur5e)")
    parser.add_argument("--version", default="5.15.0.0", help="controller software version to report "
                        "(5.x: e-Series, 500 Hz; 3.x: CB3, 125 Hz; default 5.15.0.0)")
    parser.add_argument("--q0", metavar="Q", help="initial joint angles, 6 comma-separated radians "
                        "(default: the cell's home, else UR home)")
    parser.add_argument("--power-off", action="store_true", help="start powered off (dashboard 'power on' "
                        "and 'brake release' needed)")
    parser.add_argument("--local-control", action="store_true", help="answer 'is in remote control' with false")
    parser.add_argument("--unlock-delay", type=float, default=5.0, metavar="S",
                        help="seconds before a protective stop can be unlocked (default 5, as UR)")
    parser.add_argument("--programs", metavar="DIR", help="directory for dashboard load/play (.script files)")
    parser.add_argument("--fault", action="append", default=[], metavar="KIND[@progress=N|@t=S][:ARG]",
                        help="inject a fault (repeatable): protective_stop, estop, program_stop, drop_rtde, "
                        "stall:SECONDS, slow:DELAY[,EVERY]")
    parser.add_argument("--admin-port", type=int, default=30020, help="fault-injection admin port (default 30020)")
    parser.add_argument("--rt-priority", type=int, default=0, metavar="N",
                        help="run the 500 Hz tick thread SCHED_FIFO at priority N (needs the privilege; "
                        "default 0 = normal scheduling)")
    parser.add_argument("--log", metavar="FILE", help="append the controller log to FILE")
    parser.add_argument("-v", "--verbose", action="store_true", help="print the controller log to stderr")
    add_common(parser)


def plan_files(args, plan) -> None:
    plan.input(args.cell, "--cell")
    plan.stream(args.log, "--log")
    plan.output(args.report, "--report")


def run(args) -> int:
    from sim.ursim.cli import run_stand_in

    return run_stand_in(args)
