"""RTDE variable names with their official wire types, and the binary framing of RTDE v2.

The types follow UR's RTDE guide / Universal_Robots_Client_Library `data_package.cpp`: ur_rtde
ignores the type strings the controller returns and parses every data package with its own
hard-coded sizes, so each variable must go out at its official size or every later field is
misparsed (reference ur-rtde.md §1.3).
"""
from __future__ import annotations

import struct

#: RTDE type name -> struct format (big-endian, without the leading ">").
TYPE_FORMATS: dict[str, str] = {
    "BOOL": "?", "UINT8": "B", "INT32": "i", "UINT32": "I", "UINT64": "Q", "DOUBLE": "d",
    "VECTOR3D": "3d", "VECTOR6D": "6d", "VECTOR6INT32": "6i", "VECTOR6UINT32": "6I",
}
#: Number of scalar values of each type (vectors are flattened when packed).
TYPE_WIDTH = {"VECTOR3D": 3, "VECTOR6D": 6, "VECTOR6INT32": 6, "VECTOR6UINT32": 6}

_V6 = "VECTOR6D"
OUTPUTS: dict[str, str] = {
    "timestamp": "DOUBLE",
    **{n: _V6 for n in ("target_q", "target_qd", "target_qdd", "target_current", "target_moment", "actual_q",
                        "actual_qd", "actual_current", "actual_current_window", "joint_control_output",
                        "actual_TCP_pose", "actual_TCP_speed", "actual_TCP_force", "target_TCP_pose",
                        "target_TCP_speed", "joint_temperatures", "actual_joint_voltage", "ft_raw_wrench",
                        "payload_inertia", "actual_current_as_torque", "tcp_offset")},
    "actual_digital_input_bits": "UINT64",
    "actual_digital_output_bits": "UINT64",
    "actual_configurable_digital_input_bits": "UINT64",
    "actual_configurable_digital_output_bits": "UINT64",
    "encoder0_raw": "INT32",
    "encoder1_raw": "INT32",
    "tool_output_mode": "UINT8",
    "tool_digital_output0_mode": "UINT8",
    "tool_digital_output1_mode": "UINT8",
    "actual_execution_time": "DOUBLE",
    "robot_mode": "INT32",
    "joint_mode": "VECTOR6INT32",
    "safety_mode": "INT32",
    "safety_status": "INT32",
    "actual_tool_accelerometer": "VECTOR3D",
    "elbow_position": "VECTOR3D",
    "elbow_velocity": "VECTOR3D",
    "payload_cog": "VECTOR3D",
    **{n: "DOUBLE" for n in ("speed_scaling", "target_speed_fraction", "actual_momentum", "actual_main_voltage",
                             "actual_robot_voltage", "actual_robot_current", "standard_analog_input0",
                             "standard_analog_input1", "standard_analog_output0", "standard_analog_output1",
                             "io_current", "euromap67_24V_voltage", "euromap67_24V_current",
                             "tool_analog_input0", "tool_analog_input1", "tool_output_current",
                             "tool_temperature", "tcp_force_scalar", "payload", "joint_position_deviation_ratio",
                             "collision_detection_ratio")},
    **{n: "UINT32" for n in ("runtime_state", "robot_status_bits", "safety_status_bits", "analog_io_types",
                             "euromap67_input_bits", "euromap67_output_bits", "tool_mode",
                             "tool_analog_input_types", "output_bit_registers0_to_31",
                             "output_bit_registers32_to_63", "input_bit_registers0_to_31",
                             "input_bit_registers32_to_63", "script_control_line")},
    "tool_output_voltage": "INT32",
    "time_scale_source": "INT32",
    **{f"output_bit_register_{i}": "BOOL" for i in range(64, 128)},
    **{f"input_bit_register_{i}": "BOOL" for i in range(64, 128)},
    **{f"output_int_register_{i}": "INT32" for i in range(48)},
    **{f"output_double_register_{i}": "DOUBLE" for i in range(48)},
    **{f"input_int_register_{i}": "INT32" for i in range(48)},
    **{f"input_double_register_{i}": "DOUBLE" for i in range(48)},
}

INPUTS: dict[str, str] = {
    **{f"input_int_register_{i}": "INT32" for i in range(48)},
    **{f"input_double_register_{i}": "DOUBLE" for i in range(48)},
    **{f"input_bit_register_{i}": "BOOL" for i in range(64, 128)},
    "input_bit_registers0_to_31": "UINT32",
    "input_bit_registers32_to_63": "UINT32",
    "speed_slider_mask": "UINT32",
    "speed_slider_fraction": "DOUBLE",
    "standard_digital_output_mask": "UINT8",
    "standard_digital_output": "UINT8",
    "configurable_digital_output_mask": "UINT8",
    "configurable_digital_output": "UINT8",
    "tool_digital_output_mask": "UINT8",
    "tool_digital_output": "UINT8",
    "standard_analog_output_mask": "UINT8",
    "standard_analog_output_type": "UINT8",
    "standard_analog_output_0": "DOUBLE",
    "standard_analog_output_1": "DOUBLE",
    "external_force_torque": "VECTOR6D",
    "ft_rtde_input_enable": "BOOL",
}


def record_format(types: list[str]) -> struct.Struct:
    """The big-endian struct of a recipe's fields packed back to back."""
    return struct.Struct(">" + "".join(TYPE_FORMATS[t] for t in types))


def receive_default_variables(version: tuple[int, int, int, int]) -> list[str]:
    """The variables `RTDEReceiveInterface(host)` asks for by default from a controller of `version`.

    ur_rtde 1.6.5 `rtde_receive_interface.cpp` (reference ur-rtde.md §3.1); used by the benchmark and
    the tests to exercise the real default recipe.
    """
    major, minor, bugfix = version[0], version[1], version[2]
    names = ["timestamp", "target_q", "target_qd", "target_qdd", "target_current", "target_moment", "actual_q",
             "actual_qd", "actual_current", "joint_control_output", "actual_TCP_pose", "actual_TCP_speed",
             "actual_TCP_force", "target_TCP_pose", "target_TCP_speed", "actual_digital_input_bits",
             "joint_temperatures", "actual_execution_time", "robot_mode", "joint_mode", "safety_mode",
             "actual_tool_accelerometer", "speed_scaling", "target_speed_fraction", "actual_momentum",
             "actual_main_voltage", "actual_robot_voltage", "actual_robot_current", "actual_joint_voltage",
             "actual_digital_output_bits", "runtime_state", "standard_analog_input0", "standard_analog_input1",
             "standard_analog_output0", "standard_analog_output1", "robot_status_bits", "safety_status_bits"]
    if (major, minor) >= (5, 23):
        names.append("actual_current_as_torque")
    if (major, minor) >= (5, 9):
        names.append("ft_raw_wrench")
    if (major == 3 and minor >= 11) or (major >= 5 and (minor, bugfix) >= (5, 1)):
        names += ["payload", "payload_cog"]
    if (major == 3 and minor >= 15) or (major >= 5 and minor >= 11):
        names.append("payload_inertia")
    if major >= 3 and minor >= 4:
        names += ["output_int_register_2"] + [f"output_int_register_{i}" for i in range(12, 20)]
        names += [f"output_double_register_{i}" for i in range(12, 20)]
    return names


# ---- framing -----------------------------------------------------------------------------------

HEADER = struct.Struct(">HB")


def frame(kind: bytes, payload: bytes = b"") -> bytes:
    """One RTDE package: uint16 size (header included) + uint8 type + payload."""
    return HEADER.pack(3 + len(payload), kind[0]) + payload


class FrameReader:
    """Splits an RTDE byte stream into (type, payload) packages (one recv may hold several)."""

    def __init__(self):
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[tuple[int, bytes]]:
        self._buf += data
        out = []
        while len(self._buf) >= 3:
            size, kind = HEADER.unpack_from(self._buf)
            if size < 3:
                raise ValueError(f"RTDE package with impossible size {size}")
            if len(self._buf) < size:
                break
            out.append((kind, bytes(self._buf[3:size])))
            del self._buf[:size]
        return out

    def pending(self) -> int:
        """Bytes of a package not yet complete."""
        return len(self._buf)
