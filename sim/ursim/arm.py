"""The simulated arm's motion executor: advances planned trajectories, servo and speed control one
controller period at a time, and stops them (decelerating stop or immediate halt).

Trajectories come from `sim.ursim.motion.plan_moves` (`robot.ur_motion`'s model, joint
accelerations within the payload's bound `joint_accel_max`) and are time-scaled by the speed slider
f: each tick advances them by f periods, so the path is unchanged, speeds scale by f and
accelerations by f^2. Servo and speed control, and stops from them, are bounded by
`joint_accel_max`; a halt (protective or emergency stop, a killed program) stops at once.

Called from the controller's tick thread only; other threads hand it work through the methods
below, which take the controller lock. Callbacks run in the tick thread and must be quick.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from sim.ursim.motion import Trajectory


class Arm:
    """Joint state of the simulated arm and whatever is moving it."""

    def __init__(self, q0, joint_speed_max, joint_accel_max: float = 40.0):
        self.q = np.array(q0, dtype=np.float64)
        self.qd = np.zeros(6)
        self.qdd = np.zeros(6)
        self.joint_accel_max = float(joint_accel_max)
        self.target_q = self.q.copy()
        self.joint_speed_max = np.asarray(joint_speed_max, dtype=np.float64)
        self.mode = "idle"  # idle | traj | servo | speed
        self._traj: Trajectory | None = None
        self._tau = 0.0
        self._rate = 1.0
        self._decel: float | None = None
        self._next_marker = 0
        self._on_marker: Callable[[int], None] | None = None
        self._on_done: Callable[[bool], None] | None = None
        self._servo_target = self.q.copy()
        self._speed_target = np.zeros(6)
        self._speed_acc = 1.0
        self._speed_deadline: float | None = None
        self._after_speed_stop: Callable[[bool], None] | None = None

    # ---- commands (hold the controller lock when calling) --------------------------------------
    def run(self, traj: Trajectory, on_marker=None, on_done=None) -> None:
        """Start a trajectory (its first sample must be the current q). `on_done(completed)`."""
        self._finish(False)
        self._traj, self._tau, self._rate, self._decel = traj, 0.0, 1.0, None
        self._next_marker, self._on_marker, self._on_done = 0, on_marker, on_done
        self.mode = "traj"
        self._fire_markers()

    def servo(self, q_target) -> None:
        if self.mode != "servo":
            self._finish(False)
            self.mode = "servo"
        self._servo_target = np.asarray(q_target, dtype=np.float64)

    def speed(self, qd, acceleration: float, duration: float | None = None, now: float = 0.0) -> None:
        if self.mode != "speed":
            self._finish(False)
            self.mode = "speed"
        self._speed_target = np.asarray(qd, dtype=np.float64)
        self._speed_acc = min(max(float(acceleration), 1e-6), self.joint_accel_max)
        self._speed_deadline = now + duration if duration else None

    def stop(self, deceleration: float, on_done=None) -> None:
        """Decelerate to rest along the current motion at `deceleration` (rad/s^2 or m/s^2)."""
        deceleration = max(float(deceleration), 1e-6)
        if self.mode == "traj":
            prev = self._on_done
            self._decel = deceleration

            def done(completed, prev=prev):
                if prev:
                    prev(False)
                if on_done:
                    on_done(True)
            self._on_done = done
            self._on_marker = None
        elif self.mode in ("speed", "servo"):  # servo: ramp the current joint speed down as well
            self.mode = "speed"
            self._speed_target = np.zeros(6)
            self._speed_acc = min(deceleration, self.joint_accel_max)
            self._speed_deadline = None
            self._after_speed_stop = on_done
        else:
            self.mode = "idle"
            self.qd[:] = 0.0
            if on_done:
                on_done(True)

    def halt(self) -> None:
        """Stop at once (protective stop, e-stop, program killed): cancel everything."""
        self._finish(False)
        self.mode = "idle"
        self.qd[:] = 0.0
        self.qdd[:] = 0.0
        self.target_q = self.q.copy()

    @property
    def moving(self) -> bool:
        return self.mode != "idle" or bool(np.any(np.abs(self.qd) > 1e-9))

    # ---- the periodic step ---------------------------------------------------------------------
    def step(self, dt: float, fraction: float = 1.0, now: float = 0.0) -> None:
        q_prev, qd_prev = self.q.copy(), self.qd.copy()
        if self.mode == "traj":
            self._step_traj(fraction)
        elif self.mode == "servo":
            self._step_servo(dt, fraction)
        elif self.mode == "speed":
            if self._speed_deadline is not None and now >= self._speed_deadline:
                self._speed_target = np.zeros(6)
            dv = self._speed_target - self.qd
            lim = self._speed_acc * dt
            self.qd = self.qd + np.clip(dv, -lim, lim)
            self.q = self.q + self.qd * dt
            self.target_q = self.q.copy()
            if not np.any(self._speed_target) and not np.any(np.abs(self.qd) > 1e-12):
                self.mode = "idle"
                cb, self._after_speed_stop = self._after_speed_stop, None
                if cb:
                    cb(True)
        if self.mode != "speed":
            self.qd = (self.q - q_prev) / dt
        self.qdd = (self.qd - qd_prev) / dt

    def _step_servo(self, dt: float, fraction: float) -> None:
        """Toward the servo target at the joint speed limit (times the speed slider) with the joint
        acceleration bounded, braking so as to stop on the target (lookahead and gain ignored)."""
        d = self._servo_target - self.q
        a = self.joint_accel_max
        # the speed from which the arm still stops on the target losing a*dt per period:
        # v^2 / (2a) + v dt / 2 = |d|  (the discrete form of v = sqrt(2 a |d|))
        v_stop = a * (np.sqrt(dt * dt / 4.0 + 2.0 * np.abs(d) / a) - dt / 2.0)
        v_want = np.sign(d) * np.minimum(self.joint_speed_max * fraction, v_stop)
        v = self.qd + np.clip(v_want - self.qd, -a * dt, a * dt)
        step = v * dt
        arrive = (np.abs(step) >= np.abs(d)) & (step * d >= 0)  # the last step lands exactly
        self.q = np.where(arrive, self._servo_target, self.q + step)
        self.target_q = self._servo_target.copy()

    def _step_traj(self, fraction: float) -> None:
        tr = self._traj
        n = len(tr.q) - 1
        k = min(int(self._tau), n)
        if self._decel is not None:
            v = tr.speed[k] * self._rate
            if v <= 1e-12:
                self._rate = 0.0
            else:
                self._rate = max(0.0, self._rate * (1.0 - self._decel * tr.dt / v))
        self._tau = min(self._tau + self._rate * fraction, float(n))
        k = int(self._tau)
        f = self._tau - k
        self.q = tr.q[k] if k >= n else tr.q[k] + (tr.q[k + 1] - tr.q[k]) * f
        self.target_q = self.q.copy()
        self._fire_markers()
        if self._tau >= n:
            self.q = tr.q[-1].copy()
            self._finish(True)
            self.mode = "idle"
        elif self._decel is not None and self._rate <= 0.0:
            self._finish(True)
            self.mode = "idle"

    def _fire_markers(self) -> None:
        tr = self._traj
        while tr is not None and self._next_marker < len(tr.markers) and tr.markers[self._next_marker][0] <= self._tau:
            value = tr.markers[self._next_marker][1]
            self._next_marker += 1
            if self._on_marker:
                self._on_marker(value)

    def _finish(self, completed: bool) -> None:
        cb = self._on_done
        self._traj, self._on_done, self._on_marker, self._decel = None, None, None, None
        if cb:
            cb(completed)
