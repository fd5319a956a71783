"""Child processes that never outlive their parent.

On Linux a child asks the kernel for a signal when its parent dies (prctl PR_SET_PDEATHSIG, via
ctypes: no library wraps this one call), so a `kill -9` of fabkit takes its pool workers and its
ur_rtde worker with it. Elsewhere the children still end when their pipe to the parent closes.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys

__all__ = ["die_with_parent"]

_PR_SET_PDEATHSIG = 1


def die_with_parent(parent_pid: int | None = None, sig: int = signal.SIGKILL) -> bool:
    """Call first thing in a child: deliver `sig` to it when its parent dies (Linux).

    `parent_pid` (the parent's pid as the parent saw it) closes the race in which the parent died
    before the call: the child then exits at once. Returns whether the kernel took the request.
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        ok = libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False
    if parent_pid is not None and os.getppid() != parent_pid:
        os._exit(1)  # the parent is already gone
    return ok
