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
    digital_in N 0|1             set standard digital input N (0-7), as a wire into the controller would
    io_stall SECONDS             block the stand-in's own network thread for SECONDS (at most 5): the
                                 stand-in starved of CPU, to test that its client is not blamed
    record [clear]               the motion and tool commands received so far (see
                                 `Controller.record`), or forget them
    shutdown                     stop the stand-in

A fault with an unknown name or a malformed argument is answered `{"ok": false, "error": ...}` and
nothing is scheduled; a line over `clients.MAX_LINE` bytes gets an error reply and is closed.

The same faults can be given at start-up with `--fault KIND[@progress=N|@t=SECONDS][:ARG]`.
"""
from __future__ import annotations

import json
import socket
import time

from sim.ursim.clients import MAX_LINE
from sim.ursim.lines import serve_lines

FAULTS = ("protective_stop", "estop", "estop_release", "program_stop", "drop_rtde", "stall", "slow", "normal")
#: Faults that take a free-text reason as their argument; the others take none or a number.
_TEXT_ARG = ("protective_stop", "estop")
_NO_ARG = ("estop_release", "program_stop", "drop_rtde", "normal")
#: Longest stall or reply delay the admin channel accepts (s).
MAX_DELAY_S = 3600.0
#: Longest `io_stall` (s): the stand-in's own network thread blocked, to test it is not blamed on the client.
MAX_IO_STALL_S = 5.0


def _seconds(text: str, what: str, allow_zero: bool = True) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{what}: expected seconds, got {text!r}") from None
    if not (0.0 <= value <= MAX_DELAY_S) or (value == 0.0 and not allow_zero):
        raise ValueError(f"{what}: {text} s is outside {'[' if allow_zero else '('}0, {MAX_DELAY_S:g}]")
    return value


def validate_fault(kind: str, arg: str | None) -> str | None:
    """The normalised argument of fault `kind`, or ValueError naming what is wrong (nothing is
    scheduled or applied with a bad fault)."""
    if kind not in FAULTS:
        raise ValueError(f"unknown fault {kind!r}; known: {', '.join(FAULTS)}")
    if kind in _TEXT_ARG:
        return arg[:200] if arg else None
    if kind in _NO_ARG:
        if arg:
            raise ValueError(f"{kind} takes no argument (got {arg!r})")
        return None
    if kind == "stall":
        if arg:
            _seconds(arg, "stall", allow_zero=False)
        return arg or None
    parts = (arg or "0.5").split(",")  # slow DELAY[,EVERY]
    if len(parts) > 2:
        raise ValueError(f"slow: expected DELAY[,EVERY], got {arg!r}")
    delay = _seconds(parts[0], "slow delay")
    every = 1
    if len(parts) == 2:
        try:
            every = int(parts[1])
        except ValueError:
            every = 0
        if not 1 <= every <= 10000:
            raise ValueError(f"slow: EVERY must be an integer in 1-10000, got {parts[1]!r}")
    return f"{delay!r},{every}"


def apply_fault(ctrl, kind: str, arg: str | None = None) -> None:
    """Apply a fault now (call with an argument from `validate_fault`)."""
    arg = validate_fault(kind, arg)
    with ctrl.lock:
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
            conns = list(ctrl.rtde_conns)
        elif kind == "stall":
            seconds = float(arg) if arg else MAX_DELAY_S
            ctrl.log(f"injected fault: RTDE streaming stalled for {seconds} s")
            ctrl.stall_until = time.monotonic() + seconds
        elif kind == "slow":
            delay, every = arg.split(",")
            ctrl.reply_delay, ctrl.stream_decimate = float(delay), int(every)
            ctrl.log(f"injected fault: slow controller (delay {ctrl.reply_delay} s, every {ctrl.stream_decimate})")
        else:  # normal
            ctrl.reply_delay, ctrl.stream_decimate, ctrl.stall_until = 0.0, 1, 0.0
    if kind == "drop_rtde":
        for conn in conns:  # outside the lock: closing waits for nothing, but keeps the rule simple
            conn.close()


def parse_fault_option(text: str) -> dict:
    """`KIND[@progress=N|@t=SECONDS][:ARG]` -> a scheduled-fault dict (ValueError if malformed)."""
    head, _, arg = text.partition(":")
    kind, _, when = head.partition("@")
    if when.startswith("progress="):
        return make_fault(kind, arg or None, at_progress=when[9:])
    if when.startswith("t="):
        return make_fault(kind, arg or None, after=when[2:])
    if when:
        raise ValueError(f"bad fault trigger {when!r} (use @progress=N or @t=SECONDS)")
    return make_fault(kind, arg or None, after="0")


def make_fault(kind: str, arg: str | None, at_progress: str | None = None, after: str | None = None) -> dict:
    """A validated scheduled fault: run `kind` when the async progress reaches `at_progress`, or
    `after` seconds from now."""
    fault = {"kind": kind, "arg": validate_fault(kind, arg)}
    if at_progress is not None:
        try:
            n = int(at_progress)
        except ValueError:
            n = -1
        if not 0 <= n <= 32767:
            raise ValueError(f"progress must be an integer in 0-32767 (the progress register), got {at_progress!r}")
        fault["at_progress"] = n
    else:
        fault["at_time"] = time.monotonic() + _seconds(after, "after")
    return fault


def handle(ctrl, line: str, shutdown, stall_io=None) -> dict:
    """One admin command -> its JSON reply. `stall_io(seconds)` blocks the stand-in's network thread
    (the `io_stall` command: the stand-in starved of CPU, not a controller fault)."""
    words = line.split()
    if not words:
        return {"ok": False, "error": "empty command"}
    cmd, rest = words[0], words[1:]
    try:
        if cmd == "state":
            return {"ok": True, "state": ctrl.state()}
        if cmd == "record":
            if rest == ["clear"]:
                ctrl.clear_record()
                return {"ok": True}
            if rest:
                raise ValueError("usage: record | record clear")
            return {"ok": True, "commands": ctrl.recorded()}
        if cmd == "shutdown":
            shutdown()
            return {"ok": True}
        if cmd == "digital_in":
            if len(rest) != 2 or rest[0] not in tuple("01234567") or rest[1] not in ("0", "1"):
                raise ValueError("usage: digital_in N 0|1 (N a standard digital input 0-7)")
            with ctrl.lock:
                bit = 1 << int(rest[0])
                ctrl.digital_in = (ctrl.digital_in | bit) if rest[1] == "1" else (ctrl.digital_in & ~bit)
            return {"ok": True}
        if cmd in ("at_progress", "after"):
            if len(rest) < 2:
                raise ValueError(f"usage: {cmd} {'N' if cmd == 'at_progress' else 'SECONDS'} KIND [ARG]")
            arg = " ".join(rest[2:]) or None
            if cmd == "at_progress":
                ctrl.schedule_fault(make_fault(rest[1], arg, at_progress=rest[0]))
            else:
                ctrl.schedule_fault(make_fault(rest[1], arg, after=rest[0]))
            return {"ok": True}
        if cmd == "slow":
            apply_fault(ctrl, "slow", ",".join(rest) or None)
            return {"ok": True}
        if cmd == "io_stall" and stall_io is not None:
            if len(rest) != 1:
                raise ValueError("usage: io_stall SECONDS")
            seconds = _seconds(rest[0], "io_stall", allow_zero=False)
            if seconds > MAX_IO_STALL_S:
                raise ValueError(f"io_stall: at most {MAX_IO_STALL_S:g} s")
            ctrl.log(f"injected: the stand-in's network thread stalls for {seconds:g} s")
            stall_io(seconds)
            return {"ok": True}
        apply_fault(ctrl, cmd, " ".join(rest) or None)
        return {"ok": True}
    except ValueError as exc:
        return {"ok": False, "error": str(exc)}


def serve_admin(ctrl, loop, listener: socket.socket, shutdown) -> None:
    """Answer admin commands, one JSON reply per line (from the I/O loop `loop`)."""
    def stall_io(seconds: float) -> None:  # after this reply has gone out
        loop.call_later(0.0, lambda: time.sleep(seconds))

    serve_lines(ctrl, loop, listener, "admin",
                lambda text: (json.dumps(handle(ctrl, text, shutdown, stall_io)), False),
                too_long=lambda head: json.dumps({"ok": False, "error": f"line over {MAX_LINE} bytes"}))


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
