"""The controller stand-in's core: arm, I/O registers, modes and the periodic control tick.

One `Controller` per process. A tick thread runs at the controller period (500 Hz for e-Series
versions, 125 Hz for CB3) and, each tick, advances the arm, applies the safety checks, wakes the
running program (URScript's `sync()`), and streams RTDE data packages to every started
connection.

Ownership of shared state, one rule: every attribute of `Controller` (arm, registers, modes,
programs, scheduled faults, the RTDE connection list and input owners, the
command record) and every value the tick thread reads from another thread (an RTDE connection's
published output recipe and stream flags) is read and written only while holding
`Controller.lock` (a re-entrant lock). What a connection keeps for itself (its receive buffer,
its socket) belongs to that connection's thread. Sockets are written outside the lock, and the
log and the client registry (`clients.Clients`) have leaf locks of their own (nothing is acquired
under them), so no thread holds the controller lock
while it waits on a client. A lock rather than one event loop: the programs (ur_rtde's control
script, URScript) are blocking threads on a real controller too, and the tick must keep its
period whatever a client does (the network is one non-blocking loop, io_loop.py).

Over the project's ~400-line guide (about 565 lines) for that rule's sake: `Controller` is the one
writer of the state the lock guards, and its methods are all of those writes; spreading them over
modules would spread the ownership rule with them.
"""
from __future__ import annotations

import json
import os
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from robot import kinematics as K
from robot.ur_motion import JOINT_ACCEL_MAX as UR_JOINT_ACCEL_MAX
from robot.ur_arm import HOME_Q
from sim.ursim.arm import Arm
from sim.ursim.clients import Clients
from sim.ursim.motion import matrix_to_pose, pose_to_matrix
from sim.ursim.rtde_vars import INPUTS

ROBOT_MODES = {-1: "NO_CONTROLLER", 0: "DISCONNECTED", 1: "CONFIRM_SAFETY", 2: "BOOTING", 3: "POWER_OFF",
               4: "POWER_ON", 5: "IDLE", 6: "BACKDRIVE", 7: "RUNNING", 8: "UPDATING_FIRMWARE"}
SAFETY_MODES = {1: "NORMAL", 2: "REDUCED", 3: "PROTECTIVE_STOP", 4: "RECOVERY", 5: "SAFEGUARD_STOP",
                6: "SYSTEM_EMERGENCY_STOP", 7: "ROBOT_EMERGENCY_STOP", 8: "VIOLATION", 9: "FAULT"}
RUNTIME_STOPPED, RUNTIME_PLAYING, RUNTIME_PAUSED = 1, 2, 4
ROBOT_RUNNING, ROBOT_POWER_OFF, ROBOT_IDLE = 7, 3, 5
SAFETY_NORMAL, SAFETY_PROTECTIVE_STOP, SAFETY_ROBOT_ESTOP = 1, 3, 7
# safety_status_bits (RTDE guide): 0 normal, 2 protective stopped, 6 robot e-stop, 7 emergency
# stopped, 10 stopped due to safety
_SAFETY_BITS = {SAFETY_NORMAL: 1 << 0, SAFETY_PROTECTIVE_STOP: (1 << 2) | (1 << 10),
                SAFETY_ROBOT_ESTOP: (1 << 6) | (1 << 7) | (1 << 10)}
#: Commands kept by `Controller.record` (the oldest are forgotten first).
RECORD_MAX = 20000
#: Joint acceleration bound of servo motion and the configuration data (rad/s^2, URSim 5.8's value).
JOINT_ACCEL_MAX = UR_JOINT_ACCEL_MAX
#: Faults that can wait at once (admin `at_progress` / `after`).
MAX_PENDING_FAULTS = 100


@dataclass
class ControllerConfig:
    """Start-up settings of the stand-in (CLI options of `fabkit ursim` / `python -m sim.ursim`)."""

    host: str = "127.0.0.1"
    version: tuple = (5, 15, 0, 0)
    model: str = "ur5e"
    q0: tuple = HOME_Q
    robot_mode: int = ROBOT_RUNNING
    remote_control: bool = True
    unlock_delay_s: float = 5.0
    serial: str = "20235500042"
    ports: dict = field(default_factory=lambda: {"rtde": 30004, "dashboard": 29999, "primary": 30001,
                                                 "secondary": 30002, "realtime": 30003, "admin": 30020})
    cell: object = None  # robot.cell.Cell or None
    collision: object = None  # callable q -> name of the contact pair or None
    log_file: str | None = None
    verbose: bool = False
    rt_priority: int = 0  # > 0: run the tick thread SCHED_FIFO at this priority (needs the privilege)
    robot_mode_data_46: bool = False  # primary/secondary robot mode sub-package of 3.2-3.4 (python-urx 0.11)

    @property
    def cb3(self) -> bool:
        return self.version[0] < 5


class Controller:
    """State of the simulated controller plus its tick thread (see the module docstring)."""

    def __init__(self, config: ControllerConfig):
        self.cfg = config
        self.model = K.get_model(config.model)
        self.period = 1 / 125 if config.cb3 else 1 / 500
        self.lock = threading.RLock()
        self.tick_cond = threading.Condition()
        self.tick_index = 0
        self.timestamp = 0.0
        self.arm = Arm(config.q0, self.model.joint_speed_max, JOINT_ACCEL_MAX)
        self.tcp = np.eye(4)
        self.payload = 0.0
        self.payload_cog = np.zeros(3)
        self.payload_inertia = np.zeros(6)
        #: jointMaxAcceleration of the configuration data (rad/s^2, URSim 5.8); servo motion is bounded by it
        self.joint_accel_max = np.full(6, JOINT_ACCEL_MAX)
        self.tool_output_mode = 0  # RTDE tool_output_mode / tool mode info: standard digital outputs
        self.tool_digital_output_modes = [1, 1]  # 1 = sinking (NPN), the controller's default
        self.interface_streams: list = []  # client_interfaces.Stream of the 30001-30003 clients
        self.next_state_tick = 0  # tick of the next 10 Hz robot state (client_interfaces)
        self.output_getters: dict | None = None  # outputs.output_getter's table, built on first use
        self.motion_time = 0.0  # controller seconds with the arm under motion control (admin state)
        self.execution_time_ms = 0.0  # RTDE actual_execution_time: the last tick's computing time
        self.inputs = {name: (0.0 if t == "DOUBLE" else (np.zeros(6) if t == "VECTOR6D" else 0))
                       for name, t in INPUTS.items()}
        self.out_int = [0] * 48
        self.out_double = [0.0] * 48
        self.digital_out = 0
        self.digital_in = 0  # standard digital inputs (bits 0-7): admin `digital_in`, or a wire (sim.ursim.wires)
        self.analog_out = [0.0, 0.0]
        self.speed_fraction = 1.0
        self.robot_mode = config.robot_mode
        self.safety_mode = SAFETY_NORMAL
        self.safety_event_time = 0.0
        self.program = None  # the running program (control_script.ControlScript / urscript.Program)
        self.paused = False
        self.operational_mode = "NONE"  # dashboard `get operational mode`: NONE until one is set
        self.operational_mode_by_dashboard = False
        self.loaded_program: str | None = None
        self.owners: dict[str, int] = {}
        self.input_written: dict[str, float] = {}  # last RTDE write per input (for the watchdog)
        self.rtde_conns: list = []
        self.stall_until = 0.0
        self.reply_delay = 0.0
        self.stream_decimate = 1
        self.pending_faults: list[dict] = []
        self.log_lines: deque = deque(maxlen=2000)
        self._log_lock = threading.Lock()
        self._record: deque = deque(maxlen=RECORD_MAX)
        self.clients = Clients(self)
        self.last_error: str | None = None
        self._log_fh = open(config.log_file, "a", encoding="utf-8") if config.log_file else None
        self._stop = threading.Event()
        self._tcp_pose = np.zeros(6)
        self._tcp_speed = np.zeros(6)
        self._flange = np.eye(4)
        self._elbow = np.zeros(3)
        self._tcp_offset_pose = np.zeros(6)
        self._q_for_pose = None
        self._contact_depth = 0.0
        self._update_pose()
        self._thread = threading.Thread(target=self._tick_loop, name="ursim-tick", daemon=True)
        self._interfaces_thread = threading.Thread(target=self._interfaces_loop, name="ursim-interfaces",
                                                   daemon=True)

    # ---- lifecycle ---------------------------------------------------------------------------
    def start(self) -> None:
        self._thread.start()
        self._interfaces_thread.start()

    def shutdown(self) -> None:
        self._stop.set()
        with self.lock:
            if self.program is not None:
                self.program.kill("shutdown")
        for thread in (self._thread, self._interfaces_thread):
            if thread.is_alive():
                thread.join(timeout=2)

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def log(self, text: str, popup: bool = False) -> None:
        """A controller log line; `popup`: also on stderr without `--verbose` (what a real controller
        shows in a popup, e.g. a runtime error that stopped the program)."""
        line = f"{self.timestamp:10.3f} {text}"
        with self._log_lock:
            self.log_lines.append(line)
            if self._log_fh:
                self._log_fh.write(line + "\n")
                self._log_fh.flush()
            if self.cfg.verbose or popup:
                print(line, file=sys.stderr, flush=True)

    # ---- the command record (admin `record`) -------------------------------------------------
    def record(self, source: str, command: str, **values) -> None:
        """Remember one received motion or tool command exactly as the stand-in will act on it.

        `source`: "register" (ur_rtde's register protocol: doubles bit for bit), "path" (a path
        injected into ur_rtde's control script: numbers as printed in the script text), "urscript"
        (a URScript program), "rtde_io" (RTDE input registers). The last `RECORD_MAX` are kept.
        """
        entry = {"t": self.timestamp, "source": source, "command": command}
        for k, v in values.items():
            entry[k] = [float(x) for x in np.asarray(v, dtype=np.float64).reshape(-1)] if np.ndim(v) else v
        with self.lock:
            self._record.append(entry)

    def recorded(self) -> list[dict]:
        with self.lock:
            return list(self._record)

    def clear_record(self) -> None:
        with self.lock:
            self._record.clear()

    # ---- derived state -----------------------------------------------------------------------
    @property
    def runtime_state(self) -> int:
        if self.program is not None and self.program.running:
            return RUNTIME_PAUSED if self.paused else RUNTIME_PLAYING
        return RUNTIME_STOPPED

    @property
    def safety_status_bits(self) -> int:
        return _SAFETY_BITS.get(self.safety_mode, 1 << 10)

    @property
    def robot_status_bits(self) -> int:
        power = self.robot_mode in (4, 5, 6, 7)
        return int(power) | (int(self.runtime_state == RUNTIME_PLAYING) << 1)

    @property
    def tcp_pose(self) -> np.ndarray:
        return self._tcp_pose

    @property
    def tcp_speed(self) -> np.ndarray:
        return self._tcp_speed

    @property
    def speed_scaling(self) -> float:
        """RTDE `speed_scaling` (the trajectory limiter): 1 while moving freely, 0 while paused. The
        slider is `target_speed_fraction`; the arm runs at their product (reference §5.1)."""
        return 0.0 if self.paused else 1.0

    def can_move(self) -> bool:
        return self.robot_mode == ROBOT_RUNNING and self.safety_mode == SAFETY_NORMAL

    def _update_pose(self) -> None:
        q = self.arm.q
        if self._q_for_pose is not None and np.array_equal(q, self._q_for_pose):
            self._tcp_speed = np.zeros(6)
            return
        frames = K.fk_frames(self.model, q)  # once per tick: the flange, and the elbow RTDE reports
        self._flange = frames[6]
        self._elbow = frames[3, :3, 3].copy()
        new = matrix_to_pose(self._flange @ self.tcp)
        if self._q_for_pose is not None:
            lin = (new[:3] - self._tcp_pose[:3]) / self.period
            self._tcp_speed = np.r_[lin, np.zeros(3)]
        self._tcp_pose = new
        self._q_for_pose = q.copy()

    def set_tcp(self, pose) -> None:
        with self.lock:
            self.tcp = pose_to_matrix(pose)
            self._tcp_offset_pose = matrix_to_pose(self.tcp)
            self._q_for_pose = None
            self._update_pose()

    def tcp_offset_pose(self) -> np.ndarray:
        return self._tcp_offset_pose

    @property
    def elbow_position(self) -> np.ndarray:
        """The elbow (DH frame 3) in the base frame at the last tick (RTDE `elbow_position`)."""
        return self._elbow

    # ---- registers ---------------------------------------------------------------------------
    def read_input(self, name: str):
        return self.inputs[name]

    def apply_inputs(self, values: dict) -> None:
        """Set input variables from one RTDE data package (atomically) and act on the IO ones."""
        with self.lock:
            self.inputs.update(values)
            now = time.monotonic()
            for name in values:
                self.input_written[name] = now
            if "standard_digital_output_mask" in values:
                m = int(values["standard_digital_output_mask"])
                self.digital_out = (self.digital_out & ~m) | (int(values.get("standard_digital_output", 0)) & m)
            if "configurable_digital_output_mask" in values:
                m = int(values["configurable_digital_output_mask"]) << 8
                v = int(values.get("configurable_digital_output", 0)) << 8
                self.digital_out = (self.digital_out & ~m) | (v & m)
            if "tool_digital_output_mask" in values:
                m = int(values["tool_digital_output_mask"]) << 16
                v = int(values.get("tool_digital_output", 0)) << 16
                self.digital_out = (self.digital_out & ~m) | (v & m)
            for key in ("standard", "configurable", "tool"):
                if values.get(f"{key}_digital_output_mask"):
                    self.record("rtde_io", f"set_{key}_digital_output", mask=int(values[f"{key}_digital_output_mask"]),
                                value=int(values.get(f"{key}_digital_output", 0)))
            if values.get("speed_slider_mask"):
                self.speed_fraction = float(np.clip(values.get("speed_slider_fraction", 1.0), 0.0, 1.0))
            if "standard_analog_output_mask" in values:
                m = int(values["standard_analog_output_mask"])
                for i in range(2):
                    if m & (1 << i):
                        self.analog_out[i] = float(values.get(f"standard_analog_output_{i}", 0.0))

    def output_value(self, name: str):
        """Current value of an RTDE output variable (registers, state, arm)."""
        return self.output_getter(name)()

    def output_getter(self, name: str):
        """A callable giving the current value of RTDE output `name` (see `outputs`)."""
        from sim.ursim.outputs import output_getter

        return output_getter(self, name)

    def set_payload(self, mass: float, cog=None, inertia=None, source: str = "urscript") -> None:
        """`set_payload(m, cog)` / ur_rtde `setPayload`: store and report the payload (RTDE
        `payload`, `payload_cog`, `payload_inertia`, the real-time package, admin `state`) and
        lower the arm's joint acceleration bound for it (`robot.ur_motion.joint_accel_bound`); a
        mass over the arm's rated payload is refused (`ValueError`)."""
        from robot.loads import arm_rating
        from robot.ur_motion import joint_accel_bound

        if not (np.isfinite(mass) and 0.0 <= mass <= 1000.0):
            raise ValueError(f"set_payload: mass {mass} kg is not a payload")
        bound = joint_accel_bound(mass, arm_rating(self.model.name).payload, JOINT_ACCEL_MAX)
        with self.lock:
            self.arm.joint_accel_max = bound
            self.payload = float(mass)
            if cog is not None:
                self.payload_cog = np.asarray(cog, dtype=np.float64).reshape(3)
            self.payload_inertia = np.zeros(6) if inertia is None else np.asarray(inertia, dtype=np.float64)
            self.log(f"payload {self.payload:g} kg, CoG {self.payload_cog.tolist()} ({source})")
        self.record(source, "set_payload", mass=float(mass), cog=self.payload_cog.copy())

    # ---- program management ------------------------------------------------------------------
    def start_program(self, program) -> bool:
        """Replace the running program with `program` (as a controller does on a new script)."""
        with self.lock:
            if self.program is not None and self.program.running:
                self.program.kill("replaced by a new program")
            if not self.can_move():
                self.log(f"program {program.name} not started: robot mode {ROBOT_MODES.get(self.robot_mode)}, "
                         f"safety {SAFETY_MODES.get(self.safety_mode)}")
                self.program = None
                return False
            self.paused = False
            self.program = program
            program.start()
            return True

    def stop_program(self, reason: str) -> None:
        with self.lock:
            if self.program is not None and self.program.running:
                self.program.kill(reason)
            self.arm.halt()
            self.paused = False

    def runtime_error(self, text: str, program=None) -> None:
        """A runtime error of `program` (default: the running one): it stops (the controller's
        popup/log line). A program that was already replaced only logs it: its error must not stop
        the program that replaced it, nor the arm that program drives."""
        with self.lock:
            if program is not None and program is not self.program:
                self.log(f"runtime error in the replaced program {getattr(program, 'name', '?')}: {text}")
                return
            self.last_error = text
            self.log(f"runtime error: {text}", popup=True)
            if self.program is not None and self.program.running:
                self.program.kill(f"runtime error: {text}")
            self.arm.halt()

    # ---- safety ------------------------------------------------------------------------------
    def protective_stop(self, reason: str) -> None:
        with self.lock:
            if self.safety_mode == SAFETY_PROTECTIVE_STOP:
                return
            self.safety_mode = SAFETY_PROTECTIVE_STOP
            self.safety_event_time = time.monotonic()
            self.last_error = f"protective stop: {reason}"
            self.log(f"PROTECTIVE STOP: {reason}", popup=True)
            if self.program is not None and self.program.running:
                self.program.kill("protective stop")
            self.arm.halt()

    def emergency_stop(self, reason: str = "emergency stop button") -> None:
        with self.lock:
            self.safety_mode = SAFETY_ROBOT_ESTOP
            self.safety_event_time = time.monotonic()
            self.last_error = f"emergency stop: {reason}"
            self.log(f"EMERGENCY STOP: {reason}", popup=True)
            if self.program is not None and self.program.running:
                self.program.kill("emergency stop")
            self.arm.halt()

    def release_emergency_stop(self) -> None:
        with self.lock:
            if self.safety_mode == SAFETY_ROBOT_ESTOP:
                self.safety_mode = SAFETY_NORMAL
                self.robot_mode = ROBOT_POWER_OFF
                self.log("emergency stop released; robot powered off")

    def unlock_protective_stop(self) -> str:
        with self.lock:
            if self.safety_mode != SAFETY_PROTECTIVE_STOP:
                return "Protective stop releasing"
            if time.monotonic() - self.safety_event_time < self.cfg.unlock_delay_s:
                return ("Cannot unlock protective stop until 5s after occurrence. "
                        "Always inspect cause of protective stop before unlocking")
            self.safety_mode = SAFETY_NORMAL
            self.log("protective stop unlocked")
            return "Protective stop releasing"

    def _safety_checks(self) -> None:
        arm = self.arm
        if arm.mode == "idle" and not np.any(arm.qd):
            return
        over = np.abs(arm.qd) > np.asarray(self.model.joint_speed_max) * 1.02 + 1e-9
        if np.any(over):
            j = int(np.argmax(over))
            self.protective_stop(f"joint {j} speed limit ({abs(arm.qd[j]):.3f} rad/s)")
            return
        lo, hi = np.asarray(self.model.q_min), np.asarray(self.model.q_max)
        if np.any(arm.q < lo - 1e-9) or np.any(arm.q > hi + 1e-9):
            self.protective_stop("joint position limit")
            return
        if self.cfg.collision is not None:
            # a new or deepening contact stops the arm; moving out of a contact is allowed (as a
            # controller lets the arm back away after a collision stop)
            hit = self.cfg.collision(arm.q)
            depth = hit[1] if hit else 0.0
            if hit and depth > self._contact_depth + 1e-4:
                self.protective_stop(f"collision: {hit[0]} ({depth * 1e3:.1f} mm)")
            self._contact_depth = depth

    # ---- the tick ----------------------------------------------------------------------------
    def wait_tick(self, last: int, timeout: float = 0.5) -> int:
        """Block until the tick after `last` (URScript `sync()`); returns the new tick index."""
        with self.tick_cond:
            if self.tick_index == last:
                self.tick_cond.wait(timeout)
            return self.tick_index

    def _tick_loop(self) -> None:
        if self.cfg.rt_priority > 0:
            try:  # tid 0 = this thread only; the servers stay at normal priority
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.cfg.rt_priority))
                self.log(f"tick thread runs SCHED_FIFO priority {self.cfg.rt_priority}")
            except (PermissionError, OSError, AttributeError) as exc:
                self.log(f"real-time priority not available ({exc}); tick thread at normal priority")
        period = self.period
        t0 = time.monotonic()
        k = 0
        while not self._stop.is_set():
            k += 1
            delay = t0 + k * period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            t_tick = time.perf_counter()
            steps = 1
            if delay < -period:  # fell behind: skip the missed ticks (a controller sends the newest)
                missed = int(-delay / period)
                k += missed
                steps += min(missed, 50)
            with self.lock:
                try:
                    for j in range(steps):  # catching up: every missed period is simulated and checked
                        self.timestamp = (k - steps + 1 + j) * period
                        if self.arm.mode != "idle":
                            self.motion_time += period
                        self.arm.step(period, self.speed_fraction if not self.paused else 0.0, self.timestamp)
                        self._safety_checks()
                    self._update_pose()
                    self._run_pending_faults()
                except Exception as exc:  # a bug must not silence the controller: stop the program, go on
                    self.log(f"stand-in error in the control tick: {type(exc).__name__}: {exc}")
                    self.arm.halt()
                    if self.program is not None and self.program.running:
                        self.program.kill("stand-in error")
                self.tick_index = k
                self.execution_time_ms = (time.perf_counter() - t_tick) * 1e3
            with self.tick_cond:
                self.tick_cond.notify_all()
            self._stream(k)

    def _interfaces_loop(self) -> None:
        """The 30001-30003 streams, in a thread of their own: however many clients they have, they
        never delay the tick or its RTDE packages (a tick they miss is skipped, the newest sent)."""
        from sim.ursim.client_interfaces import stream_interfaces

        last = self.tick_index
        while not self._stop.is_set():
            k = self.wait_tick(last)
            if k == last:
                continue
            last = k
            if self.interface_streams:
                try:
                    stream_interfaces(self, k)
                except Exception as exc:  # a bug here must not stop the streams for good
                    self.log(f"stand-in error in the interface streams: {type(exc).__name__}: {exc}")

    def _stream(self, k: int) -> None:
        with self.lock:
            if time.monotonic() < self.stall_until:
                return
            conns = list(self.rtde_conns)
        for conn in conns:
            try:
                conn.maybe_send(k, self)
            except Exception as exc:  # one bad recipe or socket must not stop the others
                self.log(f"rtde client {conn.id}: cannot send ({type(exc).__name__}: {exc}): closing")
                conn.close()

    # ---- scheduled faults --------------------------------------------------------------------
    def schedule_fault(self, fault: dict) -> None:
        """Queue a fault; an `at_progress` fault only counts progress written after it was queued."""
        with self.lock:
            if len(self.pending_faults) >= MAX_PENDING_FAULTS:
                raise ValueError(f"{MAX_PENDING_FAULTS} faults are already scheduled")
            fault.setdefault("armed_word", self.out_int[2])
            self.pending_faults.append(fault)

    def _run_pending_faults(self) -> None:
        """Run the due faults (validated when scheduled); a fault runs once, whatever happens."""
        if not self.pending_faults:
            return
        word = self.out_int[2]
        progress = word & 0x7FFF if word & 0x8000 else None
        keep, due_now = [], []
        for f in self.pending_faults:
            if f.get("armed_word") is not None and word != f["armed_word"]:
                f["armed_word"] = None  # the async status changed since the fault was queued
            due = (f.get("at_time") is not None and time.monotonic() >= f["at_time"]) or \
                  (f.get("at_progress") is not None and f.get("armed_word") is None and progress is not None
                   and progress >= f["at_progress"])
            (due_now if due else keep).append(f)
        self.pending_faults = keep
        if due_now:
            from sim.ursim.admin import apply_fault

            for f in due_now:
                try:
                    apply_fault(self, f["kind"], f.get("arg"))
                except ValueError as exc:
                    self.log(f"scheduled fault {f['kind']} not applied: {exc}")

    # ---- a JSON-able view for the admin channel and tests ------------------------------------
    def state(self) -> dict:
        with self.lock:
            return {
                "timestamp": self.timestamp, "q": self.arm.q.tolist(), "tcp_pose": self._tcp_pose.tolist(),
                "tcp_offset": self.tcp_offset_pose().tolist(),
                "robot_mode": ROBOT_MODES.get(self.robot_mode), "safety_mode": SAFETY_MODES.get(self.safety_mode),
                "runtime_state": self.runtime_state, "program": getattr(self.program, "name", None),
                "arm_mode": self.arm.mode, "digital_out": self.digital_out, "digital_in": self.digital_in,
                "out_int": self.out_int[:8],
                "speed_fraction": self.speed_fraction, "last_error": self.last_error,
                "payload": self.payload, "payload_cog": self.payload_cog.tolist(),
                "operational_mode": self.operational_mode, "clients": self.clients.count(),
                "pending_faults": len(self.pending_faults), "motion_time": self.motion_time,
                "rtde_clients": len(self.rtde_conns), "log_tail": list(self.log_lines)[-20:],
            }

    def state_json(self) -> str:
        return json.dumps(self.state())
