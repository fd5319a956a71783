"""Client connections of the stand-in: a cap per port, one registry that shutdown closes, and
bounded line framing for the text ports (the I/O loop, io_loop.py, serves them)."""
from __future__ import annotations

import socket
import threading

#: Clients served at once on one port; a client over the cap is accepted and closed at once.
MAX_CLIENTS_PER_PORT = 32
#: Longest dashboard / admin line (bytes, newline excluded).
MAX_LINE = 4096


class Clients:
    """The open client sockets of every port, under a lock of their own: a burst of connects and
    disconnects must not queue on `Controller.lock`, which the tick takes every period."""

    def __init__(self, ctrl, limit: int = MAX_CLIENTS_PER_PORT):
        self.ctrl = ctrl
        self.limit = limit
        self._open: dict[str, set] = {}
        self.closed = False
        self._lock = threading.Lock()

    def admit(self, port: str, sock: socket.socket) -> bool:
        with self._lock:
            conns = self._open.setdefault(port, set())
            if self.closed or len(conns) >= self.limit:
                return False
            conns.add(sock)
            return True

    def release(self, port: str, sock: socket.socket) -> None:
        with self._lock:
            self._open.get(port, set()).discard(sock)

    def count(self, port: str | None = None) -> int:
        with self._lock:
            return sum(len(v) for k, v in self._open.items() if port is None or k == port)

    def close_all(self) -> None:
        with self._lock:
            self.closed = True
            socks = [s for conns in self._open.values() for s in conns]
            self._open.clear()
        for s in socks:
            close_socket(s)


def close_socket(sock: socket.socket) -> None:
    for op in (lambda: sock.shutdown(socket.SHUT_RDWR), sock.close):  # shutdown wakes a blocked recv()
        try:
            op()
        except OSError:
            pass


class LineReader:
    """Splits a byte stream into lines, scanning each byte once. Once a line passes `limit` bytes,
    `overflow` is set and nothing more is read (the caller answers with the error and closes)."""

    def __init__(self, limit: int = MAX_LINE):
        self.limit = limit
        self.overflow = False
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[bytes]:
        lines, start = [], 0
        while not self.overflow:
            nl = data.find(b"\n", start)
            if nl < 0:
                self._buf += data[start:start + self.limit + 1 - len(self._buf)]
                self.overflow = len(self._buf) > self.limit
                break
            if len(self._buf) + nl - start > self.limit:
                self.overflow = True
                break
            self._buf += data[start:nl]
            lines.append(bytes(self._buf))
            self._buf.clear()
            start = nl + 1
        return lines

    def head(self, n: int = 40) -> str:
        """The first `n` characters of the line being read (for error replies)."""
        return bytes(self._buf[:n]).decode("utf-8", "replace")
