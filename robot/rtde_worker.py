"""ur_rtde in a supervised worker process, with the controller's RTDE watchdog armed while it moves.

ur_rtde's constructors hold the GIL, its auto-reconnect can segfault the process, and several of
its calls can block for minutes (reference ur-rtde.md §6). So every ur_rtde object lives in a
child process that answers one request at a time over a socket pair, and the parent
(`RTDEWorker`) puts a timeout on every call: when the worker crashes, hangs or times out, the
parent kills it and raises `WorkerError` — it never hangs with it. ur_rtde's `reconnect()` is
never called; a lost link means a new worker.

The child is a plain `python -m robot.rtde_worker` subprocess (not multiprocessing's spawn, which
re-imports the caller's `__main__` and so would need an `if __name__ == "__main__":` guard in every
user script that sends). It exits when the parent's end of the socket closes (the parent died).

Watchdog: every move is commanded with the controller's RTDE watchdog armed
(`setWatchdog(watchdog_hz)`, re-armed after each `movePath`, which re-uploads the control script),
and the worker kicks it before answering each request. The parent polls the state every few tens
of milliseconds while the arm moves, so the kicks stop — and the controller stops the program and
the arm within 1 / watchdog_hz — when the parent dies or hangs, the worker dies or hangs, or the
link drops. When the parent dies, the kernel also sends the worker SIGTERM (PR_SET_PDEATHSIG), and
the worker stops the arm itself (`stopL`, then `stopScript`) before it exits: that covers a death
between a `movePath` upload and the watchdog's re-arming.

Requests are `(seq, method, args)`, replies `(seq, "ok", result)` or `(seq, "error", text, trace)`;
the worker's methods are the `_Channels` methods below.
"""
from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
import traceback
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any, Callable

#: RTDE variables the monitor receives (a small set at 125 Hz, reference ur-rtde.md §9.1).
MONITOR_VARIABLES = ["timestamp", "actual_q", "actual_TCP_pose", "runtime_state", "robot_mode", "safety_mode",
                     "safety_status_bits", "actual_digital_output_bits"]
#: Added when the toolpath declares a payload (controllers since 5.5.1).
PAYLOAD_VARIABLES = ["payload", "payload_cog"]


#: Seconds the worker may spend stopping the arm when its parent died before it exits regardless.
HALT_TIMEOUT_S = 3


class WorkerError(Exception):
    """The worker died, hung past its timeout, or could not be reached; it has been killed."""


class CallError(Exception):
    """ur_rtde raised inside the worker (the worker is still usable); message = its exception."""


class _Channels:
    """The ur_rtde objects of one worker: dashboard, receive, control (created on request)."""

    def __init__(self, host: str):
        self.host = host
        self.dash = self.recv = self.ctrl = self.io = None
        self.recv_payload = False
        self.watchdog_hz = 0.0

    def kick(self) -> None:
        """Kick the controller's watchdog (before every request, once it is armed)."""
        if self.ctrl is not None and self.watchdog_hz > 0:
            self.ctrl.kickWatchdog()

    def arm_watchdog(self, hz: float) -> bool:
        """Arm the controller's RTDE watchdog: the program stops unless kicked at >= hz."""
        self.watchdog_hz = float(hz)
        return bool(self.ctrl.setWatchdog(self.watchdog_hz)) if hz > 0 else True

    def connect_dashboard(self) -> str:
        import dashboard_client

        self.dash = dashboard_client.DashboardClient(self.host)
        self.dash.connect()
        return self.dash.polyscopeVersion()

    def dashboard(self, command: str) -> str:
        """One raw dashboard command -> the controller's reply line."""
        self.dash.send(command + "\n")
        return self.dash.receive().strip()

    def connect_receive(self, frequency: float, payload: bool = False) -> bool:
        import rtde_receive

        # rt_priority -1: leave the scheduling alone (ur_rtde's default 0 makes the thread SCHED_FIFO
        # on real-time kernels)
        names = MONITOR_VARIABLES + (PAYLOAD_VARIABLES if payload else [])
        self.recv = rtde_receive.RTDEReceiveInterface(self.host, frequency, names, False, False, -1)
        self.recv_payload = bool(payload)
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
                "progress_word": int(self.ctrl.getAsyncOperationProgressEx().value()) if self.ctrl else 0,
                **({"payload": float(r.getPayload()), "payload_cog": list(r.getPayloadCog())}
                   if self.recv_payload else {})}

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

    def set_payload(self, mass: float, cog) -> bool:
        """ur_rtde `setPayload(mass [kg], cog [m] in the flange frame)`."""
        return bool(self.ctrl.setPayload(float(mass), [float(x) for x in cog]))

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
        ok = bool(self.ctrl.movePath(path, asynchronous))
        if ok and self.watchdog_hz > 0:  # movePath re-uploaded the control script: arm its watchdog
            self.ctrl.setWatchdog(self.watchdog_hz)
        return ok

    def move_j(self, q, v: float, a: float, asynchronous: bool) -> bool:
        self._rearm()
        return bool(self.ctrl.moveJ(list(q), v, a, asynchronous))

    def move_l(self, pose, v: float, a: float, asynchronous: bool) -> bool:
        self._rearm()
        return bool(self.ctrl.moveL(list(pose), v, a, asynchronous))

    def _rearm(self) -> None:
        if self.watchdog_hz > 0:
            self.ctrl.setWatchdog(self.watchdog_hz)

    def progress(self) -> int:
        return int(self.ctrl.getAsyncOperationProgress())

    def stop_l(self, deceleration: float) -> bool:
        return bool(self.ctrl.stopL(deceleration, False))

    def reupload(self) -> bool:
        return bool(self.ctrl.reuploadScript())

    def stop_script(self) -> bool:
        self.ctrl.stopScript()
        return True

    def halt(self) -> None:
        """Stop the arm because the worker is about to exit without its parent: decelerate, then
        end the control script. The watchdog alone is not enough: `movePath` re-uploads the script,
        and a parent that dies between the upload and `setWatchdog` leaves a path running with no
        watchdog armed. Bounded: SIGALRM (default action: terminate) ends a call that hangs."""
        import signal

        if self.ctrl is None:
            return
        signal.alarm(HALT_TIMEOUT_S)
        for stop in (lambda: self.ctrl.stopL(2.0, False), self.ctrl.stopScript):
            try:
                stop()
            except Exception:  # the link may be gone as well: the controller's watchdog then stops it
                pass

    def disconnect(self) -> bool:
        self.watchdog_hz = 0.0
        for obj in (self.ctrl, self.io, self.recv, self.dash):
            if obj is not None:
                obj.disconnect()
        self.ctrl = self.io = self.recv = self.dash = None
        return True


def serve(fd: int, host: str, priority: int = -1) -> None:
    """Worker process: answer requests on socket `fd` until the parent's end closes; at nice value
    `priority` (< 0) when the OS allows (`robot.realtime`; ur_rtde's threads, created later, inherit it).

    Ctrl-C reaches the whole process group; the worker ignores it so that the parent can still
    stop the arm through it before shutting it down.
    """
    import signal

    from fabkit.lifeline import die_with_parent

    from robot.realtime import raise_priority

    conn = Connection(fd)
    ch = _Channels(host)
    raise_priority(priority)

    def parent_gone(*_):
        ch.halt()
        os._exit(0)

    signal.signal(signal.SIGTERM, parent_gone)
    die_with_parent(os.getppid(), signal.SIGTERM)  # never outlive the sender, even on kill -9: stop, then exit
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    while True:
        try:
            seq, method, args = conn.recv()
        except (EOFError, OSError):
            parent_gone()  # the parent is gone: no more kicks; stop the arm rather than wait for the watchdog
        try:
            ch.kick()
            result = getattr(ch, method)(*args)
            conn.send((seq, "ok", result))
        except (EOFError, OSError, BrokenPipeError):
            parent_gone()
        except Exception as exc:  # ur_rtde errors go back to the parent as CallError
            conn.send((seq, "error", f"{type(exc).__name__}: {exc}", traceback.format_exc(limit=2)))


class RTDEWorker:
    """Parent side: start the worker, call it with timeouts, kill it when anything goes wrong.

    `log(event: dict)` (optional) receives every request and reply, for the send log.
    """

    def __init__(self, host: str, log: Callable[[dict], None] | None = None, priority: int = -1):
        self.host = host
        self._log = log or (lambda e: None)
        mine, child = socket.socketpair()
        root = str(Path(__file__).resolve().parents[1])  # the folder holding the robot package
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([root] + [p for p in [os.environ.get("PYTHONPATH")] if p])}
        try:
            self.proc = subprocess.Popen([sys.executable, "-m", "robot.rtde_worker", str(child.fileno()), host,
                                          str(int(priority))],
                                         pass_fds=(child.fileno(),), stdin=subprocess.DEVNULL, env=env)
        finally:
            child.close()
        self._conn = Connection(mine.detach())
        self._seq = 0
        self.dead_reason: str | None = None
        self._log({"t": round(time.time(), 4), "worker": "started", "pid": self.proc.pid})

    def scheduling(self) -> str:
        """The worker's nice value as "nice N", or "normal" (`robot.realtime`)."""
        try:
            nice = os.getpriority(os.PRIO_PROCESS, self.proc.pid)
        except OSError:
            return "unknown"
        return f"nice {nice}" if nice else "normal"

    @property
    def pid(self) -> int:
        return self.proc.pid

    @property
    def alive(self) -> bool:
        return self.dead_reason is None and self.proc.poll() is None

    def call(self, method: str, *args, timeout: float = 10.0) -> Any:
        """Run `method(*args)` in the worker; `WorkerError` after killing it on a timeout or crash."""
        if self.dead_reason is not None:
            raise WorkerError(self.dead_reason)
        t0 = time.monotonic()
        self._seq += 1
        seq = self._seq
        self._log({"t": round(time.time(), 4), "call": method, "args": args})
        try:
            self._conn.send((seq, method, args))
            deadline = t0 + timeout
            while True:  # replies to calls abandoned by an exception (Ctrl-C) are skipped
                while not self._conn.poll(min(0.05, max(0.0, deadline - time.monotonic()))):
                    if self.proc.poll() is not None:
                        self._die(f"ur_rtde worker died during {method} ({self._exit_text()})")
                    if time.monotonic() >= deadline:
                        self._die(f"ur_rtde call {method} did not return within {timeout:g} s")
                reply = self._conn.recv()
                if reply[0] == seq:
                    break
        except (EOFError, OSError, BrokenPipeError):
            self._die(f"ur_rtde worker died during {method} ({self._exit_text()})")
        dt = time.monotonic() - t0
        if reply[1] == "ok":
            self._log({"t": round(time.time(), 4), "reply": method, "result": reply[2], "dt": round(dt, 4)})
            return reply[2]
        self._log({"t": round(time.time(), 4), "reply": method, "error": reply[2], "dt": round(dt, 4)})
        raise CallError(reply[2])

    def _exit_text(self) -> str:
        try:
            code = self.proc.wait(timeout=0.2)
        except subprocess.TimeoutExpired:
            return "still running"
        return f"killed by signal {-code}" if code < 0 else f"exit code {code}"

    def _die(self, reason: str):
        self.kill()
        self.dead_reason = reason
        self._log({"t": round(time.time(), 4), "worker": "killed", "reason": reason})
        raise WorkerError(reason)

    def kill(self) -> None:
        """Terminate the worker (SIGTERM, then SIGKILL after 1 s; a stopped worker gets SIGKILL)."""
        if self.proc.poll() is None:
            self.proc.kill()  # SIGKILL: also ends a worker that was stopped (SIGSTOP) or hangs in C
            try:
                self.proc.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                pass
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


if __name__ == "__main__":
    serve(int(sys.argv[1]), sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else -1)
