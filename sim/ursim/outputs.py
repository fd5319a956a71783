"""RTDE output values of the controller stand-in: one getter per variable, resolved once per
recipe (the tick does no name parsing). Getters read `Controller` state: call them under
`Controller.lock`."""
from __future__ import annotations

import numpy as np

from robot import kinematics as K

_JOINT_MODE_RUNNING = np.full(6, 253, dtype=np.int64)  # JOINT_RUNNING_MODE
_JOINT_MODE_IDLE = np.full(6, 250, dtype=np.int64)  # JOINT_IDLE_MODE (brakes on)
_TEMPS = np.full(6, 32.0)
_VOLTS = np.full(6, 47.5)
_ACC = np.array([0.0, 0.0, 9.81])
_ZERO6 = np.zeros(6)
ROBOT_RUNNING = 7


def _zero():
    """An output the stand-in does not model: zeros of the variable's width (see rtde_server)."""
    return 0


def output_getter(ctrl, name: str):
    """A callable giving the current value of output `name`."""
    if name.startswith("output_int_register_"):
        k = int(name[20:])
        return lambda: ctrl.out_int[k]
    if name.startswith("output_double_register_"):
        k = int(name[23:])
        return lambda: ctrl.out_double[k]
    if name.startswith("input_"):
        return lambda: ctrl.inputs.get(name, 0)
    if name.startswith("output_bit_register"):
        return lambda: 0
    if ctrl.output_getters is None:
        ctrl.output_getters = _getters(ctrl)
    return ctrl.output_getters.get(name, _zero)


def _elbow_velocity(ctrl) -> np.ndarray:
    q, qd = ctrl.arm.q, ctrl.arm.qd
    if not np.any(qd):
        return np.zeros(3)
    h = 1e-6
    return (K.fk_frames(ctrl.model, q + qd * h)[3, :3, 3] - K.fk_frames(ctrl.model, q)[3, :3, 3]) / h


def _getters(ctrl) -> dict:
    arm = ctrl.arm
    return {
        "timestamp": lambda: ctrl.timestamp,
        "target_q": lambda: arm.target_q, "target_qd": lambda: arm.qd, "actual_q": lambda: arm.q,
        "actual_qd": lambda: arm.qd, "actual_TCP_pose": lambda: ctrl.tcp_pose,
        "target_TCP_pose": lambda: ctrl.tcp_pose, "actual_TCP_speed": lambda: ctrl.tcp_speed,
        "target_TCP_speed": lambda: ctrl.tcp_speed, "robot_mode": lambda: ctrl.robot_mode,
        "safety_mode": lambda: ctrl.safety_mode, "safety_status": lambda: ctrl.safety_mode,
        "runtime_state": lambda: ctrl.runtime_state, "robot_status_bits": lambda: ctrl.robot_status_bits,
        "safety_status_bits": lambda: ctrl.safety_status_bits,
        "actual_digital_output_bits": lambda: ctrl.digital_out,
        "actual_digital_input_bits": lambda: ctrl.digital_in,
        "speed_scaling": lambda: ctrl.speed_scaling,
        "target_speed_fraction": lambda: ctrl.speed_fraction,
        "standard_analog_output0": lambda: ctrl.analog_out[0],
        "standard_analog_output1": lambda: ctrl.analog_out[1],
        "joint_mode": lambda: _JOINT_MODE_RUNNING if ctrl.robot_mode == ROBOT_RUNNING else _JOINT_MODE_IDLE,
        "joint_temperatures": lambda: _TEMPS, "actual_main_voltage": lambda: 48.0,
        "actual_robot_voltage": lambda: 48.0 if ctrl.robot_mode >= 4 else 0.0,
        "actual_joint_voltage": lambda: _VOLTS, "actual_execution_time": lambda: ctrl.execution_time_ms,
        "actual_tool_accelerometer": lambda: _ACC, "payload": lambda: ctrl.payload,
        "payload_cog": lambda: ctrl.payload_cog, "payload_inertia": lambda: ctrl.payload_inertia,
        "target_qdd": lambda: arm.qdd, "elbow_velocity": lambda: _elbow_velocity(ctrl),
        "tool_output_mode": lambda: ctrl.tool_output_mode,
        "tool_digital_output0_mode": lambda: ctrl.tool_digital_output_modes[0],
        "tool_digital_output1_mode": lambda: ctrl.tool_digital_output_modes[1],
        "actual_configurable_digital_output_bits": lambda: (ctrl.digital_out >> 8) & 0xFF,
        "tool_output_voltage": lambda: 24 if ctrl.robot_mode >= 4 else 0,
        "tool_mode": lambda: _JOINT_MODE_RUNNING[0] if ctrl.robot_mode == ROBOT_RUNNING else 255,
        "tool_temperature": lambda: 30.0, "target_moment": lambda: _ZERO6,
        "tcp_offset": lambda: ctrl.tcp_offset_pose(),
        "elbow_position": lambda: ctrl.elbow_position,
    }
