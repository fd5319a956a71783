"""Start the controller stand-in: bind every port on one loopback address, start the threads."""
from __future__ import annotations

import os
import socket
import sys
import threading
from pathlib import Path

from sim.ursim.admin import serve_admin
from sim.ursim.clients import MAX_CLIENTS_PER_PORT
from sim.ursim.controller import Controller, ControllerConfig
from sim.ursim.dashboard import serve_dashboard
from sim.ursim.io_loop import IOLoop
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


def _realtime_threads() -> None:
    """SCHED_FIFO 1 for this thread and so for every thread it starts (Linux threads inherit the
    policy): a thread holding the GIL is then never preempted by the machine's ordinary processes
    while the tick thread (SCHED_FIFO at `--rt-priority`) waits for it. Without the privilege the
    threads stay at normal priority (the tick thread logs that)."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
    except (PermissionError, OSError, AttributeError):
        pass


class StandIn:
    """A running stand-in: `Controller` plus its listeners. `close()` stops everything: listeners,
    every client connection, the running program and the tick. `done` is set by admin or dashboard
    `shutdown` (the CLI then closes and exits)."""

    def __init__(self, config: ControllerConfig, programs_dir: Path | None = None):
        if config.rt_priority > 0:
            _realtime_threads()
        self.ctrl = Controller(config)
        self.done = threading.Event()
        # A busy client thread keeps the GIL for up to the switch interval (5 ms by default): far
        # more than the 2 ms period. A tenth of the period lets the tick thread in on time.
        sys.setswitchinterval(min(sys.getswitchinterval(), self.ctrl.period / 40))
        ports = config.ports
        self._sockets = []
        try:
            for key in ("rtde", "dashboard", "primary", "secondary", "realtime", "admin"):
                self._sockets.append((key, _listen(config.host, ports[key])))
        except OSError:
            self.close()
            raise
        self.loop = IOLoop(self.ctrl)
        for key, sock in self._sockets:
            if key == "rtde":
                serve_rtde(self.ctrl, self.loop, sock)
            elif key == "dashboard":
                serve_dashboard(self.ctrl, self.loop, sock, programs_dir, self.done.set)
            elif key == "admin":
                serve_admin(self.ctrl, self.loop, sock, self.done.set)
            else:
                serve_script_port(self.ctrl, self.loop, sock, key, ports[key])
        self.ctrl.start()
        self.loop.start()

    def close(self) -> None:
        loop = getattr(self, "loop", None)
        if loop is not None:
            loop.stop()  # closes every client of every port and the listeners
        else:  # the listeners that were bound before one failed
            for _, s in self._sockets:
                s.close()
        self.ctrl.clients.close_all()
        self.ctrl.shutdown()
