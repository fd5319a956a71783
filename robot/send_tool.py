"""The tool during a send: the gripper output and the payload the controller is told about.

Gripper: the toolpath's `grip` record names a tool or standard digital output; it is on while the
arm moves from a `grip` waypoint to the next `release`, switched after arriving and confirmed by
the receive stream's output bits, then the dwell runs (the link still watched).

Payload: a toolpath planned for a real sheet carries a `payload` record (`robot.loads.payload_record`:
the tool alone, and tool + panel while held, CoG in the flange frame). The sender declares it
through ur_rtde's `setPayload(mass, cog)` before the first motion (the one for the gripper state
the send starts in), then tool + panel after the grip and the tool alone after the release, as
the URScript program does with `set_payload`; each is confirmed by the receive stream (RTDE
`payload`, `payload_cog`), and every later poll checks that the controller still has it (a
controller that dropped it, e.g. on a new program, stops the send). A toolpath without a payload
record sends no payload, as before.
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

__all__ = ["PAYLOAD_TOL_KG", "PAYLOAD_TOL_M", "ToolControl"]

#: How closely the controller must report the declared payload (kg, m): the RTDE doubles are exact,
#: so this only absorbs printing.
PAYLOAD_TOL_KG = 1e-6
PAYLOAD_TOL_M = 1e-6


class ToolControl:
    """Gripper and payload of one send. `call(method, *args, timeout=None)` runs a worker call,
    `poll()` one checked state sample, `event(**kw)` logs, `fault(text)` makes the exception that
    stops the send."""

    def __init__(self, toolpath, call: Callable, poll: Callable[[], dict], event: Callable, fault: Callable,
                 poll_s: float = 0.02):
        self.tp = toolpath
        self.wps = list(toolpath.waypoints)
        self.call, self.poll, self.event, self.fault = call, poll, event, fault
        self.poll_s = poll_s
        pay = toolpath.extra.get("payload") if isinstance(toolpath.extra, dict) else None
        self.payload = pay if isinstance(pay, dict) else None
        self.declared: tuple[float, tuple[float, ...]] | None = None  # confirmed on the controller

    @property
    def grip(self) -> dict | None:
        return self.tp.grip

    def holding_at(self, k: int) -> bool:
        """Whether the gripper is closed while moving toward waypoint k (grip ... release)."""
        on = False
        for w in self.wps[:k]:
            if w["op"] == "grip":
                on = True
            elif w["op"] == "release":
                on = False
        return on

    # ---- payload --------------------------------------------------------------------------------
    def payload_for(self, holding: bool) -> tuple[float, tuple[float, ...]] | None:
        """(mass kg, CoG m) the program declares while (not) holding the panel; None without a record."""
        if self.payload is None:
            return None
        key = "held" if holding else "tool"
        return float(self.payload[f"{key}_mass_kg"]), tuple(float(x) for x in self.payload[f"{key}_cog_m"])

    def verify_payload(self, st: dict) -> None:
        """Fault unless the controller (state sample `st`) has the payload last declared."""
        if self.declared is None or "payload" not in st:
            return
        mass, cog = self.declared
        if abs(st["payload"] - mass) > PAYLOAD_TOL_KG or \
                np.abs(np.subtract(st["payload_cog"], cog)).max() > PAYLOAD_TOL_M:
            raise self.fault(f"the controller's payload {st['payload']:.4g} kg, CoG {list(st['payload_cog'])} is not "
                             f"the declared {mass:.4g} kg, CoG {list(cog)}")

    def set_payload(self, holding: bool) -> None:
        """Declare the payload for the gripper state (`setPayload`) and wait until the receive
        stream reports it (at most 2 s); nothing without a payload record."""
        want = self.payload_for(holding)
        if want is None:
            return
        mass, cog = want
        if not self.call("set_payload", mass, list(cog)):
            raise self.fault(f"the controller refused the payload {mass:g} kg, CoG {list(cog)}")
        self.declared = None  # not yet confirmed: the polls below must not compare with the old one
        t_end = time.monotonic() + 2.0
        while True:
            st = self.poll()
            if abs(st["payload"] - mass) <= PAYLOAD_TOL_KG and \
                    np.abs(np.subtract(st["payload_cog"], cog)).max() <= PAYLOAD_TOL_M:
                break
            if time.monotonic() > t_end:
                raise self.fault(f"the controller did not take the payload {mass:g} kg, CoG {list(cog)} (it reports "
                                 f"{st['payload']:g} kg, CoG {list(st['payload_cog'])})")
            time.sleep(self.poll_s)
        self.declared = want
        self.event(step="payload", mass_kg=mass, cog_m=list(cog), held=holding)

    # ---- gripper --------------------------------------------------------------------------------
    def set_gripper(self, on: bool, dwell: float = 0.0, payload_after: bool = False) -> None:
        """Switch the gripper output, confirmed by the receive stream; then (`payload_after`) the
        payload for the new state; then dwell, still polling."""
        g = self.grip
        if g is None:
            return
        kind, n = str(g.get("kind", "tool")), int(g["output"])
        if not self.call("set_output", kind, n, on):
            raise self.fault(f"the controller refused to set the {kind} digital output {n}")
        bit = 1 << (n + (16 if kind == "tool" else 0))
        t_end = time.monotonic() + 2.0
        while bool(self.poll()["digital_out"] & bit) != on:  # confirmed by the receive stream
            if time.monotonic() > t_end:
                raise self.fault(f"the {kind} digital output {n} did not switch {'on' if on else 'off'}")
            time.sleep(self.poll_s)
        self.event(step="gripper", on=on, output=n, kind=kind)
        if payload_after:
            self.set_payload(on)
        if dwell > 0:
            t_end = time.monotonic() + dwell
            while time.monotonic() < t_end:  # keep watching the link while dwelling
                self.poll()
                time.sleep(min(self.poll_s, max(0.0, t_end - time.monotonic())))

    def after_waypoint(self, k: int) -> None:
        """At a grip or release waypoint: switch the gripper, declare the payload, dwell."""
        g = self.grip
        op = self.wps[k]["op"]
        if g is not None and op in ("grip", "release"):
            self.set_gripper(op == "grip", float(g.get(f"{op}_dwell_s", 0.5)), payload_after=True)
        elif op in ("grip", "release"):
            self.set_payload(op == "grip")
