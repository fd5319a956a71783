"""Emulation of ur_rtde's uploaded control script (`def rtde_control(): ... end`).

The stand-in does not interpret that 40-50 KB URScript generally; it recognises it, reads what
the upload carries (the register offset, 0 or 24, which ur_rtde injects on the line *after* its
marker comment, and the path injected into `exec_move_path()`), and runs the script's main loop
and command table in Python with the same register protocol (reference ur-rtde.md §2.2-2.7):

- each controller period: read the command id from `input_int_register_0` (+offset);
- "realtime" commands (servo/speed/forceMode/...) run every period and answer ready (1);
- other commands run once (blocking for synchronous moves), then write done (2) to
  `output_int_register_0`; command 0 writes ready (1); 255 ends the script;
- asynchronous moves run in the emulated `move_thread`, which reports the waypoint index through
  the async progress word in `output_int_register_2` (running bit 15, change counter bits 16-23,
  operation id bits 24-30), exactly as the script's `write_async_progress_register` does.

The RTDE watchdog (`rtde_set_watchdog`) stops the program when its register is not written for
1 / f s. A controller reads its network in real time; this stand-in shares the client's CPU, and
its network thread can fall behind on a loaded machine. So a watchdog that would fire while bytes
of the client that owns the register sit unread in the stand-in (`RTDEConnection.input_waiting`)
waits for them, up to `MAX_READER_LAG_S` more: a client that went quiet is stopped on time, one
the stand-in has not read yet is not stopped for the stand-in's lateness.
"""
from __future__ import annotations

import re
import threading
import time

import numpy as np

from robot import kinematics as K
from sim.ursim.motion import PlanError, Waypoint, matrix_to_pose, plan_moves, pose_to_matrix
from sim.ursim.urscript import (Killed, ScriptError, parse_statements, path_waypoints, record_waypoints,
                                resolve_fk_targets)

HEADER = "def rtde_control():"
REALTIME = {24, 11, 9, 10, 6, 25, 26, 27, 38, 58, 66, 67, 68, 69, 70, 71}
LOADED_MSG = "RTDE Control Script Loaded (14.02.2024-12:23)"
_INT_OFFSET = re.compile(r"global reg_offset_int = # int register offset\n(\d+)")
_FLOAT_OFFSET = re.compile(r"global reg_offset_float = # float register offset\n(\d+)")
#: [s] longest the watchdog waits, past 1 / f, for client bytes the stand-in has not read yet
MAX_READER_LAG_S = 1.0
_PATH = re.compile(r"# inject move path\n(.*?)^[ \t]*end[ \t]*$", re.S | re.M)


def is_control_script(text: str) -> bool:
    return text.lstrip().startswith(HEADER)


def parse_upload(text: str) -> tuple[int, int, list[Waypoint]]:
    """(int register offset, float register offset, injected path waypoints) of an upload."""
    mi, mf = _INT_OFFSET.search(text), _FLOAT_OFFSET.search(text)
    if not mi or not mf:
        raise ScriptError("control script without register offsets (unknown ur_rtde version?)")
    path: list[Waypoint] = []
    mp = _PATH.search(text)
    if mp and mp.group(1).strip():
        start = text[:mp.start(1)].count("\n") + 1
        lines = [(start + i, ln) for i, ln in enumerate(mp.group(1).split("\n"))]
        path = path_waypoints(parse_statements(lines))
    return int(mi.group(1)), int(mf.group(1)), path


class ControlScript:
    """The running control script: a thread doing the script's main loop (module docstring)."""

    name = "rtde_control"

    def __init__(self, ctrl, text: str):
        self.ctrl = ctrl
        self.off_i, self.off_f, self.path = parse_upload(text)
        self.running = False
        self._killed = threading.Event()
        self._wr_count = 0
        self._op_id = 0
        self._move_active = False
        self._move_token = 0
        self._thread = threading.Thread(target=self._main, name="rtde_control", daemon=True)
        self.watchdog: float | None = None
        self._watchdog_set = 0.0

    # ---- program interface -------------------------------------------------------------------
    def start(self) -> None:
        """Called under the controller lock: the script's first cycle (up to its first sync())
        writes ready in the same period in which the program becomes PLAYING."""
        self.ctrl.log("textmsg: " + LOADED_MSG)
        self._write_async(-1)  # reset_async_progress()
        self._out_i(0, 1)  # signal_ready()
        self.running = True
        self._thread.start()

    def kill(self, reason: str) -> None:
        if self.running:
            self.running = False  # runtime_state is STOPPED from here on
            self._killed.set()
            self.ctrl.log(f"RTDE Control Script Terminated ({reason})")

    # ---- registers ---------------------------------------------------------------------------
    def _i(self, k: int) -> int:
        with self.ctrl.lock:
            return int(self.ctrl.inputs[f"input_int_register_{k + self.off_i}"])

    def _d(self, k: int) -> float:
        with self.ctrl.lock:
            return float(self.ctrl.inputs[f"input_double_register_{k + self.off_f}"])

    def _vec(self, k: int) -> np.ndarray:
        with self.ctrl.lock:  # one RTDE package's values, never half of the next
            return np.array([self._d(k + j) for j in range(6)])

    def _out_i(self, k: int, value: int) -> None:
        with self.ctrl.lock:
            self.ctrl.out_int[k + self.off_i] = int(value)

    def _out_vec(self, k: int, vec) -> None:
        with self.ctrl.lock:
            for j, v in enumerate(np.asarray(vec, dtype=np.float64).reshape(-1)[:6]):
                self.ctrl.out_double[k + j + self.off_f] = float(v)

    def _write_async(self, value: int) -> None:
        """`write_async_progress_register` of the script, bit for bit."""
        self._wr_count = 0 if self._wr_count + 1 > 127 else self._wr_count + 1
        if value == 0:
            self._op_id = 0 if self._op_id + 1 > 127 else self._op_id + 1
        reg = self._wr_count * 65536 + self._op_id * 16777216
        if value >= 0:
            reg += min(value, 32767) + 32768
        self._out_i(2, reg)

    # ---- main loop ---------------------------------------------------------------------------
    def _main(self) -> None:
        ctrl = self.ctrl
        executing = False
        last, last_cmd = ctrl.tick_index, 0
        try:
            while not self._killed.is_set():
                last = ctrl.wait_tick(last)
                if self._killed.is_set():
                    break
                self._check_watchdog()
                cmd = self._i(0)
                if cmd != last_cmd and cmd not in REALTIME:
                    ctrl.log(f"rtde_control: command {cmd}")
                last_cmd = cmd
                if cmd in REALTIME:
                    self._process(cmd)
                    self._out_i(0, 1)
                elif cmd == 0:
                    executing = False
                    self._out_i(0, 1)
                elif not executing:
                    keep = self._process(cmd)
                    executing = True
                    if not keep:
                        break
        except Killed:
            return
        except (PlanError, ScriptError) as exc:
            ctrl.runtime_error(str(exc), self)
            return
        except Exception as exc:  # a bug in the emulation must not look like a hang
            ctrl.runtime_error(f"stand-in error: {type(exc).__name__}: {exc}", self)
            return
        with ctrl.lock:
            if self.running:
                ctrl.log("textmsg: RTDE Control Script Terminated")
                self.running = False

    def _check(self) -> None:
        if self._killed.is_set():
            raise Killed()

    def _check_watchdog(self) -> None:
        """`rtde_set_watchdog(input_int_register_0, f, "stop")`: stop when the client goes quiet."""
        if not self.watchdog:
            return
        name = f"input_int_register_{self.off_i}"
        quiet = time.monotonic() - max(self.ctrl.input_written.get(name, 0.0), self._watchdog_set)
        if quiet <= 1.0 / self.watchdog:
            return
        owner = self.ctrl.owners.get(name)
        behind = any(conn.id == owner and conn.input_waiting() for conn in list(self.ctrl.rtde_conns))
        if behind and quiet <= 1.0 / self.watchdog + MAX_READER_LAG_S:
            return  # the client has written: this stand-in has not read it yet
        lag = f"; the stand-in's network thread is over {MAX_READER_LAG_S:g} s behind its clients" if behind else ""
        raise PlanError(f"RTDE watchdog: {name} not updated for {quiet:.3f} s "
                        f"(minimum {self.watchdog:g} Hz){lag}: program stopped")

    # ---- moves -------------------------------------------------------------------------------
    def _plan(self, waypoints: list[Waypoint]):
        ctrl = self.ctrl
        return plan_moves(ctrl.model, ctrl.tcp, ctrl.arm.q.copy(), resolve_fk_targets(ctrl, waypoints), ctrl.period,
                          joint_accel_max=ctrl.arm.joint_accel_max)

    def _move(self, waypoints: list[Waypoint], asynchronous: bool) -> None:
        ctrl = self.ctrl
        self._stop_async_move()
        if not ctrl.can_move():
            raise Killed()
        traj = self._plan(waypoints)
        if asynchronous:
            with ctrl.lock:
                self._check()
                self._move_token += 1
                token = self._move_token
                self._move_active = True
                self._write_async(0)  # move_thread: signal_async_operation_started()

                def marker(v):
                    if v > 0 and self.running:  # progress 0 is the start signal already written
                        self._write_async(v)

                def done(completed, token=token):
                    # a killed program writes nothing more (its threads die with it)
                    if self.running and self._move_active and self._move_token == token:
                        self._move_active = False
                        self._write_async(-1)  # signal_async_operation_finished()
                ctrl.arm.run(traj, on_marker=marker, on_done=done)
            return
        finished = threading.Event()
        with ctrl.lock:
            self._check()
            ctrl.arm.run(traj, on_done=lambda ok: finished.set())
        while not finished.wait(0.05):
            self._check()
            self._check_watchdog()
        self._check()

    def _stop_async_move(self, deceleration: float | None = None) -> None:
        """`stop_async_move()`: kill the move thread (the arm stops) and report it finished."""
        ctrl = self.ctrl
        with ctrl.lock:
            if self._move_active:
                self._move_active = False
                if deceleration is None:
                    ctrl.arm.halt()
                else:
                    ctrl.arm.stop(deceleration)
                self._write_async(-1)

    def _wait_rest(self) -> None:
        ctrl = self.ctrl
        while True:
            with ctrl.lock:
                if not ctrl.arm.moving:
                    return
            self._check()
            ctrl.wait_tick(ctrl.tick_index)

    def _ik(self, pose, qnear=None) -> np.ndarray:
        ctrl = self.ctrl
        sols = K.ik(ctrl.model, pose_to_matrix(pose), ctrl.tcp)
        if len(sols) == 0:
            raise PlanError("get_inverse_kin(): no solution for the pose")
        return K.select_nearest(sols, ctrl.arm.q if qnear is None else qnear, model=ctrl.model)

    # ---- the command table -------------------------------------------------------------------
    def _process(self, cmd: int) -> bool:
        ctrl = self.ctrl
        i, d, vec = self._i, self._d, self._vec
        if cmd in (1, 2, 3, 4):
            target, v, a, asyn = vec(0), d(6), d(7), i(1) == 1
            ctrl.record("register", {1: "moveJ", 2: "moveJ_IK", 3: "moveL", 4: "moveL_FK"}[cmd],
                        **({"q": target} if cmd in (1, 4) else {"pose": target}), v=v, a=a)
            if cmd == 1:
                wp = Waypoint("movej", v, a, q=tuple(target))
            elif cmd == 2:
                wp = Waypoint("movej", v, a, q=tuple(self._ik(target)))
            elif cmd == 3:
                wp = Waypoint("movel", v, a, pose=tuple(target))
            else:
                wp = Waypoint("movel", v, a, q=tuple(target))
            self._move([wp], asyn)
        elif cmd == 45:
            if not self.path:
                raise PlanError("move_path: no path was injected into the script")
            record_waypoints(ctrl, "path", self.path)
            self._move(self.path, i(1) == 1)
        elif cmd in (9, 10):
            qd = vec(0)
            if cmd == 10:  # speedl: tool speed -> joint speed through the flange Jacobian
                qd = np.linalg.lstsq(K.jacobian(ctrl.model, ctrl.arm.q), qd, rcond=None)[0]
            with ctrl.lock:
                self._stop_async_move()
                ctrl.arm.speed(qd, d(6), d(7) if d(7) > 0 else None, ctrl.timestamp)
        elif cmd in (11, 24):
            q = vec(0) if cmd == 11 else self._ik(vec(0))
            with ctrl.lock:
                self._stop_async_move()
                ctrl.arm.servo(q)
        elif cmd in (15, 16, 42):
            ctrl.record("register", "stop", command_id=cmd)
            with ctrl.lock:
                ctrl.arm.stop(d(0) if cmd != 42 else 1.2)
            self._wait_rest()
        elif cmd in (33, 34):
            ctrl.record("register", "stopL" if cmd == 33 else "stopJ", deceleration=d(0))
            asyn = i(1) == 1
            self._stop_async_move(d(0))
            with ctrl.lock:
                ctrl.arm.stop(d(0))
            if not asyn:
                self._wait_rest()
        elif cmd in (17, 65):  # setPayload / setTargetPayload (its inertia is not carried here)
            cog = [d(1), d(2), d(3)] if any(d(k) for k in (1, 2, 3)) else None
            try:
                ctrl.set_payload(d(0), cog, source="register")
            except ValueError as exc:
                raise PlanError(str(exc)) from None
        elif cmd == 26:
            self._out_vec(0, [ctrl.period])
        elif cmd in (27, 58):
            self._out_vec(0, ctrl.arm.q if cmd == 27 else matrix_to_pose(K.fk(ctrl.model, ctrl.arm.q)))
        elif cmd == 28:
            self._out_vec(0, ctrl.tcp_pose)
        elif cmd == 29:
            ctrl.set_tcp(vec(0))
            ctrl.record("register", "setTcp", pose=vec(0))
        elif cmd in (30, 46):
            self._out_vec(0, self._ik(vec(0), vec(6) if cmd == 30 else None))
        elif cmd in (60, 61):
            try:
                self._ik(vec(0))
                ok = 1
            except PlanError:
                ok = 0
            self._out_i(1, ok)
        elif cmd == 31:
            ctrl.protective_stop("protective_stop() called by the program")
            raise Killed()
        elif cmd == 35:
            self.watchdog = d(0) if d(0) > 0 else None
            self._watchdog_set = time.monotonic()
        elif cmd == 36:
            try:
                q = self._ik(vec(0))
                ok = int(self._within_limits(q))
            except PlanError:
                ok = 0
            self._out_i(1, ok)
        elif cmd == 37:
            self._out_i(1, int(self._within_limits(vec(0))))
        elif cmd == 38:
            self._out_vec(0, np.zeros(6))
        elif cmd == 39:
            self._out_vec(0, matrix_to_pose(pose_to_matrix(vec(0)) @ pose_to_matrix(vec(6))))
        elif cmd == 40:
            self._out_vec(0, ctrl.tcp_offset_pose())
        elif cmd == 43:
            self._out_vec(0, ctrl.tcp_pose)
        elif cmd == 44:
            self._out_vec(0, matrix_to_pose(K.fk_tcp(ctrl.model, vec(0), pose_to_matrix(vec(6)))))
        elif cmd == 47:
            self._out_i(1, int(not ctrl.arm.moving))
        elif cmd in (25, 63, 64, 54):
            self._out_i(1, 0)  # no tool contact / freedrive in the stand-in
        elif cmd in (67, 68, 69, 70, 71):
            # dynamics getters (mass matrix, Jacobians ...): the stand-in's arm is kinematic, so the
            # result registers say "no value" (NaN) instead of carrying stale numbers
            with ctrl.lock:
                for k in list(range(0, 24)) + list(range(36, 48)):
                    ctrl.out_double[k] = float("nan")
        elif cmd in (6, 7, 8, 18, 19, 20, 21, 52, 53, 56, 57, 59, 62, 66):
            pass  # force/teach/freedrive/gravity settings: accepted, no effect on the kinematic arm
        elif cmd == 255:
            ctrl.log("textmsg: Received stop script!")
            self.kill("stop script command")
            return False
        else:
            raise PlanError(f"command {cmd} is not emulated by the controller stand-in")
        if cmd not in REALTIME:
            self._out_i(0, 2)  # signal_done_with_cmd()
        return True

    def _within_limits(self, q) -> bool:
        m = self.ctrl.model
        q = np.asarray(q)
        return bool(np.all(q >= np.asarray(m.q_min)) and np.all(q <= np.asarray(m.q_max)))
