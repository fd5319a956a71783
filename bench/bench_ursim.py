"""Controller stand-in streaming: a receive client at 500 Hz for 10 s with ur_rtde's default variables.

The stand-in runs in its own process (as in use). The client here is a plain-socket RTDE client
(the measuring instrument: it timestamps every package on arrival, which ur_rtde's getters cannot)
asking for exactly the variables `RTDEReceiveInterface(host)` asks a 5.15 controller for (58
variables, 1180-byte packages). A package is on time when its controller timestamp is exactly one
period after the previous one (no skipped tick) and it arrives within one period of its schedule
(first arrival + controller time elapsed); `sent_on_schedule_pct` counts only the first condition
(the stand-in's own share, free of the client's wake-up latency). The client runs SCHED_FIFO when
the process may (recorded in the JSON). CPU is the stand-in process's user+system time over the
window, in percent of one core. Baseline in the same run: the stand-in idling with no client, and
a 125 Hz stream; a last row streams every output the stand-in serves in one recipe at 500 Hz.
"""
from __future__ import annotations

import os
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from bench.common import report
from sim.ursim.launch import free_loopback_address

ROOT = Path(__file__).resolve().parents[1]
SECONDS = 10.0


def _free_host() -> str:
    """A 127.0.0.x (x in 180-250) with every stand-in port free right now."""
    return free_loopback_address(first=180, last=251)


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class _Client:
    def __init__(self, host):
        self.sock = socket.create_connection((host, 30004), timeout=5)
        self.buf = bytearray()

    def send(self, kind, payload=b""):
        self.sock.sendall(struct.pack(">HB", 3 + len(payload), kind[0]) + payload)

    def packages(self):
        while True:
            while len(self.buf) >= 3:
                size, kind = struct.unpack_from(">HB", self.buf)
                if len(self.buf) < size:
                    break
                pkg = bytes(self.buf[3:size])
                del self.buf[:size]
                yield chr(kind), pkg
            data = self.sock.recv(1 << 16)
            if not data:
                return
            self.buf += data


def _stream(host: str, freq: float, names: list[str], seconds: float, pid: int) -> dict:
    c = _Client(host)
    pk = c.packages()
    c.send(b"V", struct.pack(">H", 2))
    next(pk)
    c.send(b"O", struct.pack(">d", freq) + (",".join(names) + ",").encode())
    _, payload = next(pk)
    assert payload[0] != 0, payload
    c.send(b"S")
    next(pk)
    period = 1.0 / freq
    arrivals, stamps, size = [], [], 0
    cpu0, t0 = _cpu_seconds(pid), time.perf_counter()
    for kind, payload in pk:
        now = time.perf_counter()
        if kind != "U":
            continue
        arrivals.append(now)
        stamps.append(struct.unpack_from(">d", payload, 1)[0])
        size = len(payload) + 3
        if now - t0 >= seconds:
            break
    cpu = (_cpu_seconds(pid) - cpu0) / (time.perf_counter() - t0) * 100
    c.sock.close()
    arrivals, stamps = np.array(arrivals), np.array(stamps)
    consecutive = np.r_[True, np.isclose(np.diff(stamps), period, atol=1e-9)]
    lateness = (arrivals - arrivals[0]) - (stamps - stamps[0])
    lateness -= lateness.min()
    on_time = consecutive & (lateness <= period)
    expected = int(round((stamps[-1] - stamps[0]) / period)) + 1
    return {"stream": f"{freq:.0f} Hz, {len(names)} variables, {size} B", "packages": len(stamps),
            "expected": expected, "on_time_pct": 100.0 * on_time.sum() / expected,
            "sent_on_schedule_pct": 100.0 * consecutive.sum() / expected,
            "skipped_ticks": int(expected - len(stamps)), "late_p99_ms": float(np.percentile(lateness, 99) * 1e3),
            "cpu_pct": cpu}


def _run(extra: list[str], label: str) -> list[dict]:
    from sim.ursim.rtde_vars import OUTPUTS, receive_default_variables

    names = receive_default_variables((5, 15, 0, 0))
    host = _free_host()
    proc = subprocess.Popen([sys.executable, "-m", "sim.ursim", "--host", host, *extra], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        line = proc.stdout.readline()  # "ursim: ready on HOST ..." once every port listens
        if not line.startswith(f"ursim: ready on {host}"):
            raise RuntimeError(f"stand-in did not start on {host}: {line!r}")
        time.sleep(0.5)
        cpu0, t0 = _cpu_seconds(proc.pid), time.perf_counter()
        time.sleep(min(5.0, SECONDS))
        idle = (_cpu_seconds(proc.pid) - cpu0) / (time.perf_counter() - t0) * 100
        rows = [{"stream": "idle (no client)", "cpu_pct": idle}]
        rows.append(_stream(host, 500.0, names, SECONDS, proc.pid))
        rows.append(_stream(host, 125.0, names, SECONDS / 2, proc.pid))
        rows.append(_stream(host, 500.0, list(OUTPUTS), SECONDS / 2, proc.pid))  # every output in one recipe
        for r in rows:
            r["scheduling"] = label
        for r in rows[1:]:
            r["cpu_vs_idle"] = r["cpu_pct"] / max(idle, 1e-9)
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    return rows


def main() -> dict:
    load = os.getloadavg()[0]
    # the measuring client should not add its own wake-up latency: real-time if permitted
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(20))
        client = "SCHED_FIFO 20"
    except (PermissionError, OSError, AttributeError):
        client = "normal"
    rows = _run([], "normal") + _run(["--rt-priority", "10"], "SCHED_FIFO 10")
    for label in ("normal", "SCHED_FIFO 10"):
        r = next(r for r in rows if r["scheduling"] == label and r["stream"].startswith("500"))
        print(f"target: >= 99% of packages on time at 500 Hz; {label}: {r['on_time_pct']:.2f}% "
              f"(load average {load:.1f} on {os.cpu_count()} cores)")
    if client != "normal":
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    return report("ursim", rows, meta={"seconds": SECONDS, "cpu_count": os.cpu_count(), "client_scheduling": client,
                                       "load_average_1min": load, "target_on_time_pct": 99.0})


if __name__ == "__main__":
    main()
