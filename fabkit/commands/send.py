"""`fabkit send`: send a checked toolpath to a UR controller over RTDE with ur_rtde."""
from __future__ import annotations

import json
import math
import os
import re
import sys

from fabkit.commands._common import add_common, progress, say, write_report
from fabkit.errors import InputError

HELP = """Send a checked toolpath (PATH.json) to a UR controller over RTDE with ur_rtde.

Refuses unless CHECK.json (from `fabkit check`) passed and was made for this very toolpath
(its toolpath_sha256 equals the toolpath's recomputed hash). Preflight over the dashboard:
robot mode RUNNING, safety NORMAL, remote control on. The path goes out as blended movePath
chunks, asynchronously, while the RTDE receive stream is watched (the controller timestamp must
advance). On any fault the arm is stopped and the command exits 1 naming the last completed
waypoint; `--resume-from N` continues from waypoint N.

ur_rtde runs in a supervised worker process with a timeout on every call, so a crashing or
hanging ur_rtde never takes this command with it.

Example (against the controller stand-in):
  fabkit ursim --host 127.0.0.2 &
  fabkit send PATH.json --check CHECK.json --host 127.0.0.2 --log send.log
"""


def add_arguments(parser) -> None:
    parser.add_argument("toolpath", metavar="PATH.json", help="toolpath from `fabkit toolpath`")
    parser.add_argument("--check", required=True, metavar="CHECK.json", help="passing check report of this toolpath")
    parser.add_argument("--host", default=os.environ.get("FABKIT_UR_HOST"),
                        help="controller address (default: $FABKIT_UR_HOST)")
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


#: longest --stall: a frozen controller must be noticed within seconds, never switched off
MAX_STALL_S = 5.0

_HOST_LABEL = re.compile(r"^(?!-)[A-Za-z0-9-]{1,63}(?<!-)$")


def _is_host(text: str) -> bool:
    """An IPv4/IPv6 address or an RFC 1123 host name."""
    import ipaddress

    try:
        ipaddress.ip_address(text)
        return True
    except ValueError:
        pass
    return len(text) <= 253 and all(_HOST_LABEL.match(label) for label in text.rstrip(".").split("."))


def plan_files(args, plan) -> None:
    plan.input(args.toolpath, "PATH.json")
    plan.input(args.check, "--check")
    plan.stream(args.log, "--log")
    plan.output(args.report, "--report")


def _load_check(path: str, sha: str) -> dict:
    from fabkit.io.jsonfile import load_json

    check = load_json(path, "JSON check report", missing="check report not found")
    if not isinstance(check, dict) or check.get("format") != "fabkit.check/1":
        raise InputError("not a fabkit.check/1 report", source=path)
    if not isinstance(check.get("ok"), bool):
        raise InputError("ok: expected true or false", source=path)
    if check.get("toolpath_sha256") != sha:
        raise InputError(f"toolpath_sha256 {str(check.get('toolpath_sha256'))[:12]}... does not match the toolpath "
                         f"({sha[:12]}...): this check was made for another toolpath", source=path)
    return check


def run(args) -> int:
    from robot.sender import SendError, SendSettings, send_toolpath
    from robot.toolpath import Toolpath

    if not args.host:
        raise InputError("no controller address: give --host or set FABKIT_UR_HOST", source="--host")
    if args.chunk < 2:
        raise InputError("a chunk needs at least 2 waypoints", source="--chunk")
    if not (math.isfinite(args.stall) and 0 < args.stall <= MAX_STALL_S):
        raise InputError(f"must be a number of seconds in (0, {MAX_STALL_S:g}], got {args.stall}", source="--stall")
    if not _is_host(args.host):
        raise InputError(f"{args.host!r} is not an IP address or host name", source="--host")
    tp = Toolpath.load(args.toolpath)
    check = _load_check(args.check, tp.sha256)
    if not check["ok"]:
        problems = check.get("problems") or []
        first = problems[0] if problems and isinstance(problems[0], dict) else {}
        print(f"fabkit send: refusing to send: {args.check} reports {len(problems)} problem(s)"
              + (f", first at waypoint {first.get('waypoint')}: {first.get('kind')} {first.get('detail', '')}"
                 if first else ""), file=sys.stderr)
        write_report(args, {"ok": False, "sent": False, "reason": "check failed", "check": args.check})
        return 1
    settings = SendSettings(host=args.host, chunk=args.chunk, resume_from=args.resume_from,
                            power_on=args.power_on, unlock=args.unlock, stall_s=args.stall)
    if args.log:
        from fabkit.io.atomic import atomic_write

        with atomic_write(args.log) as fh:
            def log(event, fh=fh):
                fh.write(json.dumps(event, default=_plain) + "\n")
            result = _send(args, tp, settings, log, send_toolpath, SendError)
    else:
        result = _send(args, tp, settings, None, send_toolpath, SendError)
    n = len(tp)
    if result.ok:
        say(args, f"sent {n - args.resume_from} of {n} waypoints to {args.host} in {result.elapsed_s:.1f} s "
                  f"({result.chunks_sent} path chunk(s)); final pose off by {result.final_error_m * 1e3:.4f} mm, "
                  f"{result.final_error_rad * 1e3:.4f} mrad; path rounding <= {result.quantisation_m * 1e6:.2f} um")
    else:
        nxt = result.last_completed + 1
        print(f"fabkit send: stopped: {result.reason}; last completed waypoint {result.last_completed} of {n - 1}"
              + (f"; continue with --resume-from {nxt}" if 0 <= nxt < n else ""), file=sys.stderr)
    write_report(args, {"ok": result.ok, "sent": True, "host": args.host, "toolpath": args.toolpath,
                        "toolpath_sha256": tp.sha256, "resume_from": args.resume_from, **result.to_json()})
    return 0 if result.ok else 1


def _send(args, tp, settings, log, send_toolpath, SendError):
    n = len(tp)
    with progress(args, "sending", total=n) as advance:
        def on_progress(k, st):
            p = st.get("tcp_pose") or [0, 0, 0]
            advance(0, completed=k + 1, description=f"waypoint {k + 1}/{n} "
                    f"TCP {p[0]:+.3f} {p[1]:+.3f} {p[2]:+.3f} m")
        try:
            return send_toolpath(tp, settings, log=log, on_progress=on_progress)
        except SendError as exc:
            raise InputError(str(exc), source=args.toolpath) from None


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
