"""Script ports (30001 primary, 30002 secondary, 30003 real-time) of the controller stand-in: the
URScript they accept.

Clients write URScript text. A program starts with `def`/`sec` in column 0 and ends with `end` in
column 0 (URScript manual, "Connecting to URControl"); the text is buffered until then. ur_rtde's
control script becomes a `ControlScript`; anything else is compiled by `urscript` and run, or,
when it does not compile, refused with the error in the controller log and the running program
stopped, as a controller does. A bare statement line outside a program runs as a one-line program.
A line over `MAX_SCRIPT_LINE` bytes or a program over `MAX_SCRIPT` bytes is refused the same way
and the connection is closed. What the ports send (robot state, the real-time package) is
`client_interfaces`.
"""
from __future__ import annotations

import re
import socket
from collections import deque

from sim.ursim.control_script import ControlScript, is_control_script
from sim.ursim.urscript import ScriptError, URScriptProgram, parse_program

#: Longest program accepted on a script port (bytes): ur_rtde's control script is 40-50 KB.
MAX_SCRIPT = 4 << 20
#: Longest line of a script (bytes).
MAX_SCRIPT_LINE = 64 << 10


def program_from_text(ctrl, text: str, name: str = "<script>"):
    """A runnable program for `text`, or None after logging the compile error."""
    try:
        if is_control_script(text):
            return ControlScript(ctrl, text)
        prog_name, statements = parse_program(text)
        return URScriptProgram(ctrl, prog_name if prog_name != "<statement>" else name, statements)
    except ScriptError as exc:
        refuse(ctrl, f"compile error in {name}: {exc}")
        return None


def refuse(ctrl, text: str) -> None:
    ctrl.log(text)
    with ctrl.lock:
        ctrl.last_error = text


#: A controller stops the running program when a new one arrives, then needs a moment to compile
#: and start it (tens of ms for ur_rtde's 40-50 KB script); the stand-in waits this long (s).
COMPILE_DELAY_S = 0.04


class ScriptFramer:
    """Cuts a script stream into programs (or bare statement lines). Inside a program the closing
    `end` is found with `bytes.find` over each new block (no per-line Python work, no rescans), so
    a multi-megabyte upload costs the stand-in little time under the GIL.

    `feed(data)` returns the complete texts; `error` is set (and nothing more is read) once an
    unterminated line or a program passes its limit."""

    _END_LINE = re.compile(rb"^end[ \t\r]*$", re.M)
    _START_LINE = re.compile(rb"(def|sec)\s")

    def __init__(self, max_script: int = MAX_SCRIPT, max_line: int = MAX_SCRIPT_LINE):
        self.max_script, self.max_line = max_script, max_line
        self._partial = b""
        self._program: list[bytes] | None = None  # the open program's blocks
        self._size = 0
        self.error: str | None = None

    @property
    def pending(self) -> int:
        """Bytes of an unfinished program or line."""
        return self._size + len(self._partial)

    def feed(self, data: bytes) -> list[str]:
        if self.error:
            return []
        buf = self._partial + data if self._partial else data
        cut = buf.rfind(b"\n") + 1  # complete lines: buf[:cut]
        self._partial = buf[cut:]
        out: list[str] = []
        self._take(buf, cut, out)
        if self.error is None and len(self._partial) > self.max_line:
            self.error = f"script line over {self.max_line} bytes"
        return out

    def _take(self, block: bytes, stop: int, out: list[str]) -> None:
        """Take the complete lines `block[:stop]` (no copy of the block is made)."""
        pos = 0
        while pos < stop and self.error is None:
            if self._program is None:
                nl = block.index(b"\n", pos, stop) + 1
                line = block[pos:nl]
                pos = nl
                if not line.strip():
                    continue
                if self._START_LINE.match(line):
                    self._program, self._size = [], 0
                    self._add(line)
                else:
                    out.append(line.decode("utf-8", "replace"))  # a bare statement runs as a program
                continue
            found = self._end_line(block, pos, stop)
            end = stop if found is None else found
            self._add(block[pos:end])
            pos = end
            if found is not None and self.error is None:
                out.append(b"".join(self._program).decode("utf-8", "replace"))
                self._program, self._size = None, 0

    def _end_line(self, block: bytes, pos: int, stop: int) -> int | None:
        """The index after the first `end` line in `block[pos:stop]` (`pos` a line start), or None.
        Candidates are found with bytes.find at C speed: `end` is rarer than the newline before
        it, so it is the needle."""
        start = pos
        while True:
            j = block.find(b"end", start, stop)
            if j < 0:
                return None
            if j == pos or block[j - 1] == 0x0A:  # at a line start
                nl = block.index(b"\n", j, stop)
                if self._END_LINE.match(block, j, nl):
                    return nl + 1
            start = j + 3

    def _add(self, chunk: bytes) -> None:
        self._program.append(chunk)
        self._size += len(chunk)
        if self._size > self.max_script:
            self.error = f"program over {self.max_script} bytes"


#: Programs of one client waiting for the one before them to start; more and the client is not read.
MAX_QUEUED = 64


class ScriptHandler:
    """One client of a script port: what the port streams (client_interfaces) plus the URScript
    it writes. Each complete text is compiled at once; a program replaces the running one after
    `COMPILE_DELAY_S`, and the client's next texts wait for that (in order, as on a controller)."""

    def __init__(self, ctrl, key: str, port: int):
        self.ctrl, self.key, self.port = ctrl, key, port
        self.framer = ScriptFramer()
        self.queue: deque[str] = deque()
        self.starting = False
        self.stream = None

    def on_open(self, conn) -> None:
        from sim.ursim import client_interfaces as ci

        self.stream = ci.Stream(conn.sock, self.key)
        if self.key != "realtime":
            self.stream.offer(ci.version_message(self.ctrl) + ci.robot_state_message(self.ctrl))
        with self.ctrl.lock:
            self.ctrl.interface_streams.append(self.stream)

    def on_data(self, conn, data: bytes) -> None:
        self.queue.extend(self.framer.feed(data))
        self._run_queued(conn)
        if self.framer.error:
            refuse(self.ctrl, f"port {self.port}: {self.framer.error}: program refused, connection closed")
            self.ctrl.stop_program("a program that does not compile was sent")
            conn.close_after_writes()

    def _run_queued(self, conn) -> None:
        ctrl = self.ctrl
        while self.queue and not self.starting:
            text = self.queue.popleft()
            program = program_from_text(ctrl, text, f"port {self.port}")
            if program is None:
                ctrl.stop_program("a program that does not compile was sent")
                continue
            ctrl.log(f"port {self.port}: program {program.name} received ({len(text)} bytes)")
            if getattr(program, "secondary", False):
                program.run_beside()
                continue
            with ctrl.lock:
                if ctrl.program is not None and ctrl.program.running:
                    ctrl.stop_program("replaced by a new program")
            self.starting = True
            conn.loop.call_later(COMPILE_DELAY_S, lambda: self._start(conn, program))
        conn.pause_reading(len(self.queue) >= MAX_QUEUED)

    def _start(self, conn, program) -> None:
        self.starting = False
        if not self.ctrl.stopped:
            self.ctrl.start_program(program)
            self._run_queued(conn)

    def on_close(self, conn) -> None:
        with self.ctrl.lock:
            if self.stream in self.ctrl.interface_streams:
                self.ctrl.interface_streams.remove(self.stream)
        if self.framer.pending:
            self.ctrl.log(f"port {self.port}: incomplete program discarded at disconnect ({self.framer.pending} bytes)")


def serve_script_port(ctrl, loop, listener: socket.socket, key: str, port: int) -> None:
    """Serve one script port from the I/O loop `loop`."""
    loop.listen(listener, key, lambda sock: ScriptHandler(ctrl, key, port))
