"""Before a send: the controller's state read without changing anything, then the changes a send
needs; and the stop of last resort, `stop` on a fresh dashboard connection."""
from __future__ import annotations

import socket
import time

from robot.interlock import verify_start
from robot.path_chunks import SendError
from robot.rtde_worker import CallError

__all__ = ["ControllerFault", "read_only_preflight", "prepare_controller", "dashboard_stop", "DASHBOARD_PORT"]

DASHBOARD_PORT = 29999


class ControllerFault(Exception):
    """The controller is not (or no longer) in a state to run the send; the message says why."""


def read_only_preflight(call, robot: str, waypoints, s, event, payload: bool = False, verify=None) -> str:
    """Read-only: the dashboard answers, the robot model is `robot`, remote control is on, and the
    arm stands where a send from `s.resume_from` may start (`robot.interlock.verify_start`).
    Changes nothing on the controller. `call(method, *args, timeout=None)` runs a worker call, `s`
    is the `SendSettings`; `payload`: also receive the controller's payload (RTDE `payload`,
    `payload_cog`); `verify(waypoints, k, q, tcp_pose, tol)` replaces `verify_start` (a lockstep
    resume's rule, `robot.lockstep.resume_start`); returns the controller's software version."""
    t_end = time.monotonic() + s.connect_retry_s
    while True:
        try:
            version = call("connect_dashboard", timeout=s.connect_timeout_s)
            break
        except CallError:
            if time.monotonic() > t_end:
                raise
            time.sleep(0.25)
    model = call("dashboard", "get robot model").strip()
    want = str(robot).lower().removesuffix("e").upper()  # e-Series answer "UR5", "UR10"
    if model.upper() != want:
        raise ControllerFault(f"preflight: the controller reports robot model {model!r}, the toolpath is for "
                              f"{robot}")
    remote = call("dashboard", "is in remote control")
    if "true" not in remote.lower():
        raise ControllerFault(f"preflight: remote control is off ({remote!r}); switch the pendant to Remote Control")
    call("connect_receive", s.monitor_hz, payload, timeout=s.connect_timeout_s)
    st = call("state", timeout=max(1.0, s.stall_s * 2))
    event(step="start position", q=st["q"], tcp_pose=st["tcp_pose"], resume_from=s.resume_from)
    try:
        (verify or verify_start)(waypoints, s.resume_from, st["q"], st["tcp_pose"], s.start)
    except SendError as exc:
        if s.resume_from == 0:
            raise ControllerFault(str(exc)) from None
        raise
    return version


def prepare_controller(call, s) -> None:
    """The changes a send needs: power on and brake release (`s.power_on`), unlock a protective
    stop (`s.unlock`), then safety NORMAL."""
    mode = call("dashboard", "robotmode")
    if "RUNNING" not in mode:
        if not s.power_on:
            raise ControllerFault(f"preflight: {mode!r}, expected 'Robotmode: RUNNING' (use --power-on)")
        call("dashboard", "power on")
        _wait_dashboard(call, "robotmode", ("IDLE", "RUNNING"), 30.0)
        call("dashboard", "brake release")
        _wait_dashboard(call, "robotmode", ("RUNNING",), 30.0)
    safety = call("dashboard", "safetystatus")
    if "PROTECTIVE_STOP" in safety and s.unlock:
        # a controller refuses for 5 s after the stop: wait that out, then give up
        t_end = time.monotonic() + 6.0
        while (reply := call("dashboard", "unlock protective stop")) != "Protective stop releasing":
            if time.monotonic() > t_end:
                raise ControllerFault(f"preflight: unlock refused: {reply!r}")
            time.sleep(0.5)
        call("dashboard", "close safety popup")
        safety = call("dashboard", "safetystatus")
    if safety != "Safetystatus: NORMAL":
        hint = " (use --unlock after inspecting the cause)" if "PROTECTIVE" in safety else ""
        raise ControllerFault(f"preflight: {safety!r}, expected 'Safetystatus: NORMAL'{hint}")


def _wait_dashboard(call, command: str, words: tuple, timeout: float) -> str:
    t_end = time.monotonic() + timeout
    while True:
        reply = call("dashboard", command)
        if any(w in reply for w in words):
            return reply
        if time.monotonic() > t_end:
            raise ControllerFault(f"preflight: {reply!r} after {timeout:g} s")
        time.sleep(0.2)


def dashboard_stop(host: str, timeout: float = 1.0) -> str:
    """`stop` on a fresh dashboard connection (the program stops, and with it the arm); the reply or
    why it failed. A plain socket rather than ur_rtde: a new ur_rtde client needs a new worker
    process (seconds to start), and the dashboard's protocol is one text line each way."""
    try:
        with socket.create_connection((host, DASHBOARD_PORT), timeout=timeout) as s:
            s.settimeout(timeout)
            _read_line(s)  # the greeting
            s.sendall(b"stop\n")
            return _read_line(s)
    except OSError as exc:
        return f"dashboard stop failed: {exc}"


def _read_line(s: socket.socket, limit: int = 4096) -> str:
    buf = b""
    while not buf.endswith(b"\n") and len(buf) < limit:
        chunk = s.recv(256)
        if not chunk:
            break
        buf += chunk
    return buf.decode("utf-8", "replace").strip()
