"""What the script ports send: the primary/secondary client interfaces (30001/30002) and the
real-time interface (30003), big-endian, in the layouts of a 5.x controller (reference
ur-client-interfaces.md §1-2, checked there against a URSim 5.8 capture).

- 30001/30002: on connect a version message (type 20, robot message 3), then every 100 ms a
  robot state message (type 16) of 13 sub-packages in the controller's order and sizes: robot
  mode (47 B, or 46 B with `ControllerConfig.robot_mode_data_46` for python-urx 0.11, which
  parses only the 3.2-3.4 size), joint data, cartesian info, kinematics info, calibration,
  masterboard, tool data, configuration, force mode, additional info, safety data, tool
  communication and tool mode info: 1386 B in all. 30001 sends no robot messages besides the
  version message (no key, error-code or runtime-exception messages).
- 30003: one 1220-byte package (int32 size + 152 doubles, the 5.10+ layout) every controller
  period.

Values that the kinematic arm does not have (currents, torques, forces) are 0; temperatures and
voltages are constant plausible numbers; UR-internal fields carry the capture's values.
"""
from __future__ import annotations

import socket
import struct

import numpy as np

from sim.ursim.controller import (RUNTIME_PAUSED, RUNTIME_PLAYING, SAFETY_PROTECTIVE_STOP, SAFETY_ROBOT_ESTOP)

#: Seconds between robot state messages on 30001/30002 (10 Hz on every controller).
STATE_PERIOD_S = 0.1
REALTIME_SIZE = 1220
_ROBOT_TYPE = {"ur3e": 3, "ur5e": 1, "ur10e": 2, "ur16e": 4}
_JOINT_RUNNING, _JOINT_IDLE, _JOINT_POWER_OFF = 253, 255, 239


def _sub(kind: int, fmt: str, *values) -> bytes:
    body = struct.pack(">" + fmt, *values)
    return struct.pack(">iB", 5 + len(body), kind) + body


def version_message(ctrl) -> bytes:
    major, minor, bugfix, build = ctrl.cfg.version
    name = b"URControl"
    body = struct.pack(">Qbbb", 0, -2, 3, len(name)) + name + struct.pack(">BBii", major, minor, bugfix, build)
    body += b"21-11-2026, 00:00:00"
    return struct.pack(">iB", 5 + len(body), 20) + body


def snapshot(ctrl) -> dict:
    """Everything both interfaces report, read at one instant (under the controller lock)."""
    with ctrl.lock:
        arm = ctrl.arm
        return {
            "t": ctrl.timestamp, "q": arm.q.copy(), "q_target": arm.target_q.copy(), "qd": arm.qd.copy(),
            "qdd": arm.qdd.copy(), "pose": ctrl.tcp_pose.copy(), "pose_target": ctrl.tcp_pose.copy(),
            "tcp_speed": ctrl.tcp_speed.copy(), "tcp_offset": ctrl.tcp_offset_pose(),
            "robot_mode": ctrl.robot_mode, "safety_mode": ctrl.safety_mode, "runtime": ctrl.runtime_state,
            "speed_fraction": ctrl.speed_fraction, "speed_scaling": ctrl.speed_scaling,
            "digital_in": ctrl.digital_in, "digital_out": ctrl.digital_out, "analog_out": list(ctrl.analog_out),
            "safety_status_bits": ctrl.safety_status_bits, "payload": ctrl.payload,
            "payload_cog": ctrl.payload_cog.copy(), "elbow": ctrl.elbow_position.copy(),
            "tool_output_mode": ctrl.tool_output_mode, "tool_do_modes": tuple(ctrl.tool_digital_output_modes),
        }


def _power_on(s) -> bool:
    return s["robot_mode"] in (4, 5, 6, 7)


def robot_state_message(ctrl, s: dict | None = None) -> bytes:
    """One type-16 robot state message (module docstring)."""
    s = s or snapshot(ctrl)
    m = ctrl.model
    on = _power_on(s)
    estop = s["safety_mode"] in (6, SAFETY_ROBOT_ESTOP)
    running, paused = s["runtime"] == RUNTIME_PLAYING, s["runtime"] == RUNTIME_PAUSED
    mode_fmt = "Q???????BBddd" + ("" if ctrl.cfg.robot_mode_data_46 else "B")
    mode_vals = [int(s["t"] * 1e9), True, True, on, estop, s["safety_mode"] == SAFETY_PROTECTIVE_STOP, running,
                 paused, s["robot_mode"], 0, s["speed_fraction"], s["speed_scaling"], 1.0]
    parts = [_sub(0, mode_fmt, *(mode_vals + ([] if ctrl.cfg.robot_mode_data_46 else [0])))]
    jmode = _JOINT_RUNNING if s["robot_mode"] == 7 else _JOINT_IDLE if on else _JOINT_POWER_OFF
    joints = []
    for j in range(6):
        joints += [s["q"][j], s["q_target"][j], s["qd"][j], 0.0, 48.0 if on else 0.0, 32.0, 0.0, jmode]
    parts.append(_sub(1, "dddffffB" * 6, *joints))
    parts.append(_sub(4, "12d", *s["pose"], *s["tcp_offset"]))
    parts.append(_sub(5, "6I24dI", *([0xFFFFFFFF] * 6), *([0.0] * 6), *m.a, *m.d, *m.alpha, 0))
    parts.append(_sub(9, "6d", *([0.0] * 6)))
    parts.append(_sub(3, "IIBBddbbddffffB??IBBB", s["digital_in"], s["digital_out"] & 0xFFFFFFFF, 1, 1, 0.0, 0.0,
                      0, 0, *s["analog_out"], 24.0, 48.0 if on else 0.0, 0.0, 0.0, s["safety_mode"], False, False,
                      0x57F4285B, 1, True, 1))
    tool_on = on and s["robot_mode"] == 7
    parts.append(_sub(2, "bbddfBffB", 1, 1, 0.0, 0.0, 24.0 if on else 0.0, 24 if on else 0, 0.0, 30.0,
                      _JOINT_RUNNING if tool_on else _JOINT_IDLE if on else _JOINT_POWER_OFF))
    limits = [v for j in range(6) for v in (m.q_min[j], m.q_max[j])]
    speeds = [v for j in range(6) for v in (m.joint_speed_max[j], ctrl.joint_accel_max[j])]
    parts.append(_sub(6, "24d5d24d4i", *limits, *speeds, 1.0472, 1.3963, 0.25, 1.2, 0.25, *m.a, *m.d, *m.alpha,
                      *([0.0] * 6), 6, 4, _ROBOT_TYPE.get(m.name, 1), 3))
    parts.append(_sub(7, "7d", *([0.0] * 6), 0.0))
    parts.append(_sub(8, "B??B", 0, True, False, 1))
    parts.append(_sub(10, "IBB4d", 0x57F4285B, 1, 1, -0.0949, -0.0633, 0.5823, 0.13))
    parts.append(_sub(11, "?iiiff", False, 115200, 0, 1, 1.5, 3.5))
    parts.append(_sub(12, "BBB", s["tool_output_mode"], *s["tool_do_modes"]))
    body = b"".join(parts)
    return struct.pack(">iB", 5 + len(body), 16) + body


_RT = struct.Struct(">i152d")


def realtime_package(ctrl, s: dict | None = None) -> bytes:
    """One 1220-byte real-time package (reference ur-client-interfaces.md §2.2)."""
    s = s or snapshot(ctrl)
    on = _power_on(s)
    jmode = _JOINT_RUNNING if s["robot_mode"] == 7 else _JOINT_IDLE if on else _JOINT_POWER_OFF
    z6 = [0.0] * 6
    v = [s["t"], *s["q_target"], *s["qd"], *s["qdd"], *z6, *z6, *s["q"], *s["qd"], *z6, *z6, *s["pose"],
         *s["tcp_speed"], *z6, *s["pose_target"], *s["tcp_speed"], float(s["digital_in"]), *([32.0] * 6), s["t"],
         0.0, float(s["robot_mode"]), *([float(jmode)] * 6), float(s["safety_mode"]), *z6, 0.0, 0.0, 9.81, *z6,
         s["speed_scaling"], 0.0, 0.0, 0.0, 48.0, 48.0 if on else 0.0, 0.0, *([47.5 if on else 0.0] * 6),
         float(s["digital_out"]), float(s["runtime"]), *s["elbow"], 0.0, 0.0, 0.0, float(s["safety_mode"]),
         0.0, 0.0, 0.0, s["payload"], *s["payload_cog"], *z6]
    return _RT.pack(REALTIME_SIZE, *v)


class Stream:
    """One client's share of a periodic stream: writes never block the tick. A package that does not
    fit in the socket buffer is skipped whole (framing intact), as ur_rtde never reads the 30003
    socket it uploads its script on; the client is not dropped."""

    def __init__(self, sock: socket.socket, kind: str):
        self.sock, self.kind = sock, kind
        self._rest = b""
        self.skipped = 0

    def offer(self, data: bytes) -> None:
        if self._rest:
            self._rest = self._write(self._rest, keep=True)
            if self._rest:
                self.skipped += 1
                return
        self._rest = self._write(data, keep=False)

    def _write(self, data: bytes, keep: bool) -> bytes:
        """What is left of `data` after one non-blocking send; a package of which nothing went out
        is kept only if it was already started (`keep`)."""
        try:
            n = self.sock.send(data, socket.MSG_DONTWAIT)
        except (BlockingIOError, InterruptedError):
            if not keep:
                self.skipped += 1
            return data if keep else b""
        except OSError:
            return b""
        return data[n:]


def stream_interfaces(ctrl, k: int) -> None:
    """The real-time package every period to 30003 clients, the robot state every 100 ms to
    30001/30002 clients (called by the tick thread)."""
    with ctrl.lock:
        streams = list(ctrl.interface_streams)
    if not streams:
        return
    rt = [st for st in streams if st.kind == "realtime"]
    state = []
    if k >= ctrl.next_state_tick:  # due tick, not k % n: a tick skipped under load must not skip a state
        every = max(1, int(round(STATE_PERIOD_S / ctrl.period)))
        late = k - ctrl.next_state_tick  # a few ticks under load: stay on the 100 ms grid (10 Hz on
        # average); much more (no client for a while): start a new grid
        ctrl.next_state_tick = ctrl.next_state_tick + every if late < every // 2 else k + every
        state = [st for st in streams if st.kind != "realtime"]
    if not rt and not state:
        return
    snap = snapshot(ctrl)
    if rt:
        pkg = realtime_package(ctrl, snap)
        for st in rt:
            st.offer(pkg)
    if state:
        msg = robot_state_message(ctrl, snap)
        for st in state:
            st.offer(msg)
