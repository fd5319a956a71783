"""Script ports (30001 primary, 30002 secondary, 30003 real-time) of the controller stand-in.

Clients write URScript text. A program starts with `def`/`sec` in column 0 and ends with `end` in
column 0 (URScript manual, "Connecting to URControl"); the text is buffered until then. ur_rtde's
control script becomes a `ControlScript`; anything else is compiled by `urscript` and run, or,
when it does not compile, refused with the error in the controller log and the running program
stopped, as a controller does. A bare statement line outside a program runs as a one-line program.
The stand-in sends nothing on these ports (ur_rtde never reads them).
"""
from __future__ import annotations

import re
import socket
import threading
import time

from sim.ursim.control_script import ControlScript, is_control_script
from sim.ursim.urscript import ScriptError, URScriptProgram, parse_program

_END = re.compile(r"^end\s*$", re.M)
_START = re.compile(r"^(def|sec)\s", re.M)


class _Rejected:
    """Placeholder program for a refused script."""

    running = False

    def __init__(self, name):
        self.name = name

    def kill(self, reason):
        pass


def program_from_text(ctrl, text: str, name: str = "<script>"):
    """A runnable program for `text`, or a `_Rejected` after logging the compile error."""
    try:
        if is_control_script(text):
            return ControlScript(ctrl, text)
        prog_name, statements = parse_program(text)
        return URScriptProgram(ctrl, prog_name if prog_name != "<statement>" else name, statements)
    except ScriptError as exc:
        ctrl.log(f"compile error in {name}: {exc}")
        with ctrl.lock:
            ctrl.last_error = f"compile error: {exc}"
        return _Rejected(name)


#: A controller stops the running program when a new one arrives, then needs a moment to compile
#: and start it (tens of ms for ur_rtde's 40-50 KB script); the stand-in waits this long (s).
COMPILE_DELAY_S = 0.04


def run_text(ctrl, text: str, port: int) -> None:
    program = program_from_text(ctrl, text, f"port {port}")
    if isinstance(program, _Rejected):
        ctrl.stop_program("a program that does not compile was sent")
        return
    ctrl.log(f"port {port}: program {program.name} received ({len(text)} bytes)")
    with ctrl.lock:
        if ctrl.program is not None and ctrl.program.running:
            ctrl.stop_program("replaced by a new program")
    time.sleep(COMPILE_DELAY_S)
    ctrl.start_program(program)


def split_programs(buf: str) -> tuple[list[str], str]:
    """Complete programs (or bare statement lines) at the front of `buf`, and the rest."""
    out = []
    while buf:
        stripped = buf.lstrip("\r\n")
        if not stripped:
            return out, ""
        buf = stripped
        if _START.match(buf):
            m = _END.search(buf)
            if not m:
                return out, buf
            end = m.end()
            nl = buf.find("\n", end)
            end = len(buf) if nl < 0 else nl + 1
            out.append(buf[:end])
            buf = buf[end:]
        else:
            nl = buf.find("\n")
            if nl < 0:
                return out, buf
            out.append(buf[:nl + 1])
            buf = buf[nl + 1:]
    return out, ""


def serve_script_port(ctrl, listener: socket.socket, port: int) -> None:
    def client(sock: socket.socket) -> None:
        buf = ""
        with sock:
            while not ctrl.stopped:
                try:
                    data = sock.recv(65536)
                except OSError:
                    return
                if not data:
                    break
                buf += data.decode("utf-8", "replace")
                programs, buf = split_programs(buf)
                for text in programs:
                    if text.strip():
                        run_text(ctrl, text, port)
        if buf.strip():
            ctrl.log(f"port {port}: incomplete program discarded at disconnect ({len(buf)} bytes)")

    while not ctrl.stopped:
        try:
            sock, _ = listener.accept()
        except OSError:
            return
        threading.Thread(target=client, args=(sock,), name=f"script-{port}", daemon=True).start()
