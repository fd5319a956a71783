"""Send a checked toolpath to a UR controller over RTDE with ur_rtde (in a supervised worker).

`send_toolpath(toolpath, settings)` does, in order:

1. validate the motion arguments against ur_rtde's ranges and the blend rule (r = 0 at the end,
   neighbouring blends must not overlap);
2. preflight over the dashboard: robot mode RUNNING, safety NORMAL, remote control on
   (`power_on` powers on and releases the brakes first; `unlock` clears a protective stop that is
   older than 5 s);
3. connect the receive and control interfaces (worker process, timeouts on every call), set the TCP;
4. send the waypoints from `resume_from` as blended `movePath` chunks, asynchronously, and watch
   the receive stream every `poll_s`: the timestamp must advance, safety must stay normal, the
   control script must keep running, and the async progress register gives the waypoint index;
5. finish with a register move (full double precision) onto the last waypoint and compare the
   final pose with the toolpath's.

Path numbers pass through ur_rtde's script injection printed with 6 significant digits; the
sender measures that rounding (`quantisation_m`/`_rad`, below 1 um / 10 urad for poses within
~1 m), shrinks blend radii by the rounding so that blends cannot overlap after it, and lands the
last waypoint through the registers so the end pose carries no rounding at all.

On any fault (protective or emergency stop, program stopped, stream stalled or lost, worker
crashed or hung, a timeout) it stops the arm (stopL through the control script if that still
answers, else the worker is killed), and returns a `SendResult` naming the last completed waypoint
and the reason; `resume_from` continues from there.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from robot.rtde_worker import CallError, RTDEWorker, WorkerError

# ur_rtde's client-side argument ranges (reference ur-rtde.md §2.6)
MAX_JOINT_SPEED, MAX_JOINT_ACCEL = 3.14, 40.0
MAX_TOOL_SPEED, MAX_TOOL_ACCEL = 3.0, 150.0
MAX_BLEND = 2.0
RUNTIME_PLAYING = 2
PROTECTIVE_BIT, ESTOP_BIT = 1 << 2, 1 << 7


class SendError(Exception):
    """The toolpath cannot be sent as given (bad motion arguments, far from the resume point)."""


@dataclass(frozen=True)
class SendSettings:
    """How to send. Times in seconds; tolerances in metres and radians."""

    host: str
    chunk: int = 50
    resume_from: int = 0
    power_on: bool = False
    unlock: bool = False
    monitor_hz: float = 125.0
    poll_s: float = 0.02
    stall_s: float = 0.5
    call_timeout_s: float = 10.0
    connect_timeout_s: float = 20.0
    stop_decel: float = 2.0
    final_tol_m: float = 2e-4
    final_tol_rad: float = 2e-3
    resume_tol_m: float = 0.005
    start_tol_rad: float = 0.01  # a fresh start needs the arm this close to waypoint 0 (joints)
    rt_priority: int = -1
    connect_retry_s: float = 3.0  # keep trying the dashboard this long (a controller still starting)


@dataclass
class SendResult:
    """What happened: `ok`, `last_completed` (index of the last waypoint reached, -1 for none),
    `reason` (None when ok), and measurements."""

    ok: bool
    last_completed: int
    total: int
    reason: str | None = None
    chunks_sent: int = 0
    elapsed_s: float = 0.0
    final_error_m: float | None = None
    final_error_rad: float | None = None
    quantisation_m: float = 0.0
    quantisation_rad: float = 0.0
    blend_reduction_m: float = 0.0
    controller: str | None = None
    events: list = field(default_factory=list)

    def to_json(self) -> dict:
        return {k: v for k, v in self.__dict__.items()}


# ---- checks before anything leaves the process -----------------------------------------------------

def validate_waypoints(waypoints: list[dict]) -> None:
    """ur_rtde's argument ranges and the blend rule; raises SendError naming the waypoint."""
    n = len(waypoints)
    for i, w in enumerate(waypoints):
        lin = w["move"] == "movel"
        vmax, amax = (MAX_TOOL_SPEED, MAX_TOOL_ACCEL) if lin else (MAX_JOINT_SPEED, MAX_JOINT_ACCEL)
        unit = "m/s" if lin else "rad/s"
        if not 0 < w["v"] <= vmax:
            raise SendError(f"waypoint {i}: speed {w['v']} {unit} outside (0, {vmax}]")
        if not 0 < w["a"] <= amax:
            raise SendError(f"waypoint {i}: acceleration {w['a']} {unit}^2 outside (0, {amax}]")
        if not 0 <= w["r"] <= MAX_BLEND:
            raise SendError(f"waypoint {i}: blend radius {w['r']} m outside [0, {MAX_BLEND}]")
    if waypoints[-1]["r"] != 0:
        raise SendError(f"waypoint {n - 1}: the last waypoint must have blend radius 0")
    P = np.array([w["pose"][:3] for w in waypoints])
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    r = np.array([w["r"] for w in waypoints])
    for i in range(n - 1):
        if r[i] + r[i + 1] > seg[i] * (1 + 1e-9) + 1e-12:
            raise SendError(f"waypoints {i}-{i + 1}: blend radii {r[i]:g} + {r[i + 1]:g} m overlap on a "
                            f"{seg[i]:.6g} m segment (UR rejects overlapping blends)")


def printed(x: float) -> float:
    """The value ur_rtde's script injection prints for `x` (iostream default: 6 significant digits)."""
    return float(f"{x:.6g}")


def chunk_entries(waypoints: list[dict], start: int, stop: int) -> tuple[list, float, float, float]:
    """movePath entries for waypoints[start:stop] with the arm at rest at both ends.

    Blend radii are reduced where the printed (rounded) positions would make them overlap. Returns
    (entries, max position rounding m, max rotation-vector rounding rad, largest blend reduction m).
    """
    entries, qm, qr, red = [], 0.0, 0.0, 0.0
    ws = waypoints[start:stop]
    pos = np.array([[printed(x) for x in w["pose"][:3]] for w in ws])
    seg = np.linalg.norm(np.diff(pos, axis=0), axis=1) if len(ws) > 1 else np.zeros(0)
    for k, w in enumerate(ws):
        r = 0.0 if k == 0 or k == len(ws) - 1 else float(w["r"])
        if r > 0:
            limit = 0.499 * min(seg[k - 1], seg[k])  # strictly inside half of each rounded neighbour
            if r > limit:
                red = max(red, r - limit)
                r = max(limit, 0.0)
        if w["move"] == "movej":
            vals = list(w["q"])
            qr = max(qr, max(abs(printed(x) - x) for x in vals))
            entries.append(("movej", "q", vals + [w["v"], w["a"], r]))
        else:
            vals = list(w["pose"])
            qm = max(qm, max(abs(printed(x) - x) for x in vals[:3]))
            qr = max(qr, max(abs(printed(x) - x) for x in vals[3:]))
            entries.append(("movel", "pose", vals + [w["v"], w["a"], r]))
    return entries, qm, qr, red


def pose_distance(a, b) -> tuple[float, float]:
    """(position distance m, rotation angle rad) between two UR poses."""
    from scipy.spatial.transform import Rotation

    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    ang = (Rotation.from_rotvec(a[3:]).inv() * Rotation.from_rotvec(b[3:])).magnitude()
    return float(np.linalg.norm(a[:3] - b[:3])), float(ang)


def point_segment_distance(p, a, b) -> float:
    """Distance (m) from position p to the segment a-b (UR poses or points; positions only)."""
    return point_segment_distance_nd(np.asarray(p)[:3], np.asarray(a)[:3], np.asarray(b)[:3])


def point_segment_distance_nd(p, a, b) -> float:
    """Euclidean distance from point p to the segment a-b in any dimension."""
    p, a, b = (np.asarray(x, dtype=np.float64) for x in (p, a, b))
    ab = b - a
    t = 0.0 if not np.any(ab) else float(np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


# ---- the sender -----------------------------------------------------------------------------------

class _Fault(Exception):
    pass


class Sender:
    """One send: a worker, the preflight, chunked paths and their monitoring (module docstring)."""

    def __init__(self, toolpath, settings: SendSettings, log: Callable[[dict], None] | None = None,
                 on_progress: Callable[[int, dict], None] | None = None):
        self.tp = toolpath
        self.wps = [dict(w) for w in toolpath.waypoints]
        self.s = settings
        self._log = log or (lambda e: None)
        self._on_progress = on_progress or (lambda k, st: None)
        self.worker: RTDEWorker | None = None
        self.last_completed = settings.resume_from - 1
        self.last_state: dict | None = None
        self._last_ts = None
        self._last_ts_change = 0.0
        self._watch = None  # (progress callback, op id) of the asynchronous move being watched

    def event(self, **kw) -> None:
        kw.setdefault("t", round(time.time(), 4))
        self._log(kw)

    def call(self, method: str, *args, timeout: float | None = None):
        return self.worker.call(method, *args, timeout=timeout or self.s.call_timeout_s)

    # ---- steps ----------------------------------------------------------------------------------
    def preflight(self) -> str:
        s = self.s
        t_end = time.monotonic() + s.connect_retry_s
        while True:
            try:
                version = self.call("connect_dashboard", timeout=s.connect_timeout_s)
                break
            except CallError:
                if time.monotonic() > t_end:
                    raise
                time.sleep(0.25)
        mode = self.call("dashboard", "robotmode")
        if "RUNNING" not in mode:
            if not s.power_on:
                raise _Fault(f"preflight: {mode!r}, expected 'Robotmode: RUNNING' (use --power-on)")
            self.call("dashboard", "power on")
            self._wait_dashboard("robotmode", ("IDLE", "RUNNING"), 30.0)
            self.call("dashboard", "brake release")
            mode = self._wait_dashboard("robotmode", ("RUNNING",), 30.0)
        safety = self.call("dashboard", "safetystatus")
        if "PROTECTIVE_STOP" in safety and s.unlock:
            # a controller refuses for 5 s after the stop: wait that out, then give up
            t_end = time.monotonic() + 6.0
            while (reply := self.call("dashboard", "unlock protective stop")) != "Protective stop releasing":
                if time.monotonic() > t_end:
                    raise _Fault(f"preflight: unlock refused: {reply!r}")
                time.sleep(0.5)
            self.call("dashboard", "close safety popup")
            safety = self.call("dashboard", "safetystatus")
        if safety != "Safetystatus: NORMAL":
            hint = " (use --unlock after inspecting the cause)" if "PROTECTIVE" in safety else ""
            raise _Fault(f"preflight: {safety!r}, expected 'Safetystatus: NORMAL'{hint}")
        remote = self.call("dashboard", "is in remote control")
        if "true" not in remote.lower():
            raise _Fault(f"preflight: remote control is off ({remote!r}); switch the pendant to Remote Control")
        model = self.call("dashboard", "get robot model").strip()
        want = str(self.tp.robot).lower().removesuffix("e").upper()  # e-Series answer "UR5", "UR10"
        if model.upper() != want:
            raise _Fault(f"preflight: the controller reports robot model {model!r}, the toolpath is for "
                         f"{self.tp.robot}")
        return version

    def _wait_dashboard(self, command: str, words: tuple, timeout: float) -> str:
        t_end = time.monotonic() + timeout
        while True:
            reply = self.call("dashboard", command)
            if any(w in reply for w in words):
                return reply
            if time.monotonic() > t_end:
                raise _Fault(f"preflight: {reply!r} after {timeout:g} s")
            time.sleep(0.2)

    def poll(self) -> dict:
        """One state sample; raises _Fault on stall, safety stop or a stopped program."""
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
        for _ in range(10):  # let the receive stream catch up with the control stream
            st = self.poll()
            dp, dr = pose_distance(st["tcp_pose"], w["pose"])
            if dp <= self.s.final_tol_m and dr <= self.s.final_tol_rad:
                break
            time.sleep(0.02)
        result.final_error_m, result.final_error_rad = dp, dr
        if dp > self.s.final_tol_m or dr > self.s.final_tol_rad:
            raise _Fault(f"final pose misses waypoint {len(self.wps) - 1} by {dp * 1e3:.3f} mm / "
                         f"{math.degrees(dr):.4f} deg")
        self.last_completed = len(self.wps) - 1
        self._on_progress(self.last_completed, st)

    # ---- gripper --------------------------------------------------------------------------------
    def _grip(self) -> dict | None:
        g = self.tp.extra.get("grip") if isinstance(getattr(self.tp, "extra", None), dict) else None
        return g if isinstance(g, dict) and "output" in g else None

    def gripper_state_at(self, k: int) -> bool:
        """Whether the gripper is closed while moving toward waypoint k (grip ... release)."""
        on = False
        for w in self.wps[:k]:
            if w["op"] == "grip":
                on = True
            elif w["op"] == "release":
                on = False
        return on

    def set_gripper(self, on: bool, dwell: float = 0.0) -> None:
        g = self._grip()
        if g is None:
            return
        kind, n = str(g.get("kind", "tool")), int(g["output"])
        if not self.call("set_output", kind, n, on):
            raise _Fault(f"the controller refused to set the {kind} digital output {n}")
        bit = 1 << (n + (16 if kind == "tool" else 0))
        t_end = time.monotonic() + 2.0
        while bool(self.poll()["digital_out"] & bit) != on:  # confirmed by the receive stream
            if time.monotonic() > t_end:
                raise _Fault(f"the {kind} digital output {n} did not switch {'on' if on else 'off'}")
            time.sleep(self.s.poll_s)
        self.event(step="gripper", on=on, output=n, kind=kind)
        if dwell > 0:
            t_end = time.monotonic() + dwell
            while time.monotonic() < t_end:  # keep watching the link while dwelling
                self.poll()
                time.sleep(min(self.s.poll_s, max(0.0, t_end - time.monotonic())))

    def after_waypoint(self, k: int) -> None:
        g = self._grip()
        op = self.wps[k]["op"]
        if g is not None and op in ("grip", "release"):
            self.set_gripper(op == "grip", float(g.get(f"{op}_dwell_s", 0.5)))

    def check_resume(self) -> None:
        """Where the arm must stand before sending. A fresh start: at waypoint 0 (the check covered
        the motion between waypoints, not from an arbitrary pose to the first one). A resume: on
        the way into waypoint `resume_from` (near the TCP line from the previous waypoint for a
        movel, near the joint-space line for a movej)."""
        k = self.s.resume_from
        st = self.poll()
        if k == 0:
            off = np.abs(np.subtract(st["q"], self.wps[0]["q"]))
            if off.max() > self.s.start_tol_rad:
                j = int(np.argmax(off))
                raise _Fault(f"the arm is not at waypoint 0 (joint {j + 1} is {off[j]:.3f} rad away): move it "
                             f"there first (the check did not cover a move from here)")
            return
        a, b = self.wps[k - 1], self.wps[k]
        if b["move"] == "movej":
            d = point_segment_distance_nd(st["q"], a["q"], b["q"])
            tol = 0.02
            if d > tol:
                raise SendError(f"--resume-from {k}: the joints are {d:.3f} rad from the joint move between "
                                f"waypoints {k - 1} and {k} (allowed {tol} rad); move the arm there first")
            return
        d = point_segment_distance(st["tcp_pose"], a["pose"], b["pose"])
        tol = self.s.resume_tol_m + max(a["r"], b["r"])
        if d > tol:
            raise SendError(f"--resume-from {k}: the TCP is {d * 1e3:.1f} mm from the segment between waypoints "
                            f"{k - 1} and {k} (allowed {tol * 1e3:.1f} mm); move the arm there first")

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

    def stop_arm(self) -> str:
        """Best effort: stopL through the control script; kill the worker if it does not answer."""
        if self.worker is None or not self.worker.alive:
            return "worker already gone"
        try:
            ok = self.call("stop_l", self.s.stop_decel, timeout=2.0)
            return "stopL done" if ok else "stopL returned False (control script not running: the arm is stopped)"
        except (WorkerError, CallError) as exc:
            return f"stopL failed: {exc}"

    # ---- the whole run --------------------------------------------------------------------------
    def run(self) -> SendResult:
        s = self.s
        n = len(self.wps)
        result = SendResult(ok=False, last_completed=s.resume_from - 1, total=n)
        t0 = time.monotonic()
        if not 0 <= s.resume_from < n:
            raise SendError(f"--resume-from {s.resume_from}: the toolpath has waypoints 0-{n - 1}")
        validate_waypoints(self.wps)
        self.worker = RTDEWorker(s.host, log=self._log)
        try:
            result.controller = self.preflight()
            self.event(step="preflight ok", controller=result.controller)
            self.call("connect_receive", s.monitor_hz, timeout=s.connect_timeout_s)
            self.call("connect_control", s.rt_priority, timeout=s.connect_timeout_s)
            if not self.call("set_tcp", list(self.tp.tcp)):
                raise _Fault("the controller refused the toolpath's TCP")
            active = self.call("get_tcp")
            if len(active) != 6 or np.abs(np.subtract(active, self.tp.tcp)).max() > 1e-9:
                raise _Fault(f"the controller's active TCP {active} is not the toolpath's {list(self.tp.tcp)}")
            if self._grip() is not None:
                self.call("connect_io", timeout=s.connect_timeout_s)
                self.set_gripper(self.gripper_state_at(s.resume_from))
            self.check_resume()
            # chunks end at grip/release waypoints (the arm stops there, the gripper switches)
            switch = [k for k, w in enumerate(self.wps) if w["op"] in ("grip", "release")]
            start, first = s.resume_from, True
            while True:
                stop = min(start + max(2, s.chunk), n)
                if first and start in switch:
                    stop = start + 1  # resuming at a grip/release waypoint: go there, switch, go on
                stop = min([stop] + [k + 1 for k in switch if start < k < stop])
                self.send_chunk(start, stop, result)
                self.after_waypoint(stop - 1)
                first = False
                if stop == n:
                    break
                start = stop - 1
            self.finish(result)
            result.ok = True
        except _Fault as exc:
            result.reason = str(exc)
            result.events.append(self.stop_arm())
            self.settle_progress()
        except CallError as exc:
            result.reason = f"ur_rtde error: {exc}"
            result.events.append(self.stop_arm())
            self.settle_progress()
        except WorkerError as exc:
            result.reason = f"controller link lost: {exc}"
        except KeyboardInterrupt:  # Ctrl-C: stop the arm before giving up
            result.reason = "interrupted"
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


def send_toolpath(toolpath, settings: SendSettings, log=None, on_progress=None) -> SendResult:
    """Send `toolpath` (a `robot.toolpath.Toolpath`) per the module docstring."""
    return Sender(toolpath, settings, log=log, on_progress=on_progress).run()
