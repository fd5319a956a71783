"""Controller stand-in streaming: a receive client at 500 Hz for 10 s with ur_rtde's default variables.

The stand-in runs in its own process (as in use). The instrument is sim/ursim/probe.py: a
plain-socket RTDE client that timestamps every package on arrival, asking for exactly the
variables `RTDEReceiveInterface(host)` asks a 5.15 controller for (58 variables, 1180-byte
packages); a last row polls the real ur_rtde receive client. A package is on time when its
controller timestamp is exactly one period after the previous one (no skipped tick) and it
arrives within one period of its schedule; `sent_on_schedule_pct` counts only the first
condition. The client runs SCHED_FIFO when the process may (recorded in the JSON). CPU is the
stand-in process's user+system time over the window, in percent of one core. Baseline in the same
run: the stand-in idling with no client, and a 125 Hz stream; one row streams every output the
stand-in serves in one recipe at 500 Hz.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from bench.common import report
from sim.ursim.launch import free_loopback_address
from sim.ursim.probe import measure

ROOT = Path(__file__).resolve().parents[1]
SECONDS = 10.0


def _free_host() -> str:
    """A 127.0.0.x (x in 180-250) with every stand-in port free right now."""
    return free_loopback_address(first=180, last=251)


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _stream(host: str, freq: float, names: list[str], seconds: float, pid: int, client: str = "socket") -> dict:
    cpu0, t0 = _cpu_seconds(pid), time.perf_counter()
    stats = measure(host, client, freq, names, seconds, rt_priority=0)  # this process's scheduling
    cpu = (_cpu_seconds(pid) - cpu0) / (time.perf_counter() - t0) * 100
    size = f", {stats.package_bytes} B" if stats.package_bytes else ""
    return {"stream": f"{freq:.0f} Hz, {len(names)} variables{size} ({client})",
            "packages": stats.packages, "expected": stats.expected, "on_time_pct": stats.on_time_pct,
            "sent_on_schedule_pct": stats.consecutive_pct, "skipped_ticks": stats.missed_periods,
            "late_p99_ms": stats.late_p99_ms, "cpu_pct": cpu}


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
        rows.append(_stream(host, 500.0, ["timestamp", "actual_q"], SECONDS / 2, proc.pid, "ur_rtde"))
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
