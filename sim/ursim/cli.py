"""Command-line entry of the stand-in (shared by `fabkit ursim` and `python -m sim.ursim`)."""
from __future__ import annotations

import ipaddress
import signal
import sys
import threading
import time

import numpy as np

from fabkit.errors import InputError

READY = "ursim: ready"


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
        if args.model and args.model != cell.robot.model:
            raise InputError(f"--model {args.model} contradicts the cell's robot {cell.robot.model}", source=args.cell)
        model, q0 = cell.robot.model, tuple(float(v) for v in cell.robot.home)
        collision = CellCollision(cell)
    if args.q0:
        try:
            q0 = tuple(float(v) for v in args.q0.split(","))
        except ValueError:
            q0 = ()
        if len(q0) != 6 or not np.all(np.isfinite(q0)):
            raise InputError("expected 6 comma-separated joint angles in radians", source="--q0")
    ports = {"rtde": 30004, "dashboard": 29999, "primary": 30001, "secondary": 30002, "realtime": 30003,
             "admin": args.admin_port}
    cfg = ControllerConfig(host=args.host, version=_version(args.version), model=model, q0=q0,
                           robot_mode=ROBOT_POWER_OFF if args.power_off else ROBOT_RUNNING,
                           remote_control=not args.local_control, unlock_delay_s=args.unlock_delay, ports=ports,
                           cell=cell, collision=collision, log_file=args.log, verbose=args.verbose,
                           rt_priority=args.rt_priority)
    return cfg


def run_stand_in(args) -> int:
    from pathlib import Path

    from sim.ursim.admin import parse_fault_option
    from sim.ursim.server import StandIn

    cfg = config_from_args(args)
    faults = []
    for text in args.fault:
        try:
            faults.append(parse_fault_option(text))
        except ValueError as exc:
            raise InputError(str(exc), source="--fault") from None
    programs = Path(args.programs) if args.programs else None
    if programs is not None and not programs.is_dir():
        raise InputError("not a directory", source=args.programs)
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
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    v = cfg.version
    quiet = getattr(args, "quiet", False)
    t_start = time.monotonic()
    if not quiet:
        print(f"{READY} on {cfg.host}: RTDE 30004, dashboard 29999, script 30001-30003, admin {cfg.ports['admin']}; "
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
        from fabkit.commands._common import write_json

        write_json(args.report, {"host": cfg.host, "version": ".".join(map(str, v)), "model": cfg.model,
                                 "cell": cfg.cell.name if cfg.cell else None, "period_s": stand_in.ctrl.period,
                                 "uptime_s": time.monotonic() - t_start, "final_state": state})
    if not quiet:
        print("ursim: stopped", file=sys.stderr, flush=True)
    return 0
