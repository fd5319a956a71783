"""The controller stand-in as a child process on a free loopback address (the dry run of `fabkit
demo`, the README's walk-through, the stand-in benchmark).

The stand-in runs in its own process (ur_rtde's constructors hold the GIL, so it can't share a
process with the client). Every wait is bounded; the stand-in is always terminated.
"""
from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
import time
from pathlib import Path

UR_PORTS = (30004, 29999, 30001, 30002, 30003, 30020)  # + the stand-in's fault-injection admin port


def free_loopback_address(first: int = 2, last: int = 250) -> str:
    """A 127.0.0.x address on which every UR port is free right now."""
    for x in range(first, last):
        host = f"127.0.0.{x}"
        socks = []
        try:
            for port in UR_PORTS:
                s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                socks.append(s)
                s.bind((host, port))
            return host
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
    raise RuntimeError("no loopback address with free UR ports (127.0.0.2-250)")


def wait_for_dashboard(host: str, timeout: float = 20.0) -> bool:
    """True once the stand-in's dashboard (port 29999) greets us, False after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError):
            with socket.create_connection((host, 29999), timeout=1.0) as s:
                s.settimeout(2.0)
                if s.recv(256):
                    return True
        time.sleep(0.1)
    return False


def start_standin(host: str, cell: str | None, log: Path, arm: str | None = None) -> subprocess.Popen:
    argv = [sys.executable, "-m", "fabkit", "ursim", "--host", host]
    if cell:
        argv += ["--cell", cell]
    if arm:
        argv += ["--arm", arm]
    import os
    import signal

    from fabkit.lifeline import die_with_parent

    parent = os.getpid()
    with open(log, "w") as fh:  # the stand-in shuts down on SIGTERM when this process dies
        return subprocess.Popen(argv, stdout=fh, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                preexec_fn=lambda: die_with_parent(parent, signal.SIGTERM))


def stop_standin(proc: subprocess.Popen, timeout: float = 5.0) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=timeout)


@contextlib.contextmanager
def standin(cell: str | None, log: Path, arm: str | None = None):
    """A controller stand-in on a free loopback address for the block -> its address; None when it
    did not start (its output is in `log`). Always shut down on leaving. `arm`: which arm of the
    cell it is (`fabkit ursim --arm`)."""
    import random

    first = random.randint(2, 200)  # other runs on this machine scan from the start too
    for _ in range(5):  # an address taken between the scan and the bind: the next one
        try:
            host = free_loopback_address(first)
        except RuntimeError:  # none free above `first`: scan from the start
            host = free_loopback_address()
        proc = start_standin(host, cell, log, arm)
        if _own_ready(proc, host, log):
            break
        stop_standin(proc)
        first = int(host.rsplit(".", 1)[1]) + 1
    else:
        yield None
        return
    try:
        yield host
    finally:
        stop_standin(proc)


def _own_ready(proc: subprocess.Popen, host: str, log: Path, timeout: float = 20.0) -> bool:
    """True once *this* stand-in process says it is ready (not another process that took the
    address first); False when it exits or does not get ready in time."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        with contextlib.suppress(OSError):
            if f"ursim: ready on {host}" in Path(log).read_text(errors="replace"):
                return wait_for_dashboard(host, timeout=max(0.1, deadline - time.monotonic()))
        time.sleep(0.05)
    return False
