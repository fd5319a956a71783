"""Start the controller stand-in: bind every port on one loopback address, start the threads."""
from __future__ import annotations

import socket
import sys
import threading
from pathlib import Path

from sim.ursim.admin import serve_admin
from sim.ursim.clients import MAX_CLIENTS_PER_PORT
from sim.ursim.controller import Controller, ControllerConfig
from sim.ursim.dashboard import serve_dashboard
from sim.ursim.rtde_server import serve_rtde
from sim.ursim.script_ports import serve_script_port


def _listen(host: str, port: int) -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        s.bind((host, port))
    except OSError as exc:
        s.close()
        raise OSError(f"cannot listen on {host}:{port}: {exc.strerror}") from None
    s.listen(2 * MAX_CLIENTS_PER_PORT)  # a burst of connects is accepted (or refused) at once, not retried
    return s


class StandIn:
    """A running stand-in: `Controller` plus its listeners. `close()` stops everything: listeners,
    every client connection, the running program and the tick. `done` is set by admin or dashboard
    `shutdown` (the CLI then closes and exits)."""

    def __init__(self, config: ControllerConfig, programs_dir: Path | None = None):
        self.ctrl = Controller(config)
        self.done = threading.Event()
        # A busy client thread keeps the GIL for up to the switch interval (5 ms by default): far
        # more than the 2 ms period. A tenth of the period lets the tick thread in on time.
        sys.setswitchinterval(min(sys.getswitchinterval(), self.ctrl.period / 10))
        ports = config.ports
        self._sockets = []
        try:
            for key in ("rtde", "dashboard", "primary", "secondary", "realtime", "admin"):
                self._sockets.append((key, _listen(config.host, ports[key])))
        except OSError:
            self.close()
            raise
        self.ctrl.start()
        for key, sock in self._sockets:
            if key == "rtde":
                target, args = serve_rtde, (self.ctrl, sock)
            elif key == "dashboard":
                target, args = serve_dashboard, (self.ctrl, sock, programs_dir, self.done.set)
            elif key == "admin":
                target, args = serve_admin, (self.ctrl, sock, self.done.set)
            else:
                target, args = serve_script_port, (self.ctrl, sock, key, ports[key])
            threading.Thread(target=target, args=args, name=f"listen-{key}", daemon=True).start()

    def close(self) -> None:
        for _, s in self._sockets:
            for op in (lambda: s.shutdown(socket.SHUT_RDWR), s.close):  # shutdown wakes accept()
                try:
                    op()
                except OSError:
                    pass
        self.ctrl.clients.close_all()  # every client of every port
        with self.ctrl.lock:
            conns = list(self.ctrl.rtde_conns)
        for conn in conns:
            conn.close()
        self.ctrl.shutdown()
