"""Send a checked toolpath to a UR controller over RTDE with ur_rtde (in a supervised worker).

`send_toolpath(toolpath, check, cell, settings)` does, in order:

1. the interlock (`robot.interlock.clear_for_send`), before any connection is opened: the check
   report passed and belongs to this very toolpath, cell file and FOLD file; the toolpath keeps
   the cell's joint, speed, acceleration and blend limits; the check, run again here, passes;
2. ur_rtde's argument ranges and the blend rule (`robot.path_chunks.validate_waypoints`);
3. read-only preflight: dashboard (robot model, remote control) and the receive stream: the arm
   must stand at waypoint 0, or for `resume_from` N on the segment into waypoint N (position,
   orientation and joints, `robot.interlock.verify_start`) - nothing on the controller has been
   changed when this refuses;
4. only then changes: power on and brake release (`power_on`), unlock a protective stop older than
   5 s (`unlock`); safety must be NORMAL; connect the IO and control interfaces (the control script
   is uploaded), set the TCP, the gripper and the toolpath's payload (`robot.send_tool`: ur_rtde's
   setPayload, confirmed by the receive stream), arm the RTDE watchdog (`robot.rtde_worker`);
5. the waypoints from `resume_from` as blended `movePath` chunks, asynchronously, watching the
   receive stream every `poll_s` (each poll kicks the watchdog): the timestamp must advance, safety
   must stay normal, the control script must keep running, the declared payload must stay; the
   async progress register gives the waypoint index; at grip and release waypoints the gripper
   switches and the payload follows;
6. a register move (full double precision) onto the last waypoint, compared with the toolpath.

Path numbers pass through ur_rtde's script injection printed with 6 significant digits
(`robot.path_chunks`); the last waypoint is landed through the registers without rounding.

On any fault (protective or emergency stop, program stopped, stream stalled or lost, worker
crashed or hung, a timeout, Ctrl-C) the arm is stopped - stopL through the worker if it still
answers, else `stop` on a fresh dashboard connection - and a `SendResult` names the last completed
waypoint and the reason. If this process or its worker dies or hangs, the controller's watchdog
stops the arm within 1 / `watchdog_hz` s. Use from a script needs no `__main__` guard.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Callable

import numpy as np

from robot.interlock import Cleared, clear_for_send
from robot.path_chunks import (MAX_BLEND, MAX_JOINT_ACCEL, MAX_JOINT_SPEED, MAX_TOOL_ACCEL, MAX_TOOL_SPEED,
                               SendError, chunk_entries, point_segment_distance, point_segment_distance_nd,
                               pose_distance, printed, validate_waypoints)
from robot.realtime import raised_priority
from robot.preflight import ControllerFault, dashboard_stop, prepare_controller, read_only_preflight
from robot.rtde_worker import CallError, RTDEWorker, WorkerError
from robot.send_settings import SendResult, SendSettings
from robot.send_tool import ToolControl

__all__ = ["SendSettings", "SendResult", "SendError", "send_toolpath", "ArmSender", "dashboard_stop",
           "validate_waypoints", "printed", "chunk_entries", "pose_distance", "point_segment_distance", "point_segment_distance_nd",
           "MAX_JOINT_SPEED", "MAX_JOINT_ACCEL", "MAX_TOOL_SPEED", "MAX_TOOL_ACCEL", "MAX_BLEND"]

RUNTIME_PLAYING = 2
PROTECTIVE_BIT, ESTOP_BIT = 1 << 2, 1 << 7


_Fault = ControllerFault


class ArmSender:
    """One send of a cleared toolpath to one controller: a worker, the preflight, chunked paths and
    their monitoring (module docstring). Only `send_toolpath` makes them, after the interlock; for a
    program of several arms one per arm, joined by `lockstep` (`robot.lockstep.Lockstep`: chunks
    also end at its sync waypoints, where the arm waits for the others while its state is polled,
    and a fault of any arm stops every arm)."""

    def __init__(self, cleared: Cleared, settings: SendSettings, log: Callable[[dict], None] | None = None,
                 on_progress: Callable[[int, dict], None] | None = None, lockstep=None, arm: str = "a"):
        self.cleared = cleared
        self.lockstep, self.arm = lockstep, arm
        self.tp = cleared.toolpath
        self.wps = list(cleared.toolpath.waypoints)
        self.s = settings
        self._log = log or (lambda e: None)
        self._on_progress = on_progress or (lambda k, st: None)
        self.worker: RTDEWorker | None = None
        self.start = settings.resume_from  # a lockstep resume may start this arm at the meeting point
        self.last_completed = settings.resume_from - 1
        self.last_state: dict | None = None
        self._last_ts = None
        self._last_ts_change = 0.0
        self._watch = None  # (progress callback, op id) of the asynchronous move being watched
        self._control = False  # the control interface was connected (motion may have been commanded)
        self.tool = ToolControl(self.tp, self.call, self.poll, self.event, _Fault, settings.poll_s)

    def event(self, **kw) -> None:
        kw.setdefault("t", round(time.time(), 4))
        self._log(kw)

    def call(self, method: str, *args, timeout: float | None = None):
        return self.worker.call(method, *args, timeout=timeout or self.s.call_timeout_s)

    # ---- steps ----------------------------------------------------------------------------------
    def _resume_rule(self, wps, k, q, tcp_pose, tol) -> None:
        """A lockstep resume's start rule (`robot.lockstep.resume_start`): sets where this arm starts."""
        from robot.lockstep import resume_start

        self.start = resume_start(wps, self.lockstep.sync, k, q, tcp_pose, tol, arm=self.arm)
        self.last_completed = self.start - 1

    def preflight(self) -> str:
        lockstep_resume = self.lockstep is not None and self.s.resume_from > 0
        version = read_only_preflight(self.call, self.tp.robot, self.wps, self.s, self.event,
                                      payload=self.tool.payload is not None,
                                      verify=self._resume_rule if lockstep_resume else None)
        if self.lockstep is not None:  # every arm's read-only preflight passed before any changes
            k = self.s.resume_from
            if not self.lockstep.meet(self.arm, on_path=self.start == k) and k > 0:
                raise SendError(f"--resume-from {k}: no arm is on its path into waypoint {k}, every arm stands at "
                                f"waypoint {self.start}: give --resume-from {self.start}")
        return version

    def prepare(self) -> None:
        prepare_controller(self.call, self.s)

    def poll(self) -> dict:
        """One state sample; raises _Fault on stall, safety stop or a stopped program."""
        if self.lockstep is not None:
            self.lockstep.beat(self.arm)  # raises on an abort, or when another arm fell silent
        st = self.call("state", timeout=max(1.0, self.s.stall_s * 2))
        now = time.monotonic()
        if st["timestamp"] != self._last_ts:
            self._last_ts, self._last_ts_change = st["timestamp"], now
        elif now - self._last_ts_change > self.s.stall_s:
            raise _Fault(f"RTDE stream stalled: controller timestamp stuck at {st['timestamp']:.3f} s for "
                         f"{now - self._last_ts_change:.2f} s")
        self.last_state = st
        bits = st["safety_status_bits"]
        if bits & ESTOP_BIT:
            raise _Fault("emergency stop")
        if bits & PROTECTIVE_BIT:
            raise _Fault("protective stop")
        self.tool.verify_payload(st)
        return st

    @staticmethod
    def _op(word: int) -> tuple[int, bool, int]:
        """(operation id, running, progress) of the async status word (output_int_register_2)."""
        return (word >> 24) & 0x7F, bool(word & 0x8000), word & 0x7FFF

    def _run_async(self, method: str, args: tuple, what: str, on_running: Callable[[int, dict], None],
                   timeout_s: float) -> dict:
        """Start an asynchronous move and watch it until the controller reports it finished."""
        # A movePath re-uploads the control script, which restarts the operation counter and writes
        # a "no operation" word (op id 0) first; so our operation is the first word that differs from
        # the one before the call and carries an op id >= 1. A move too short to be seen running is
        # recognised after a second by the arm resting at its end (checked by the caller).
        base = self.poll()["progress_word"]
        if not self.call(method, *args, timeout=self.s.connect_timeout_s):
            self.poll()  # names a safety stop if that is why
            raise _Fault(f"{what} was refused by the controller")
        t_call = time.monotonic()
        t_end = t_call + timeout_s
        started = False
        while True:
            st = self.poll()
            word = st["progress_word"]
            op, running, progress = self._op(word)
            if word != base and op >= 1:
                if not started:
                    self._watch = (on_running, op)
                started = True
            elif started and op == 0:
                # a fresh script's "no operation" word in the middle of our move: ur_rtde lost the
                # link, reconnected and re-uploaded its script (which stops the program's motion)
                raise _Fault("the control script restarted mid-move: the RTDE connection dropped and "
                             "ur_rtde reconnected")
            if started and running:
                on_running(progress, st)
            if not running and (started or time.monotonic() - t_call > 1.0):
                return st
            if st["runtime_state"] != RUNTIME_PLAYING:
                raise _Fault("the control script stopped (program stopped on the controller)")
            if time.monotonic() > t_end:
                raise _Fault(f"{what} did not finish within {timeout_s:.0f} s")
            time.sleep(self.s.poll_s)

    def _expected_duration(self, start: int, stop: int) -> float:
        """A generous bound on the chunk's duration (s): every segment at its speed, plus ramps."""
        t = 0.0
        for k in range(max(start, 1), stop):
            a, b = self.wps[k - 1], self.wps[k]
            if b["move"] == "movel":
                d = np.linalg.norm(np.subtract(b["pose"][:3], a["pose"][:3]))
            else:
                d = float(np.max(np.abs(np.subtract(b["q"], a["q"]))))
            t += d / b["v"] + 2 * b["v"] / b["a"]
        return t

    def send_chunk(self, start: int, stop: int, result: SendResult) -> None:
        entries, qm, qr, red = chunk_entries(self.wps, start, stop)
        result.quantisation_m = max(result.quantisation_m, qm)
        result.quantisation_rad = max(result.quantisation_rad, qr)
        result.blend_reduction_m = max(result.blend_reduction_m, red)

        def running(progress, st):
            self.last_completed = max(self.last_completed, start + progress - 1)
            self._on_progress(self.last_completed, st)

        result.chunks_sent += 1
        st = self._run_async("move_path", (entries, True), f"movePath for waypoints {start}-{stop - 1}", running,
                             3 * self._expected_duration(start, stop) + 30.0)
        tol_m, tol_rad = max(self.s.final_tol_m, 1e-5), max(self.s.final_tol_rad, 1e-4)
        for _ in range(10):  # the receive stream may lag the control stream by a few periods
            dp, dr = pose_distance(st["tcp_pose"], self.wps[stop - 1]["pose"])
            if dp <= tol_m and dr <= tol_rad:
                break
            if st["runtime_state"] != RUNTIME_PLAYING:
                raise _Fault("the control script stopped (program stopped on the controller)")
            time.sleep(0.02)
            st = self.poll()  # raises on a safety stop
        else:
            raise _Fault(f"the path ended {dp * 1e3:.3f} mm / {math.degrees(dr):.3f} deg away from waypoint {stop - 1}")
        self.last_completed = stop - 1
        self._on_progress(self.last_completed, st)

    def finish(self, result: SendResult) -> None:
        """Register move onto the last waypoint (no rounding), then compare the final pose."""
        w = self.wps[-1]
        if w["move"] == "movej":
            method, args = "move_j", (w["q"], w["v"], w["a"], True)
        else:
            method, args = "move_l", (w["pose"], w["v"], w["a"], True)
        self._run_async(method, args, "the final register move", lambda p, st: None, 30.0)
        last = None
        for _ in range(25):  # let the receive stream catch up with the control stream: settled = the
            st = self.poll()  # pose no longer changes between two polls (bounded: 25 x 20 ms)
            dp, dr = pose_distance(st["tcp_pose"], w["pose"])
            settled = last is not None and max(pose_distance(st["tcp_pose"], last)) <= 1e-9
            if dp <= self.s.final_tol_m and dr <= self.s.final_tol_rad and settled:
                break
            last = st["tcp_pose"]
            time.sleep(0.02)
        result.final_error_m, result.final_error_rad = dp, dr
        if dp > self.s.final_tol_m or dr > self.s.final_tol_rad:
            raise _Fault(f"final pose misses waypoint {len(self.wps) - 1} by {dp * 1e3:.3f} mm / "
                         f"{math.degrees(dr):.4f} deg")
        self.last_completed = len(self.wps) - 1
        self._on_progress(self.last_completed, st)

    def settle_progress(self) -> None:
        """After a fault: the stopped program's async word still holds the last waypoint it began,
        which may be newer than the last poll saw; count it (never more than the controller says)."""
        if self._watch is None or self.worker is None or not self.worker.alive:
            return
        on_running, op = self._watch
        try:
            st = self.call("state", timeout=1.0)
        except (WorkerError, CallError):
            return
        o, running, progress = self._op(st["progress_word"])
        if o == op and running:
            on_running(progress, st)

    def abort_others(self, reason: str) -> None:
        """Tell the other arms of a lockstep send to stop (this one stops next)."""
        if self.lockstep is not None:
            self.lockstep.abort(self.arm, reason)

    def stop_arm(self) -> str:
        """stopL through the control script; if the worker does not answer, kill it and send `stop`
        on a fresh dashboard connection. Nothing to do before the control script was uploaded."""
        if not self._control:
            return "no motion was commanded"
        if self.worker is not None and self.worker.alive:
            try:
                ok = self.call("stop_l", self.s.stop_decel, timeout=2.0)
                text = "stopL done" if ok else "stopL returned False (control script not running: the arm is stopped)"
                self.event(step="stop", how=text)
                return text
            except (WorkerError, CallError) as exc:
                text = f"stopL failed: {exc}"
        else:
            text = "worker gone"
        if self.worker is not None:
            self.worker.kill()
        reply = dashboard_stop(self.s.host)
        text = f"{text}; dashboard stop: {reply}"
        self.event(step="stop", how=text)
        return text

    # ---- the whole run --------------------------------------------------------------------------
    def run(self) -> SendResult:
        s = self.s
        n = len(self.wps)
        result = SendResult(ok=False, last_completed=s.resume_from - 1, total=n, toolpath_sha256=self.cleared.sha256,
                            recheck_s=self.cleared.recheck_s)
        t0 = time.monotonic()
        self.event(step="cleared", toolpath_sha256=self.cleared.sha256, cell_sha256=self.cleared.cell.sha256,
                   fold_sha256=self.cleared.fold_sha256, recheck_s=round(self.cleared.recheck_s, 4))
        self.worker = RTDEWorker(s.host, log=self._log, priority=s.send_nice)
        with raised_priority(s.send_nice) as scheduling:
            return self._run(result, t0, scheduling)

    def _run(self, result: SendResult, t0: float, scheduling: str) -> SendResult:
        s = self.s
        n = len(self.wps)
        try:
            result.controller = self.preflight()
            self.event(step="scheduling", send_loop=scheduling, worker=self.worker.scheduling())
            self.prepare()
            self.event(step="preflight ok", controller=result.controller)
            if self.tool.grip is not None:
                self.call("connect_io", timeout=s.connect_timeout_s)
            self._control = True  # from here on a fault stops the arm
            self.call("connect_control", s.rt_priority, timeout=s.connect_timeout_s)
            if not self.call("set_tcp", list(self.tp.tcp)):
                raise _Fault("the controller refused the toolpath's TCP")
            active = self.call("get_tcp")
            if len(active) != 6 or np.abs(np.subtract(active, self.tp.tcp)).max() > 1e-9:
                raise _Fault(f"the controller's active TCP {active} is not the toolpath's {list(self.tp.tcp)}")
            holding = self.tool.holding_at(self.start)
            if self.tool.grip is not None:
                self.tool.set_gripper(holding)
            self.tool.set_payload(holding)  # before the first motion (robot.send_tool)
            # from the first move on, the controller stops the program unless every poll kicks it
            if not self.call("arm_watchdog", s.watchdog_hz):
                raise _Fault("the controller refused to arm the RTDE watchdog")
            # chunks end at grip/release waypoints (the arm stops there, the gripper switches)
            sync = set(self.lockstep.sync) if self.lockstep is not None else set()
            switch = [k for k, w in enumerate(self.wps) if w.op in ("grip", "release") or k in sync]
            if self.lockstep is not None:
                self.lockstep.wait(self.arm, 0, self.poll)  # every arm ready before any moves
            start, first = self.start, True
            while True:
                stop = min(start + max(2, s.chunk), n)
                if first and start in switch:
                    stop = start + 1  # resuming at a grip/release waypoint: go there, switch, go on
                stop = min([stop] + [k + 1 for k in switch if start < k < stop])
                self.send_chunk(start, stop, result)
                self.tool.after_waypoint(stop - 1)
                if stop - 1 in sync:
                    self.event(step="sync arrived", waypoint=stop - 1)
                    self.lockstep.wait(self.arm, stop - 1, self.poll)
                    self.event(step="sync passed", waypoint=stop - 1)
                first = False
                if stop == n:
                    break
                start = stop - 1
            self.finish(result)
            if self.lockstep is not None:
                self.lockstep.finished(self.arm)
            result.ok = True
            self.call("stop_script")  # the arm rests on the last waypoint: end the control script
        except _Fault as exc:
            result.reason = str(exc)
            self.abort_others(result.reason)
            result.events.append(self.stop_arm())
            self.settle_progress()
        except CallError as exc:
            result.reason = f"ur_rtde error: {exc}"
            self.abort_others(result.reason)
            result.events.append(self.stop_arm())
            self.settle_progress()
        except WorkerError as exc:
            result.reason = f"controller link lost: {exc}"
            self.abort_others(result.reason)
            result.events.append(self.stop_arm())
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM: stop the arm before giving up
            result.reason = "interrupted"
            self.abort_others(result.reason)
            result.events.append(self.stop_arm())
            raise
        finally:
            result.last_completed = self.last_completed
            result.elapsed_s = time.monotonic() - t0
            if result.ok:
                self.worker.close()
            else:
                self.worker.kill()
            self.event(step="done", ok=result.ok, last_completed=result.last_completed, reason=result.reason)
        return result


def send_toolpath(toolpath, check, cell, settings: SendSettings, *, fold: str | Path | None = None,
                  base_dir: str | Path | None = None, log: Callable[[dict], None] | None = None,
                  on_progress: Callable[[int, dict], None] | None = None) -> SendResult:
    """Send `toolpath` (a `robot.toolpath.Toolpath`) checked by `check` (a `sim.check.CheckReport`
    or the CHECK.json data) in `cell` (a `robot.cell.Cell` loaded from its file), per the module
    docstring. A `robot.arms_toolpath.ArmsToolpath` goes to `settings.host` (its first arm) and
    `settings.hosts` (the others), in lockstep (`robot.lockstep`); it returns a
    `robot.lockstep.ArmsSendResult`.

    `fold`: the FOLD file the toolpath was planned from (default: the one the check used, else the
    one the toolpath's source names, relative to `base_dir`). `log(event)` receives every step,
    request and reply as it happens; `on_progress(k, state)` each completed waypoint.
    Raises `SendError` (`robot.interlock.InterlockError` for the interlock) before any connection
    when the toolpath may not be sent; returns a `SendResult` once the controller was contacted.
    """
    n = len(toolpath)
    if not 0 <= settings.resume_from < n:
        raise SendError(f"--resume-from {settings.resume_from}: the toolpath has waypoints 0-{n - 1}")
    if not hasattr(toolpath, "arms") and settings.hosts:
        raise SendError(f"--host: a one-arm program goes to one controller, got {1 + len(settings.hosts)} addresses")
    cleared = clear_for_send(toolpath, check, cell, fold=fold, base_dir=base_dir)
    for _, one in getattr(cleared.toolpath, "arms", (("a", cleared.toolpath),)):
        validate_waypoints(one.waypoints)
    if hasattr(cleared.toolpath, "arms"):
        from robot.lockstep import send_in_lockstep

        return send_in_lockstep(cleared, settings, log=log, on_progress=on_progress)
    return ArmSender(cleared, settings, log=log, on_progress=on_progress).run()
