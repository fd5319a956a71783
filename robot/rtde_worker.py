"""ur_rtde in a supervised worker process.

ur_rtde's constructors hold the GIL, its auto-reconnect can segfault the process, and several of
its calls can block for minutes (reference ur-rtde.md §6). So every ur_rtde object lives in a
child process (multiprocessing, spawn context) that answers one request at a time over a pipe,
and the parent (`RTDEWorker`) puts a timeout on every call: when the worker crashes, hangs or
times out, the parent kills it and raises `WorkerError` — it never hangs with it. ur_rtde's
`reconnect()` is never called; a lost link means a new worker.

Requests are `(method, args)`; the worker's methods are the `_Channels` methods below.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import time
import traceback
from typing import Any, Callable

#: RTDE variables the monitor receives (a small set at 125 Hz, reference ur-rtde.md §9.1).
MONITOR_VARIABLES = ["timestamp", "actual_q", "actual_TCP_pose", "runtime_state", "robot_mode", "safety_mode",
                     "safety_status_bits", "actual_digital_output_bits"]


class WorkerError(Exception):
    """The worker died, hung past its timeout, or could not be reached; it has been killed."""


class CallError(Exception):
    """ur_rtde raised inside the worker (the worker is still usable); message = its exception."""


class _Channels:
    """The ur_rtde objects of one worker: dashboard, receive, control (created on request)."""

    def __init__(self, host: str):
        self.host = host
        self.dash = self.recv = self.ctrl = self.io = None

    def connect_dashboard(self) -> str:
        import dashboard_client

        self.dash = dashboard_client.DashboardClient(self.host)
        self.dash.connect()
        return self.dash.polyscopeVersion()

    def dashboard(self, command: str) -> str:
        """One raw dashboard command -> the controller's reply line."""
        self.dash.send(command + "\n")
        return self.dash.receive().strip()

    def connect_receive(self, frequency: float) -> bool:
        import rtde_receive

        # rt_priority -1: leave the scheduling alone (ur_rtde's default 0 makes the thread SCHED_FIFO
        # on real-time kernels)
        self.recv = rtde_receive.RTDEReceiveInterface(self.host, frequency, MONITOR_VARIABLES, False, False, -1)
        return True

    def connect_control(self, rt_priority: int) -> bool:
        import rtde_control

        self.ctrl = rtde_control.RTDEControlInterface(self.host, -1.0, rtde_control.RTDEControlInterface.FLAG_UPLOAD_SCRIPT,
                                                      50002, rt_priority)
        return bool(self.ctrl.isProgramRunning())

    def state(self) -> dict:
        r = self.recv
        return {"timestamp": r.getTimestamp(), "q": list(r.getActualQ()), "tcp_pose": list(r.getActualTCPPose()),
                "runtime_state": r.getRuntimeState(), "robot_mode": r.getRobotMode(),
                "safety_mode": r.getSafetyMode(), "safety_status_bits": r.getSafetyStatusBits(),
                "digital_out": int(r.getActualDigitalOutputBits()),
                # the async status word (output_int_register_2) from the control interface's own stream;
                # the receive interface only exposes registers 12-19
                "progress_word": int(self.ctrl.getAsyncOperationProgressEx().value()) if self.ctrl else 0}

    def connect_io(self) -> bool:
        import rtde_io

        self.io = rtde_io.RTDEIOInterface(self.host)
        return True

    def set_output(self, kind: str, number: int, value: bool) -> bool:
        """A digital output: kind "tool" (tool connector) or "standard" (control box)."""
        if kind == "tool":
            return bool(self.io.setToolDigitalOut(int(number), bool(value)))
        return bool(self.io.setStandardDigitalOut(int(number), bool(value)))

    def set_tcp(self, pose) -> bool:
        return bool(self.ctrl.setTcp(list(pose)))

    def get_tcp(self) -> list:
        return list(self.ctrl.getTCPOffset())

    def move_path(self, entries: list, asynchronous: bool) -> bool:
        """entries: [(move "movej"|"movel", "q"|"pose", [9 values]), ...] -> movePath."""
        import rtde_control

        path = rtde_control.Path()
        E = rtde_control.PathEntry
        for move, what, values in entries:
            path.addEntry(E(E.MoveJ if move == "movej" else E.MoveL,
                            E.PositionJoints if what == "q" else E.PositionTcpPose, [float(v) for v in values]))
        return bool(self.ctrl.movePath(path, asynchronous))

    def move_j(self, q, v: float, a: float, asynchronous: bool) -> bool:
        return bool(self.ctrl.moveJ(list(q), v, a, asynchronous))

    def move_l(self, pose, v: float, a: float, asynchronous: bool) -> bool:
        return bool(self.ctrl.moveL(list(pose), v, a, asynchronous))

    def progress(self) -> int:
        return int(self.ctrl.getAsyncOperationProgress())

    def stop_l(self, deceleration: float) -> bool:
        return bool(self.ctrl.stopL(deceleration, False))

    def reupload(self) -> bool:
        return bool(self.ctrl.reuploadScript())

    def stop_script(self) -> bool:
        self.ctrl.stopScript()
        return True

    def disconnect(self) -> bool:
        for obj in (self.ctrl, self.io, self.recv, self.dash):
            if obj is not None:
                obj.disconnect()
        self.ctrl = self.io = self.recv = self.dash = None
        return True


def _worker_main(conn, host: str) -> None:
    """Worker process: answer requests until the pipe closes.

    Ctrl-C reaches the whole process group; the worker ignores it so that the parent can still
    stop the arm through it before shutting it down.
    """
    import signal

    from fabkit.lifeline import die_with_parent

    die_with_parent(getattr(mp.parent_process(), "pid", None))  # never outlive the sender, even on kill -9
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    ch = _Channels(host)
    while True:
        try:
            method, args = conn.recv()
        except (EOFError, OSError):
            os._exit(0)
        try:
            result = getattr(ch, method)(*args)
            conn.send(("ok", result))
        except Exception as exc:  # ur_rtde errors go back to the parent as CallError
            conn.send(("error", f"{type(exc).__name__}: {exc}", traceback.format_exc(limit=2)))


class RTDEWorker:
    """Parent side: start the worker, call it with timeouts, kill it when anything goes wrong.

    `log(event: dict)` (optional) receives every request and reply, for the send log.
    """

    def __init__(self, host: str, log: Callable[[dict], None] | None = None, start_timeout: float = 20.0):
        self.host = host
        self._log = log or (lambda e: None)
        ctx = mp.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(child, host), name="ur_rtde-worker", daemon=True)
        self.proc.start()
        child.close()
        self.dead_reason: str | None = None

    @property
    def alive(self) -> bool:
        return self.dead_reason is None and self.proc.is_alive()

    def call(self, method: str, *args, timeout: float = 10.0) -> Any:
        """Run `method(*args)` in the worker; `WorkerError` after killing it on a timeout or crash."""
        if self.dead_reason is not None:
            raise WorkerError(self.dead_reason)
        t0 = time.monotonic()
        self._log({"t": round(time.time(), 4), "call": method, "args": args})
        try:
            self._conn.send((method, args))
            deadline = t0 + timeout
            while not self._conn.poll(min(0.05, max(0.0, deadline - time.monotonic()))):
                if not self.proc.is_alive():
                    self._die(f"ur_rtde worker died during {method} ({self._exit_text()})")
                if time.monotonic() >= deadline:
                    self._die(f"ur_rtde call {method} did not return within {timeout:g} s")
            reply = self._conn.recv()
        except (EOFError, OSError, BrokenPipeError):
            self._die(f"ur_rtde worker died during {method} ({self._exit_text()})")
        dt = time.monotonic() - t0
        if reply[0] == "ok":
            self._log({"t": round(time.time(), 4), "reply": method, "result": reply[1], "dt": round(dt, 4)})
            return reply[1]
        self._log({"t": round(time.time(), 4), "reply": method, "error": reply[1], "dt": round(dt, 4)})
        raise CallError(reply[1])

    def _exit_text(self) -> str:
        self.proc.join(timeout=0.2)
        code = self.proc.exitcode
        if code is None:
            return "still running"
        return f"killed by signal {-code}" if code < 0 else f"exit code {code}"

    def _die(self, reason: str):
        self.kill()
        self.dead_reason = reason
        self._log({"t": round(time.time(), 4), "worker": "killed", "reason": reason})
        raise WorkerError(reason)

    def kill(self) -> None:
        """Terminate the worker (SIGTERM, then SIGKILL after 1 s)."""
        if self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(timeout=1.0)
            if self.proc.is_alive():
                self.proc.kill()
                self.proc.join(timeout=1.0)
        try:
            self._conn.close()
        except OSError:
            pass
        if self.dead_reason is None:
            self.dead_reason = "ur_rtde worker stopped"

    def close(self, timeout: float = 3.0) -> None:
        """Disconnect cleanly if the worker is healthy, then stop it."""
        if self.alive:
            try:
                self.call("disconnect", timeout=timeout)
            except (WorkerError, CallError):
                pass
        self.kill()
