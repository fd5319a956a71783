"""Fault injection and inspection for tests: a line-based admin channel on loopback.

Not part of a real controller. One command per line, one JSON reply per line:

    state                        controller state (q, TCP pose, modes, log tail, ...)
    protective_stop [REASON]     protective stop now (safety mode PROTECTIVE_STOP, bits 2 and 10)
    estop | estop_release        robot emergency stop (bits 6, 7, 10) / release (robot powers off)
    program_stop                 stop the running program (as the Stop button)
    drop_rtde                    close every RTDE connection
    stall SECONDS                stop streaming RTDE data packages for SECONDS (connections stay open)
    slow DELAY_S [EVERY]         answer dashboard and RTDE setup requests DELAY_S late and send only
                                 every EVERY-th data package
    normal                       undo slow and stall
    at_progress N KIND [ARG]     run fault KIND when the async progress register reaches N
    after SECONDS KIND [ARG]     run fault KIND after SECONDS
    shutdown                     stop the stand-in

The same faults can be given at start-up with `--fault KIND[@progress=N|@t=SECONDS][:ARG]`.
"""
from __future__ import annotations

import json
import socket
import time

from sim.ursim.lines import serve_lines

FAULTS = ("protective_stop", "estop", "estop_release", "program_stop", "drop_rtde", "stall", "slow", "normal")


def apply_fault(ctrl, kind: str, arg: str | None = None) -> None:
    if kind == "protective_stop":
        ctrl.protective_stop(arg or "injected fault")
    elif kind == "estop":
        ctrl.emergency_stop(arg or "injected fault")
    elif kind == "estop_release":
        ctrl.release_emergency_stop()
    elif kind == "program_stop":
        ctrl.stop_program("stopped by the operator (injected fault)")
    elif kind == "drop_rtde":
        ctrl.log("injected fault: dropping every RTDE connection")
        for conn in list(ctrl.rtde_conns):
            conn.close()
    elif kind == "stall":
        seconds = float(arg) if arg else 3600.0
        ctrl.log(f"injected fault: RTDE streaming stalled for {seconds} s")
        ctrl.stall_until = time.monotonic() + seconds
    elif kind == "slow":
        parts = (arg or "0.5").split(",")
        ctrl.reply_delay = float(parts[0])
        ctrl.stream_decimate = max(1, int(parts[1])) if len(parts) > 1 else 1
        ctrl.log(f"injected fault: slow controller (delay {ctrl.reply_delay} s, every {ctrl.stream_decimate})")
    elif kind == "normal":
        ctrl.reply_delay, ctrl.stream_decimate, ctrl.stall_until = 0.0, 1, 0.0
    else:
        raise ValueError(f"unknown fault {kind!r}; known: {', '.join(FAULTS)}")


def parse_fault_option(text: str) -> dict:
    """`KIND[@progress=N|@t=SECONDS][:ARG]` -> a scheduled-fault dict."""
    head, _, arg = text.partition(":")
    kind, _, when = head.partition("@")
    if kind not in FAULTS:
        raise ValueError(f"unknown fault {kind!r}; known: {', '.join(FAULTS)}")
    fault = {"kind": kind, "arg": arg or None}
    if when.startswith("progress="):
        fault["at_progress"] = int(when[9:])
    elif when.startswith("t="):
        fault["at_time"] = time.monotonic() + float(when[2:])
    elif when:
        raise ValueError(f"bad fault trigger {when!r} (use @progress=N or @t=SECONDS)")
    else:
        fault["at_time"] = time.monotonic()
    return fault


def handle(ctrl, line: str, shutdown) -> dict:
    words = line.split()
    if not words:
        return {"ok": False, "error": "empty command"}
    cmd, rest = words[0], words[1:]
    try:
        if cmd == "state":
            return {"ok": True, "state": ctrl.state()}
        if cmd == "shutdown":
            shutdown()
            return {"ok": True}
        if cmd == "at_progress":
            ctrl.schedule_fault({"kind": rest[1], "arg": " ".join(rest[2:]) or None, "at_progress": int(rest[0])})
            return {"ok": True}
        if cmd == "after":
            ctrl.schedule_fault({"kind": rest[1], "arg": " ".join(rest[2:]) or None,
                                 "at_time": time.monotonic() + float(rest[0])})
            return {"ok": True}
        if cmd == "slow":
            apply_fault(ctrl, "slow", ",".join(rest))
            return {"ok": True}
        apply_fault(ctrl, cmd, " ".join(rest) or None)
        return {"ok": True}
    except (ValueError, IndexError) as exc:
        return {"ok": False, "error": str(exc)}


def serve_admin(ctrl, listener: socket.socket, shutdown) -> None:
    """Answer admin commands, one JSON reply per line."""
    serve_lines(ctrl, listener, "admin", lambda text: (json.dumps(handle(ctrl, text, shutdown)), False))


def admin_request(host: str, line: str, port: int = 30020, timeout: float = 5.0) -> dict:
    """Send one admin command and return the JSON reply (for tests and the CLI)."""
    with socket.create_connection((host, port), timeout=timeout) as sock:
        sock.sendall((line + "\n").encode())
        buf = b""
        while b"\n" not in buf:
            data = sock.recv(65536)
            if not data:
                raise ConnectionError("admin channel closed without a reply")
            buf += data
    return json.loads(buf.split(b"\n", 1)[0])
