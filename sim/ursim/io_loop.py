"""The stand-in's one network thread: every listener and every client socket of every port.

A thread per client made a burst of connects or disconnects (50 at once on each port) a storm of
thread starts and exits, each fighting the 500 Hz tick thread for the GIL; the RTDE stream then
missed periods. Here one `selectors` loop accepts, reads and writes every client without
blocking, and the tick thread is the only other thread that runs every period. What a port does
with its bytes is a `Handler` (dashboard and admin lines, URScript on the script ports, RTDE
frames); handlers must not block: a reply that the controller would give late is written later
(`Connection.write(data, delay)`), and work that takes time is scheduled with `call_later`.

Written by hand: asyncio would bring its own event-loop model into a stand-in whose programs are
blocking threads (as on a controller), and socketserver is a thread or a process per client.
"""
from __future__ import annotations

import heapq
import itertools
import selectors
import socket
import threading
import time
from collections import deque
from typing import Callable, Protocol

#: Bytes a client may leave unread before the stand-in closes it (it has stopped reading).
MAX_OUTPUT = 1 << 20
#: Longest wait in one `select` (s): how fast the loop notices `stop()` without a wake-up.
POLL_S = 0.05


class Handler(Protocol):
    def on_open(self, conn: "Connection") -> None: ...
    def on_data(self, conn: "Connection", data: bytes) -> None: ...
    def on_close(self, conn: "Connection") -> None: ...


class Connection:
    """One client socket: non-blocking writes with a bounded output buffer, replies kept in order
    when some are delayed, and a close that first sends what was written."""

    def __init__(self, loop: "IOLoop", sock: socket.socket, port: str, handler: Handler):
        self.loop, self.sock, self.port, self.handler = loop, sock, port, handler
        self.out = bytearray()
        self.closed = False
        self.closing = False
        self.paused = False
        self._due = 0.0  # the time of the last delayed write: later ones never overtake it

    def write(self, data: bytes, delay: float = 0.0) -> None:
        """Send `data` now, or after `delay` seconds (and after every earlier delayed write)."""
        if self.closed or self.closing:
            return
        now = time.monotonic()
        if delay > 0 or self._due > now:
            self._due = max(now + delay, self._due)
            self.loop.call_at(self._due, lambda: self._write_now(data))
            return
        self._write_now(data)

    def close_after_writes(self) -> None:
        """Close once every write so far (delayed ones included) has gone out."""
        now = time.monotonic()
        if self._due > now:
            self.loop.call_at(self._due, self._begin_close)
        else:
            self._begin_close()

    def _begin_close(self) -> None:
        self.closing = True
        self.loop.flush(self)

    def _write_now(self, data: bytes) -> None:
        if self.closed:
            return
        self.out += data
        self.loop.flush(self)

    def pause_reading(self, paused: bool) -> None:
        """Stop (or resume) reading this client: back-pressure while its work is queued."""
        if paused != self.paused and not self.closed:
            self.paused = paused
            self.loop.update_events(self)


class IOLoop:
    """Accept and serve clients of every port in one thread (`start()`), until `stop()`."""

    def __init__(self, ctrl):
        self.ctrl = ctrl
        self.sel = selectors.DefaultSelector()
        self._timers: list = []
        self._seq = itertools.count()
        self._calls: deque = deque()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self.sel.register(self._wake_r, selectors.EVENT_READ, ("wake", None))
        self._stop = threading.Event()
        self._conns: set[Connection] = set()
        self._thread = threading.Thread(target=self._run, name="ursim-io", daemon=True)

    # ---- set-up (before start) -----------------------------------------------------------------
    def listen(self, listener: socket.socket, port: str, make_handler: Callable[[socket.socket], Handler]) -> None:
        listener.setblocking(False)
        self.sel.register(listener, selectors.EVENT_READ, ("listen", (port, make_handler)))

    def start(self) -> None:
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the loop; it closes every client and listener socket before it ends."""
        self._stop.set()
        self._wake()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    # ---- from any thread -----------------------------------------------------------------------
    def call_soon_threadsafe(self, fn: Callable[[], None]) -> None:
        self._calls.append(fn)
        self._wake()

    def _wake(self) -> None:
        try:
            self._wake_w.send(b"\0", socket.MSG_DONTWAIT)
        except (BlockingIOError, OSError):
            pass  # a wake-up is pending already, or the loop has ended

    # ---- loop thread only ----------------------------------------------------------------------
    def call_at(self, when: float, fn: Callable[[], None]) -> None:
        heapq.heappush(self._timers, (when, next(self._seq), fn))

    def call_later(self, delay: float, fn: Callable[[], None]) -> None:
        self.call_at(time.monotonic() + delay, fn)

    def flush(self, conn: Connection) -> None:
        """Write what `conn` can take now; the rest waits for EVENT_WRITE."""
        while conn.out and not conn.closed:
            try:
                n = conn.sock.send(conn.out, socket.MSG_DONTWAIT)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                self.close(conn)
                return
            del conn.out[:n]
        if conn.closed:
            return
        if len(conn.out) > MAX_OUTPUT:
            self.ctrl.log(f"{conn.port} client: not reading ({len(conn.out)} bytes unsent): closing")
            self.close(conn)
        elif conn.closing and not conn.out:
            self.close(conn)
        else:
            self.update_events(conn)

    def update_events(self, conn: Connection) -> None:
        events = (0 if conn.paused or conn.closing else selectors.EVENT_READ) | \
                 (selectors.EVENT_WRITE if conn.out else 0)
        try:
            if events:
                self.sel.modify(conn.sock, events, ("client", conn))
            else:
                self.sel.unregister(conn.sock)
        except KeyError:
            if events:
                self.sel.register(conn.sock, events, ("client", conn))
        except (ValueError, OSError):
            self.close(conn)

    def close(self, conn: Connection) -> None:
        if conn.closed:
            return
        conn.closed = True
        self._conns.discard(conn)
        try:
            self.sel.unregister(conn.sock)
        except (KeyError, ValueError, OSError):
            pass
        try:
            conn.handler.on_close(conn)
        except Exception as exc:
            self.ctrl.log(f"{conn.port} client: {type(exc).__name__} on close: {exc}")
        self.ctrl.clients.release(conn.port, conn.sock)
        for op in (lambda: conn.sock.shutdown(socket.SHUT_RDWR), conn.sock.close):
            try:
                op()
            except OSError:
                pass

    def _accept(self, listener: socket.socket, port: str, make_handler) -> None:
        for _ in range(64):  # a burst is taken in one go, but the loop stays responsive
            try:
                sock, _ = listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                try:
                    self.sel.unregister(listener)
                except (KeyError, ValueError):
                    pass
                return
            if not self.ctrl.clients.admit(port, sock):
                self.ctrl.log(f"{port}: more than {self.ctrl.clients.limit} clients: connection refused")
                sock.close()
                continue
            sock.setblocking(False)
            conn = Connection(self, sock, port, None)
            self._conns.add(conn)
            try:
                conn.handler = make_handler(sock)
                self.sel.register(sock, selectors.EVENT_READ, ("client", conn))
                conn.handler.on_open(conn)
            except Exception as exc:  # one client's bug must not reach the others
                self.ctrl.log(f"{port} client: {type(exc).__name__}: {exc}: closing")
                self.close(conn)

    def _read(self, conn: Connection) -> None:
        try:
            data = conn.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self.close(conn)
            return
        try:
            conn.handler.on_data(conn, data)
        except Exception as exc:  # one client's bug or bad bytes must not reach the others
            self.ctrl.log(f"{conn.port} client: {type(exc).__name__}: {exc}: closing")
            self.close(conn)

    def _run_due(self) -> float:
        """Run due timers and calls; the time until the next timer (capped at POLL_S)."""
        while self._calls:
            self._guarded(self._calls.popleft())
        now = time.monotonic()
        while self._timers and self._timers[0][0] <= now:
            self._guarded(heapq.heappop(self._timers)[2])
        return min(POLL_S, max(0.0, self._timers[0][0] - time.monotonic())) if self._timers else POLL_S

    def _guarded(self, fn) -> None:
        try:
            fn()
        except Exception as exc:
            self.ctrl.log(f"stand-in I/O: {type(exc).__name__}: {exc}")

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                timeout = self._run_due()
                for key, events in self.sel.select(timeout):
                    kind, data = key.data
                    if kind == "wake":
                        try:
                            while self._wake_r.recv(4096):
                                pass
                        except (BlockingIOError, OSError):
                            pass
                    elif kind == "listen":
                        self._accept(key.fileobj, *data)
                    else:
                        conn = data
                        if events & selectors.EVENT_WRITE and not conn.closed:
                            self.flush(conn)
                        if events & selectors.EVENT_READ and not conn.closed:
                            self._read(conn)
        finally:
            for conn in list(self._conns):
                self.close(conn)
            for key in list(self.sel.get_map().values()):
                if key.data[0] == "listen":
                    key.fileobj.close()
            self.sel.close()
            self._wake_r.close()
            self._wake_w.close()
