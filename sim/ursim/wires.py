"""Wires between two stand-ins: a standard digital output of this controller driving a standard
digital input of another, as a 24 V line between two real controllers' I/O would.

`--wire-output N:HOST:M` (repeatable): whenever this controller's standard digital output N
changes (and once at start), the level is set on standard digital input M of the stand-in at HOST
through its admin channel (`digital_in M 0|1`, port 30020). The output is sampled every controller
tick (2 ms on an e-Series), so a level reaches the other controller within a few ticks plus a
loopback round trip. A peer that does not answer yet is retried every 50 ms (the level is sent as
soon as it does). Not part of a real controller: what two cables do.
"""
from __future__ import annotations

import ipaddress
import threading

from sim.ursim.admin import admin_request

__all__ = ["Wire", "parse_wire", "run_wires"]


class Wire(tuple):
    """(output, host, input) of one `--wire-output`."""

    @property
    def output(self) -> int:
        return self[0]

    @property
    def host(self) -> str:
        return self[1]

    @property
    def input(self) -> int:
        return self[2]


def parse_wire(text: str) -> Wire:
    """`N:HOST:M` -> Wire; ValueError naming what is wrong."""
    parts = text.split(":")
    if len(parts) != 3 or not all(parts):
        raise ValueError(f"{text!r}: expected OUTPUT:HOST:INPUT, e.g. 6:127.0.0.3:6")
    out, host, inp = parts
    if out not in tuple("01234567") or inp not in tuple("01234567"):
        raise ValueError(f"{text!r}: the output and the input are standard digital I/O 0-7")
    try:
        loopback = ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False
    if not loopback:
        raise ValueError(f"{text!r}: the stand-in wires only to loopback addresses")
    return Wire((int(out), host, int(inp)))


def run_wires(ctrl, wires, stop: threading.Event) -> threading.Thread | None:
    """Forward each wire's output level to its peer until `stop` is set (a daemon thread)."""
    if not wires:
        return None

    def loop():
        sent: dict = {}
        last = ctrl.tick_index
        while not stop.is_set():
            last = ctrl.wait_tick(last, timeout=0.05)
            for w in wires:
                level = bool(ctrl.digital_out & (1 << w.output))
                if sent.get(w) == level:
                    continue
                try:
                    reply = admin_request(w.host, f"digital_in {w.input} {int(level)}", timeout=1.0)
                except OSError:
                    stop.wait(0.05)  # the peer is not up (yet): try again
                    continue
                if reply.get("ok"):
                    sent[w] = level
                    ctrl.log(f"wire: DO {w.output} -> {w.host} DI {w.input} = {level}")

    t = threading.Thread(target=loop, name="ursim-wires", daemon=True)
    t.start()
    return t
