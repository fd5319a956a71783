"""Measure an RTDE output stream as a client receives it: which controller periods arrived, and when.

Two instruments, each run in a process of its own (`python -m sim.ursim.probe`) so that the
process under test cannot delay it:

- `socket`: a plain-socket RTDE client that timestamps every data package on arrival.
- `ur_rtde`: the real `rtde_receive.RTDEReceiveInterface`, polled for `getTimestamp()` every
  `POLL_S`. ur_rtde's receive thread parses the newest package in its buffer and drops any older
  one still queued behind it (ur_rtde 1.6 `RTDE::receiveData`, "skipping package"), so a package
  that reaches the client late, bunched with the next, is never seen; one that arrives on time is
  held for a whole period and the poller sees it. (ur_rtde's own `startFileRecording` cannot be
  used for this: its recorder thread samples the state on a clock of its own, so it writes
  repeated and skipped rows whenever its phase drifts across the controller's, however regular
  the stream.)

A package is on time when the period before it arrived too (its controller timestamp is one
period after the previous one seen) and it arrived within one period of its schedule (the first
arrival plus the controller time elapsed, the schedule shifted to the earliest arrival).
"""
from __future__ import annotations

import argparse
import json
import os
import select
import socket
import struct
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

POLL_S = 0.0002
DEFAULT_VARIABLES = ("timestamp", "actual_q")


@dataclass(frozen=True)
class StreamStats:
    """What one client saw of a stream; shares are of the controller periods in the window."""
    client: str
    frequency_hz: float
    packages: int
    expected: int
    on_time_pct: float
    consecutive_pct: float
    missed_periods: int
    late_p99_ms: float
    max_gap_ms: float
    package_bytes: int
    client_scheduling: str


def stream_stats(stamps, arrivals, frequency: float, client: str, package_bytes: int = 0,
                 scheduling: str = "normal") -> StreamStats:
    """Score controller timestamps against their arrival times (both in seconds)."""
    stamps, arrivals = np.asarray(stamps, float), np.asarray(arrivals, float)
    if len(stamps) < 2:
        raise ValueError(f"{client}: {len(stamps)} package(s) received: no stream to measure")
    period = 1.0 / frequency
    steps = np.diff(stamps)
    consecutive = np.r_[True, np.isclose(steps, period, rtol=0.0, atol=1e-9)]
    lateness = (arrivals - arrivals[0]) - (stamps - stamps[0])
    lateness -= lateness.min()
    on_time = consecutive & (lateness <= period)
    expected = int(round((stamps[-1] - stamps[0]) / period)) + 1
    return StreamStats(client=client, frequency_hz=frequency, packages=len(stamps), expected=expected,
                       on_time_pct=100.0 * on_time.sum() / expected,
                       consecutive_pct=100.0 * consecutive.sum() / expected,
                       missed_periods=expected - len(stamps),
                       late_p99_ms=float(np.percentile(lateness, 99) * 1e3),
                       max_gap_ms=float(steps.max() * 1e3), package_bytes=package_bytes,
                       client_scheduling=scheduling)


def realtime_if_permitted(priority: int) -> str:
    """Run this process SCHED_FIFO at `priority` when allowed, so the instrument is not the one late."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        return f"SCHED_FIFO {priority}"
    except (PermissionError, OSError, AttributeError):
        return "normal"


def _frames(sock: socket.socket):
    buf = bytearray()
    while True:
        while len(buf) >= 3:
            size, kind = struct.unpack_from(">HB", buf)
            if size < 3:
                raise ConnectionError(f"malformed RTDE frame size {size}")
            if len(buf) < size:
                break
            payload = bytes(buf[3:size])
            del buf[:size]
            yield chr(kind), payload
        data = sock.recv(1 << 16)
        if not data:
            raise ConnectionError("the controller closed the RTDE connection")
        buf += data


class SocketStream:
    """A plain-socket RTDE v2 output stream (`frequency` Hz, `variables` with timestamp first)."""

    def __init__(self, host: str, frequency: float, variables, port: int = 30004, timeout: float = 5.0):
        if variables[0] != "timestamp":
            raise ValueError("the first variable must be timestamp")
        self.sock = socket.create_connection((host, port), timeout=timeout)
        self.frequency = frequency
        self._frames = _frames(self.sock)
        self._request(b"V", struct.pack(">H", 2))
        payload = self._request(b"O", struct.pack(">d", frequency) + ",".join(variables).encode())
        types = payload[1:].decode().split(",")
        if payload[0] == 0 or "NOT_FOUND" in types:
            raise ConnectionError(f"output recipe refused: {payload[1:].decode()}")
        self._request(b"S")

    def _request(self, kind: bytes, payload: bytes = b"") -> bytes:
        self.sock.sendall(struct.pack(">HB", 3 + len(payload), kind[0]) + payload)
        for got, body in self._frames:
            if got == kind.decode():
                return body

    def record(self, until) -> tuple[list, list, int]:
        """(controller timestamps, arrival times, package bytes) until `until()` is true."""
        stamps, arrivals, size = [], [], 0
        for kind, payload in self._frames:
            now = time.perf_counter()
            if kind == "U":
                stamps.append(struct.unpack_from(">d", payload, 1)[0])
                arrivals.append(now)
                size = len(payload) + 3
                if until():
                    break
        return stamps, arrivals, size

    def close(self) -> None:
        self.sock.close()


def record_ur_rtde(host: str, frequency: float, variables, until, rt_priority: int = 0,
                   on_start=lambda: None) -> tuple[list, list]:
    """Poll a real `RTDEReceiveInterface` for new controller timestamps until `until()` is true."""
    import rtde_receive

    recv = rtde_receive.RTDEReceiveInterface(host, frequency, list(variables), False, False, rt_priority)
    on_start()
    stamps, arrivals, last = [], [], None
    try:
        while not until():
            t = recv.getTimestamp()
            if t != last:
                stamps.append(t)
                arrivals.append(time.perf_counter())
                last = t
            time.sleep(POLL_S)
    finally:
        recv.disconnect()
    return stamps, arrivals


def _stop_condition(seconds: float, watch_stdin: bool):
    """True once `seconds` passed, or (watch_stdin) a line or end of file arrived on stdin."""
    t_end = time.monotonic() + seconds
    state = {"n": 0, "stop": False}

    def until() -> bool:
        state["n"] += 1
        if time.monotonic() >= t_end:
            return True
        if watch_stdin and state["n"] % 20 == 0:
            ready, _, _ = select.select([sys.stdin], [], [], 0)
            if ready:
                return True
        return False

    return until


def measure(host: str, client: str = "socket", frequency: float = 500.0, variables=DEFAULT_VARIABLES,
            seconds: float = 10.0, watch_stdin: bool = False, rt_priority: int = 20,
            on_start=lambda: None) -> StreamStats:
    """Measure the stream at `host` with one instrument (see the module docstring); `on_start` is
    called once the stream flows, and the window of at most `seconds` starts then."""
    scheduling = realtime_if_permitted(rt_priority) if rt_priority else "normal"
    if client == "socket":
        stream = SocketStream(host, frequency, variables)
        on_start()
        until = _stop_condition(seconds, watch_stdin)
        try:
            stamps, arrivals, size = stream.record(until)
        finally:
            stream.close()
    elif client == "ur_rtde":
        started = {}

        def start():
            started["until"] = _stop_condition(seconds, watch_stdin)
            on_start()

        stamps, arrivals = record_ur_rtde(host, frequency, variables, lambda: started["until"](),
                                          rt_priority if scheduling != "normal" else 0, start)
        size = 0
    else:
        raise ValueError(f"unknown client {client!r} (socket or ur_rtde)")
    return stream_stats(stamps, arrivals, frequency, client, size, scheduling)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m sim.ursim.probe", description=__doc__.split("\n")[0])
    p.add_argument("host")
    p.add_argument("--client", choices=("socket", "ur_rtde"), default="socket")
    p.add_argument("--frequency", type=float, default=500.0)
    p.add_argument("--variables", default=",".join(DEFAULT_VARIABLES), help="comma-separated, timestamp first")
    p.add_argument("--seconds", type=float, default=10.0, help="at most this long")
    p.add_argument("--until-stdin", action="store_true", help="also stop at a line or EOF on stdin")
    p.add_argument("--rt-priority", type=int, default=20, help="SCHED_FIFO priority if permitted (0: normal)")
    args = p.parse_args(argv)
    stats = measure(args.host, args.client, args.frequency, args.variables.split(","), args.seconds,
                    args.until_stdin, args.rt_priority, on_start=lambda: print("probe: streaming", flush=True))
    print(json.dumps(asdict(stats)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
