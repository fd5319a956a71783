"""Newline-terminated text protocols (dashboard, admin channel): one thread per client.

Written by hand: the standard library's socketserver would bring its own shutdown model, while the
stand-in stops every server through `ctrl.stopped` and a closed listener.
"""
from __future__ import annotations

import socket
import threading
from typing import Callable


def serve_lines(ctrl, listener: socket.socket, name: str, answer: Callable[[str], tuple[str | None, bool]],
                banner: str | None = None) -> None:
    """Accept clients until `ctrl.stopped` or the listener closes; answer every line.

    `answer(text)` gets one stripped line and returns `(reply, close)`: `reply` None sends nothing;
    `close` ends that client after the reply.
    """
    def client(sock: socket.socket) -> None:
        with sock:
            if banner is not None:
                sock.sendall((banner + "\n").encode())
            buf = b""
            while not ctrl.stopped:
                try:
                    data = sock.recv(4096)
                except OSError:
                    return
                if not data:
                    return
                buf += data
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    reply, close = answer(line.decode("utf-8", "replace").strip())
                    if reply is None:
                        continue
                    try:
                        sock.sendall((reply + "\n").encode())
                    except OSError:
                        return
                    if close:
                        return

    while not ctrl.stopped:
        try:
            sock, _ = listener.accept()
        except OSError:
            return
        threading.Thread(target=client, args=(sock,), name=name, daemon=True).start()
