"""ur_rtde's client-side argument bounds (reference ur-rtde.md §2.6): the one home of the numbers a
cell may not exceed (`robot.cell`) and the sender checks every waypoint against (`robot.path_chunks`).
ur_rtde refuses a call outside them before anything reaches the controller."""
from __future__ import annotations

__all__ = ["MAX_JOINT_SPEED", "MAX_JOINT_ACCEL", "MAX_TOOL_SPEED", "MAX_TOOL_ACCEL", "MAX_BLEND"]

MAX_JOINT_SPEED = 3.14   # rad/s (moveJ / movePath joint moves)
MAX_JOINT_ACCEL = 40.0   # rad/s^2
MAX_TOOL_SPEED = 3.0     # m/s (moveL / movePath linear moves)
MAX_TOOL_ACCEL = 150.0   # m/s^2
MAX_BLEND = 2.0          # m
