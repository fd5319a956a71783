"""Newline-terminated text protocols (dashboard, admin channel): bounded lines, served by the
stand-in's I/O loop (io_loop.py)."""
from __future__ import annotations

import socket
from typing import Callable

from sim.ursim.clients import MAX_LINE, LineReader


class LineHandler:
    """One client of a line protocol.

    `answer(text)` gets one stripped line and returns `(reply, close)`: `reply` None sends nothing;
    `close` ends that client after the reply. `delay()` is how late the controller answers (the
    `slow` fault; 0 normally). A line over `MAX_LINE` bytes gets `too_long(start of the line)` and
    the client is closed.
    """

    def __init__(self, ctrl, name: str, answer: Callable[[str], tuple[str | None, bool]],
                 banner: str | None = None, too_long: Callable[[str], str] | None = None,
                 delay: Callable[[], float] = lambda: 0.0):
        self.ctrl, self.name, self.answer = ctrl, name, answer
        self.banner, self.too_long, self.delay = banner, too_long, delay
        self.reader = LineReader(MAX_LINE)

    def on_open(self, conn) -> None:
        if self.banner is not None:
            conn.write((self.banner + "\n").encode())

    def on_data(self, conn, data: bytes) -> None:
        for line in self.reader.feed(data):
            reply, close = self.answer(line.decode("utf-8", "replace").strip())
            if reply is not None:
                conn.write((reply + "\n").encode(), self.delay())
            if close:
                conn.close_after_writes()
                return
        if self.reader.overflow:
            self.ctrl.log(f"{self.name}: line over {MAX_LINE} bytes: closing the client")
            if self.too_long is not None:
                conn.write((self.too_long(self.reader.head()) + "\n").encode())
            conn.close_after_writes()

    def on_close(self, conn) -> None:
        pass


def serve_lines(ctrl, loop, listener: socket.socket, name: str, answer, banner=None, too_long=None,
                delay: Callable[[], float] = lambda: 0.0) -> None:
    """Serve a line protocol on `listener` from the I/O loop `loop`."""
    loop.listen(listener, name, lambda sock: LineHandler(ctrl, name, answer, banner, too_long, delay))
