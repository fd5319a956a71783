"""Command-line entry of the stand-in: its options, their validation and the foreground run
(shared by `fabkit ursim`, a thin caller, and `python -m sim.ursim`)."""
from __future__ import annotations

import ipaddress
import math
import signal
import sys
import threading
import time

from fabkit.errors import InputError

READY = "ursim: ready"
FIXED_PORTS = {"rtde": 30004, "dashboard": 29999, "primary": 30001, "secondary": 30002, "realtime": 30003}

HELP = """Run the UR controller stand-in in the foreground.

It speaks the controller's protocols on one loopback address: RTDE (30004), dashboard (29999),
the primary/secondary/real-time client interfaces, which also take URScript (30001-30003), plus a
fault-injection and recording admin channel (30020), so that the unmodified ur_rtde client (and
python-urx, and plain-socket readers) connect and drive a simulated arm (MuJoCo cell model for
collisions when --cell is given). Stop it with Ctrl-C, SIGTERM, or `shutdown` on the dashboard or
the admin channel.

Example:
  fabkit ursim --host 127.0.0.2 --cell cells/ur5e_bench.toml
  fabkit ursim --host 127.0.0.3 --version 3.15.7 --fault protective_stop@progress=20
"""


def add_arguments(parser) -> None:
    parser.add_argument("--host", default="127.0.0.1", help="loopback address to listen on (default 127.0.0.1)")
    parser.add_argument("--cell", metavar="CELL.toml", help="robot cell: model, home pose, TCP, obstacles "
                        "(collisions cause a protective stop)")
    parser.add_argument("--arm", metavar="NAME", help="with --cell: which of the cell's arms this controller is "
                        "(\"a\" the [robot] arm, else an [[arms]] name; default a)")
    parser.add_argument("--model", choices=("ur5e", "ur10e"), help="robot model without a cell (default ur5e)")
    parser.add_argument("--version", default="5.15.0.0", help="controller software version to report "
                        "(5.x: e-Series, 500 Hz; 3.x: CB3, 125 Hz; default 5.15.0.0)")
    parser.add_argument("--q0", metavar="Q", help="initial joint angles, 6 comma-separated radians within the "
                        "model's joint range (default: the cell's home, else UR home)")
    parser.add_argument("--power-off", action="store_true", help="start powered off (dashboard 'power on' "
                        "and 'brake release' needed)")
    parser.add_argument("--local-control", action="store_true", help="answer 'is in remote control' with false")
    parser.add_argument("--unlock-delay", type=float, default=5.0, metavar="S",
                        help="seconds (0-3600) before a protective stop can be unlocked (default 5, as UR)")
    parser.add_argument("--programs", metavar="DIR", help="directory for dashboard load/play (.script files)")
    parser.add_argument("--fault", action="append", default=[], metavar="KIND[@progress=N|@t=S][:ARG]",
                        help="inject a fault (repeatable): protective_stop, estop, program_stop, drop_rtde, "
                        "stall:SECONDS, slow:DELAY[,EVERY]")
    parser.add_argument("--admin-port", type=int, default=30020, help="fault-injection admin port (default 30020)")
    parser.add_argument("--rt-priority", type=int, default=0, metavar="N",
                        help="run the 500 Hz tick thread SCHED_FIFO at priority N, 1-99, and every other stand-in thread at 1 "
                        "(needs the privilege; default 0: SCHED_OTHER at nice -10 when allowed, else normal)")
    parser.add_argument("--robot-mode-data-46", action="store_true",
                        help="send the 46-byte robot mode sub-package of 3.2-3.4 on 30001/30002 instead of "
                        "5.x's 47 bytes (python-urx 0.11 recognises only the older sizes)")
    parser.add_argument("--wire-output", action="append", default=[], metavar="N:HOST:M",
                        help="standard digital output N drives standard digital input M of the stand-in at HOST "
                             "(repeatable; two controllers' I/O wired together)")
    parser.add_argument("--log", metavar="FILE", help="append the controller log to FILE")
    parser.add_argument("-v", "--verbose", action="store_true", help="print the controller log to stderr")
    parser.add_argument("--report", metavar="R.json", help="write a machine-readable JSON report at exit")
    parser.add_argument("-q", "--quiet", action="store_true", help="no ready line")


def _check_options(args) -> None:
    """Refuse option values the stand-in cannot honour (exit 2, one line)."""
    if not (math.isfinite(args.unlock_delay) and 0.0 <= args.unlock_delay <= 3600.0):
        raise InputError(f"{args.unlock_delay:g} s is outside 0-3600 s", source="--unlock-delay")
    if not 0 <= args.rt_priority <= 99:
        raise InputError(f"{args.rt_priority} is outside 0-99 (SCHED_FIFO priorities 1-99; 0 = normal)",
                         source="--rt-priority")
    if not 1 <= args.admin_port <= 65535:
        raise InputError(f"{args.admin_port} is not a TCP port (1-65535)", source="--admin-port")
    if args.admin_port in FIXED_PORTS.values():
        raise InputError(f"{args.admin_port} is one of the controller's own ports", source="--admin-port")


def _version(text: str) -> tuple[int, int, int, int]:
    try:
        parts = [int(p) for p in text.split(".")]
    except ValueError:
        parts = []
    if not 2 <= len(parts) <= 4 or parts[0] not in (3, 5):
        raise InputError("expected a controller version like 5.15.0.0 or 3.15.7 (major 3 or 5)", source="--version")
    return tuple((parts + [0, 0])[:4])


def config_from_args(args):
    from sim.ursim.controller import HOME_Q, ROBOT_POWER_OFF, ROBOT_RUNNING, ControllerConfig

    _check_options(args)
    try:
        if not ipaddress.ip_address(args.host).is_loopback:
            raise InputError("the stand-in listens on loopback addresses only (127.0.0.0/8)", source="--host")
    except ValueError:
        raise InputError(f"not an IP address: {args.host!r}", source="--host") from None
    cell, model, q0, collision = None, args.model or "ur5e", HOME_Q, None
    if args.cell:
        from robot.cell import load_cell
        from sim.ursim.collision import CellCollision

        cell = load_cell(args.cell)
        if args.arm:
            from robot.arm_cells import arm_cell

            cell = arm_cell(cell, args.arm)
        if args.model and args.model != cell.robot.model:
            raise InputError(f"--model {args.model} contradicts the cell's robot {cell.robot.model}", source=args.cell)
        model, q0 = cell.robot.model, tuple(float(v) for v in cell.robot.home)
        collision = CellCollision(cell)
    if args.q0:
        try:
            q0 = tuple(float(v) for v in args.q0.split(","))
        except ValueError:
            q0 = ()
        if len(q0) != 6 or not all(math.isfinite(v) for v in q0):
            raise InputError("expected 6 comma-separated joint angles in radians", source="--q0")
    from robot import kinematics as K

    m = K.get_model(model)
    bad = [j for j in range(6) if not m.q_min[j] <= q0[j] <= m.q_max[j]]
    if bad:
        j = bad[0]
        raise InputError(f"joint {j} = {q0[j]:g} rad is outside the {m.name} range [{m.q_min[j]:g}, {m.q_max[j]:g}]",
                         source="--q0" if args.q0 else args.cell)
    if args.rt_priority == 0:
        # a share of the CPU above ordinary processes (its threads, started later, inherit it), but
        # not real-time: several stand-ins of one test run must not preempt a real-time one
        from robot.realtime import raise_priority

        raise_priority(-10)
    ports = {**FIXED_PORTS, "admin": args.admin_port}
    cfg = ControllerConfig(host=args.host, version=_version(args.version), model=model, q0=q0,
                           robot_mode=ROBOT_POWER_OFF if args.power_off else ROBOT_RUNNING,
                           remote_control=not args.local_control, unlock_delay_s=args.unlock_delay, ports=ports,
                           cell=cell, collision=collision, log_file=args.log, verbose=args.verbose,
                           rt_priority=args.rt_priority, robot_mode_data_46=args.robot_mode_data_46)
    return cfg


def run_stand_in(args) -> int:
    from pathlib import Path

    from sim.ursim.admin import parse_fault_option
    from sim.ursim.server import StandIn

    faults = []
    for text in args.fault:
        try:
            faults.append(parse_fault_option(text))
        except ValueError as exc:
            raise InputError(str(exc), source="--fault") from None
    from sim.ursim.wires import parse_wire, run_wires

    try:
        wires = [parse_wire(t) for t in args.wire_output]
    except ValueError as exc:
        raise InputError(str(exc), source="--wire-output") from None
    cfg = config_from_args(args)
    programs = Path(args.programs) if args.programs else None
    if programs is not None and not programs.is_dir():
        raise InputError("not a directory", source=args.programs)
    if args.log:
        try:
            open(args.log, "a").close()
        except OSError as exc:
            raise InputError(f"cannot write: {exc.strerror}", source=args.log) from None
    try:
        stand_in = StandIn(cfg, programs)
    except OSError as exc:
        raise InputError(str(exc), source="--host") from None
    if cfg.cell is not None and cfg.cell.tool is not None:
        from sim.ursim.motion import matrix_to_pose

        stand_in.ctrl.set_tcp(matrix_to_pose(cfg.cell.tool.tcp))
    for f in faults:
        stand_in.ctrl.schedule_fault(f)
    stop = threading.Event()
    run_wires(stand_in.ctrl, wires, stop)
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    v = cfg.version
    quiet = getattr(args, "quiet", False)
    t_start = time.monotonic()
    if not quiet:
        print(f"{READY} on {cfg.host}: RTDE 30004, dashboard 29999, primary/secondary/real-time 30001-30003, "
              f"admin {cfg.ports['admin']}; "
              f"{cfg.model.upper()}, controller {v[0]}.{v[1]}.{v[2]}.{v[3]}, {1 / stand_in.ctrl.period:.0f} Hz"
              + (f", cell {cfg.cell.name} (MuJoCo collisions)" if cfg.cell else ", no cell (no collision model)"),
              flush=True)
    try:
        while not stop.is_set() and not stand_in.done.is_set():
            stop.wait(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        state = stand_in.ctrl.state()
        stand_in.close()
    if getattr(args, "report", None):
        import json

        from fabkit.io.atomic import atomic_write

        with atomic_write(args.report) as fh:
            json.dump({"host": cfg.host, "version": ".".join(map(str, v)), "model": cfg.model,
                       "cell": cfg.cell.name if cfg.cell else None, "period_s": stand_in.ctrl.period,
                       "uptime_s": time.monotonic() - t_start, "final_state": state}, fh, indent=1)
    if not quiet:
        print("ursim: stopped", file=sys.stderr, flush=True)
    return 0
