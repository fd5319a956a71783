"""`fabkit send`: send a checked toolpath to a UR controller over RTDE with ur_rtde."""
from __future__ import annotations

import contextlib
import json
import os
import signal
import sys

from fabkit.commands._common import add_common, progress, say, write_report
from fabkit.errors import InputError

HELP = """Send a checked toolpath (PATH.json) to a UR controller over RTDE with ur_rtde.

Before any connection: refuses (exit 2, one line naming what differs) unless CHECK.json passed
with no problems and was made for this very toolpath, cell file and FOLD file (their sha256s,
recomputed now, equal the ones the toolpath and the check recorded), and unless every joint
target, speed, acceleration and blend radius is inside the cell's limits; then runs the check
again on exactly what it is about to send and refuses on any problem. A check that failed exits 1.

Preflight: robot model, remote control, and the arm where the send starts (waypoint 0, or with
--resume-from N on the segment into waypoint N, position and orientation) - all read-only; then
power on (--power-on), unlock (--unlock), safety NORMAL. The path goes out as blended movePath
chunks, asynchronously, with the controller's RTDE watchdog armed, while the receive stream is
watched. On any fault, Ctrl-C or SIGTERM the arm is stopped and the command exits 1 (130 when
interrupted) naming the last completed waypoint; if this command or its ur_rtde worker dies,
the watchdog stops the arm. --log is written as it goes (JSON lines).

Example (against the controller stand-in):
  fabkit ursim --host 127.0.0.2 &
  fabkit send PATH.json --check CHECK.json --cell CELL.toml --host 127.0.0.2 --log send.log
"""


def add_arguments(parser) -> None:
    parser.add_argument("toolpath", metavar="PATH.json", help="toolpath from `fabkit toolpath`")
    parser.add_argument("--check", required=True, metavar="CHECK.json", help="passing check report of this toolpath")
    parser.add_argument("--cell", required=True, metavar="CELL.toml", help="the cell file the toolpath was planned "
                        "and checked in")
    parser.add_argument("--fold", metavar="SEQ.fold", help="the FOLD file the toolpath was planned from (default: "
                        "the one the check used, else the one the toolpath names)")
    parser.add_argument("--host", action="append", default=None,
                        help="controller address; a program for several arms: one --host per arm, in the "
                             "program's arm order (default: the cell's host of every arm, else $FABKIT_UR_HOST); "
                             "given, they replace all of the cell's")
    parser.add_argument("--power-on", action="store_true", help="power on and release the brakes if needed")
    parser.add_argument("--unlock", action="store_true",
                        help="unlock a protective stop (>= 5 s old) before sending; inspect its cause first")
    parser.add_argument("--resume-from", type=int, default=0, metavar="N",
                        help="start at waypoint N (after a stop: the last completed waypoint + 1)")
    parser.add_argument("--chunk", type=int, default=50, metavar="K", help="waypoints per movePath (default 50)")
    parser.add_argument("--stall", type=float, default=0.5, metavar="S",
                        help="seconds without a new RTDE timestamp that count as a lost link (default 0.5)")
    parser.add_argument("--log", metavar="FILE", help="write everything sent and received (JSON lines)")
    add_common(parser)


def plan_files(args, plan) -> None:
    plan.input(args.toolpath, "PATH.json")
    plan.input(args.check, "--check")
    plan.input(args.cell, "--cell")
    plan.input(args.fold, "--fold")
    plan.stream(args.log, "--log")
    plan.output(args.report, "--report")


def _load_check(path: str) -> dict:
    from fabkit.io.jsonfile import load_json

    return load_json(path, "JSON check report", missing="check report not found")


def run(args) -> int:
    from robot.cell import load_cell
    from robot.interlock import CheckFailedError, InterlockError
    from robot.send_options import controller_hosts, send_option_problem
    from robot.sender import SendError, SendSettings, send_toolpath
    from robot.arms_toolpath import load_toolpath

    tp = load_toolpath(args.toolpath)
    cell = load_cell(args.cell)
    hosts, _ = controller_hosts(args.host, cell, getattr(tp, "arm_names", ("a",)), os.environ.get("FABKIT_UR_HOST"))
    hosts = list(hosts)
    args.host = hosts[0]
    problem = next((p for h in hosts for p in [send_option_problem(h, args.chunk, args.stall)] if p), None)
    if problem is not None:
        raise InputError(problem[1], source=f"--{problem[0]}")
    check = _load_check(args.check)
    settings = SendSettings(host=args.host, chunk=args.chunk, resume_from=args.resume_from,
                            power_on=args.power_on, unlock=args.unlock, stall_s=args.stall, hosts=tuple(hosts[1:]))
    job = dict(check=check, cell=cell, fold=args.fold, base_dir=os.path.dirname(args.toolpath) or ".")
    try:
        with _log_file(args.log) as log, _sigterm_interrupts():
            result = _send(args, tp, settings, log, job, send_toolpath)
    except CheckFailedError as exc:
        print(f"fabkit send: refusing to send: {args.check}: {exc}", file=sys.stderr)
        write_report(args, {"ok": False, "sent": False, "reason": "check failed", "check": args.check})
        return 1
    except InterlockError as exc:
        raise InputError(f"refusing to send: {exc}", source=args.toolpath) from None
    except SendError as exc:
        raise InputError(str(exc), source=args.toolpath) from None
    n = len(tp)
    if result.ok:
        say(args, f"sent {n - args.resume_from} of {n} waypoints to {', '.join(hosts)} in {result.elapsed_s:.1f} s "
                  f"({result.chunks_sent} path chunk(s)); final pose off by {result.final_error_m * 1e3:.4f} mm, "
                  f"{result.final_error_rad * 1e3:.4f} mrad; path rounding <= {result.quantisation_m * 1e6:.2f} um")
    else:
        nxt = result.last_completed + 1
        per_arm = getattr(result, "last_completed_per_arm", None)
        if per_arm:
            resume = result.resume
            last = ", ".join(f"arm {a} {k}" for a, k in per_arm.items())
            hint = "" if resume is None else (f" (last sync waypoint {resume.last_sync}); {resume.describe()}"
                                              if resume.last_sync >= 0 else f"; {resume.describe()}")
        else:
            last = result.last_completed
            hint = f"; continue with --resume-from {nxt}" if 0 <= nxt < n else ""
        print(f"fabkit send: stopped: {result.reason}; last completed waypoint {last} of {n - 1}{hint}",
              file=sys.stderr)
    write_report(args, {"ok": result.ok, "sent": True, "host": args.host if len(hosts) == 1 else hosts,
                        "toolpath": args.toolpath,
                        "toolpath_sha256": tp.sha256, "resume_from": args.resume_from, **result.to_json()})
    return 0 if result.ok else 1


@contextlib.contextmanager
def _log_file(path):
    """The send log, line-buffered JSON lines written as the send goes (what a crash leaves is on
    disk); None without --log."""
    if not path:
        yield None
        return
    with open(path, "w", buffering=1, encoding="utf-8") as fh:
        def log(event, fh=fh):
            fh.write(json.dumps(event, default=_plain) + "\n")
        yield log


@contextlib.contextmanager
def _sigterm_interrupts():
    """SIGTERM during the send acts as Ctrl-C: the sender stops the arm and the log is closed."""
    def on_term(signum, frame):
        raise KeyboardInterrupt("SIGTERM")

    try:
        old = signal.signal(signal.SIGTERM, on_term)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _send(args, tp, settings, log, job, send_toolpath):
    n = len(tp)
    with progress(args, "sending", total=n) as advance:
        def on_progress(k, st):
            p = st.get("tcp_pose") or [0, 0, 0]
            advance(0, completed=k + 1, description=f"waypoint {k + 1}/{n} "
                    f"TCP {p[0]:+.3f} {p[1]:+.3f} {p[2]:+.3f} m")
        return send_toolpath(tp, job["check"], job["cell"], settings, fold=job["fold"], base_dir=job["base_dir"],
                             log=log, on_progress=on_progress)


def _plain(obj):
    try:
        import numpy as np

        if isinstance(obj, np.ndarray):
            return obj.tolist()
        if isinstance(obj, np.generic):
            return obj.item()
    except ImportError:  # pragma: no cover
        pass
    return str(obj)
