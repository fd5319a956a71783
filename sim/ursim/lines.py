"""Newline-terminated text protocols (dashboard, admin channel): one thread per client, bounded lines."""
from __future__ import annotations

import socket
from typing import Callable

from sim.ursim.clients import MAX_LINE, LineReader, accept_loop


def serve_lines(ctrl, listener: socket.socket, name: str, answer: Callable[[str], tuple[str | None, bool]],
                banner: str | None = None, too_long: Callable[[str], str] | None = None) -> None:
    """Accept clients until `ctrl.stopped` or the listener closes; answer every line.

    `answer(text)` gets one stripped line and returns `(reply, close)`: `reply` None sends nothing;
    `close` ends that client after the reply. A line over `MAX_LINE` bytes gets `too_long(start of
    the line)` and the client is closed.
    """
    def client(sock: socket.socket) -> None:
        if banner is not None:
            sock.sendall((banner + "\n").encode())
        reader = LineReader(MAX_LINE)
        while not ctrl.stopped:
            try:
                data = sock.recv(65536)
            except OSError:
                return
            if not data:
                return
            for line in reader.feed(data):
                reply, close = answer(line.decode("utf-8", "replace").strip())
                if reply is None:
                    continue
                sock.sendall((reply + "\n").encode())
                if close:
                    return
            if reader.overflow:
                ctrl.log(f"{name}: line over {MAX_LINE} bytes: closing the client")
                if too_long is not None:
                    sock.sendall((too_long(reader.head()) + "\n").encode())
                return

    accept_loop(ctrl, listener, name, client)
