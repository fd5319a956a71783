"""Scheduling priority for the threads whose lateness stops the arm, when the OS allows it.

While the arm moves, the send loop polls the controller every `poll_s` and each poll kicks the
controller's RTDE watchdog (`robot.rtde_worker`); a poll that comes more than 1 / watchdog_hz late
stops the program. On a loaded machine the normal scheduler can hold a ready thread back for
hundreds of milliseconds (measured: 222 ms between two 20 ms polls, on 2 cores at load 7), so the
send loop thread and the ur_rtde worker ask for a higher share: a negative nice value (Linux
applies it per thread). This is not SCHED_FIFO on purpose: ur_rtde's receive thread, created in
the worker, would inherit a real-time policy, and at SCHED_FIFO the worker's `state` calls were
observed not to return within 1 s. A nice value cannot starve anything. Without the privilege
(CAP_SYS_NICE or RLIMIT_NICE) the threads keep their priority, as before, and the send log says so.
"""
from __future__ import annotations

import contextlib
import os
import threading

__all__ = ["raise_priority", "raised_priority"]


def raise_priority(nice: int, tid: int | None = None) -> str:
    """Set thread `tid`'s (default: the calling thread's) nice value to `nice` (-20..-1) if allowed;
    returns the scheduling it runs at ("nice N" or "normal"). `nice` >= 0 leaves it alone."""
    if nice >= 0:
        return "normal"
    tid = threading.get_native_id() if tid is None else tid
    try:
        os.setpriority(os.PRIO_PROCESS, tid, max(-20, int(nice)))
        return f"nice {max(-20, int(nice))}"
    except (PermissionError, OSError, AttributeError):
        return "normal"


@contextlib.contextmanager
def raised_priority(nice: int):
    """The calling thread at nice value `nice` (when allowed) inside the block, its previous value
    restored after; yields the scheduling as `raise_priority` names it."""
    tid = threading.get_native_id()
    try:
        before = os.getpriority(os.PRIO_PROCESS, tid)
    except (OSError, AttributeError):
        before = None
    got = raise_priority(nice, tid) if before is not None and nice < before else "normal"
    try:
        yield got
    finally:
        if got != "normal":
            with contextlib.suppress(OSError):
                os.setpriority(os.PRIO_PROCESS, tid, before)
