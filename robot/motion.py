"""Motion parameters for a waypoint list: speeds, blend radii, cycle time, joint-speed estimates.

Units: movel speeds in m/s and accelerations in m/s^2 (TCP); movej speeds in rad/s and rad/s^2
(joints); blend radii in metres (TCP); times in seconds.

Timing is `robot.ur_motion`'s model of how the controller executes the program (the model the
checker and the controller stand-in use): runs between stops, blends as Bezier pieces taken at the
slower of their two segments' speeds, the time-optimal trapezoidal time law per run, and movej
accelerations capped by the joint acceleration bound of the payload declared at each move
(`payload_accel_bounds`). Times are at full speed slider (the slider f divides them by f).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from robot import ur_motion

__all__ = ["MotionParams", "limited_params", "trapezoid_time", "blend_radii", "blend_overlaps",
           "segment_times", "payload_accel_bounds", "joint_speed_estimates", "CycleTime", "cycle_time",
           "toolpath_cycle_time"]


@dataclass(frozen=True)
class MotionParams:
    """Speeds per operation and blending.

    joint_speed [rad/s] / joint_accel [rad/s^2]: movej (home, first approach);
    approach_speed / retract_speed / fold_speed [m/s], tcp_accel [m/s^2]: movel;
    blend_max [m]: largest blend radius on fold moves (also capped at half the shorter adjacent
    segment); grip_dwell / release_dwell [s]: wait after switching the gripper.
    """

    joint_speed: float = 1.05
    joint_accel: float = 1.4
    approach_speed: float = 0.1
    retract_speed: float = 0.1
    fold_speed: float = 0.05
    tcp_accel: float = 0.5
    blend_max: float = 0.005
    grip_dwell: float = 0.5
    release_dwell: float = 0.5


def limited_params(params: MotionParams, limits) -> MotionParams:
    """`params` with every speed and acceleration capped at the cell's limits (`robot.cell.Limits`)."""
    js = float(min(limits.joint_speed))
    return replace(params,
                   joint_speed=min(params.joint_speed, js),
                   joint_accel=min(params.joint_accel, limits.joint_accel),
                   approach_speed=min(params.approach_speed, limits.tcp_speed),
                   retract_speed=min(params.retract_speed, limits.tcp_speed),
                   fold_speed=min(params.fold_speed, limits.tcp_speed),
                   tcp_accel=min(params.tcp_accel, limits.tcp_accel))


def trapezoid_time(distance, v, a) -> np.ndarray:
    """Time [s] to cover `distance` from rest to rest at top speed `v` and acceleration `a`."""
    d = np.abs(np.asarray(distance, dtype=np.float64))
    v = np.asarray(v, dtype=np.float64)
    a = np.asarray(a, dtype=np.float64)
    full = d >= v * v / a
    return np.where(full, d / v + v / a, 2.0 * np.sqrt(d / a))


def blend_radii(points: np.ndarray, stops: np.ndarray, r_max: float) -> np.ndarray:
    """Blend radius per waypoint: 0 at stops (and the first and last point), else
    min(r_max, half the shorter adjacent segment) so that neighbouring blends never overlap."""
    P = np.asarray(points, dtype=np.float64)
    n = len(P)
    r = np.zeros(n)
    if n < 3:
        return r
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    inner = np.minimum(seg[:-1], seg[1:]) * 0.5
    r[1:-1] = np.minimum(r_max, inner)
    r[np.asarray(stops, dtype=bool)] = 0.0
    r[0] = r[-1] = 0.0
    return r


def blend_overlaps(points: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Indices i of segments (i -> i+1) whose end blends overlap: r_i + r_{i+1} > |p_{i+1} - p_i|."""
    P = np.asarray(points, dtype=np.float64)
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    r = np.asarray(radii, dtype=np.float64)
    return np.flatnonzero(r[:-1] + r[1:] > seg * (1 + 1e-12))


def segment_times(moves, positions, rotations, joints, v, a, r, accel_bound=np.inf) -> np.ndarray:
    """Duration [s] of each segment i -> i+1 (`n - 1` values): from passing waypoint i to passing
    waypoint i+1 (the middle of its blend) by `robot.ur_motion.segment_times`.

    moves (n,) "movej"|"movel" (the move *to* each waypoint); positions (n, 3) TCP [m];
    rotations (n, 3, 3) TCP orientation; joints (n, 6) [rad]; v, a, r (n,) per waypoint (the
    parameters of the move to it); accel_bound: joint acceleration bound [rad/s^2], scalar or (n,)
    (`payload_accel_bounds`).
    """
    return ur_motion.segment_times(np.asarray(moves), positions, rotations, joints, v, a, r, accel_bound)


def payload_accel_bounds(ops, payload: dict | None, model: str) -> np.ndarray:
    """Joint acceleration bound [rad/s^2] of the move to each waypoint under the payload the
    program declares (`robot.loads.payload_record`: the tool alone before the grip and after the
    release, tool + panel on the moves after the grip up to the release); the unloaded bound where
    no payload is declared. `robot.ur_motion.PayloadError` for a payload over the arm's rating."""
    n = len(ops)
    if not payload:
        return np.full(n, ur_motion.JOINT_ACCEL_MAX)
    from robot.loads import arm_rating

    rated = arm_rating(model).payload
    tool = ur_motion.joint_accel_bound(float(payload["tool_mass_kg"]), rated)
    held = ur_motion.joint_accel_bound(float(payload["held_mass_kg"]), rated)
    out = np.full(n, tool)
    holding = False
    for i, op in enumerate(ops):
        if holding:
            out[i] = held
        if op == "grip":
            holding = True
        elif op == "release":
            holding = False
    return out


def joint_speed_estimates(joints: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Mean joint speeds |dq| / dt [rad/s] per segment, `(n - 1, 6)` (0 for zero-time segments)."""
    dq = np.abs(np.diff(np.asarray(joints, dtype=np.float64), axis=0))
    t = np.asarray(times, dtype=np.float64)[:, None]
    return np.divide(dq, t, out=np.zeros_like(dq), where=t > 0)


@dataclass(frozen=True)
class CycleTime:
    """Cycle time: `total` [s] = motion + dwell; `segments` (n-1,) motion time per segment."""

    total: float
    motion: float
    dwell: float
    segments: np.ndarray


def cycle_time(moves, positions, rotations, joints, v, a, r, dwell, accel_bound=np.inf) -> CycleTime:
    """Cycle time of a waypoint list (`segment_times`) plus per-waypoint dwell [s]."""
    seg = segment_times(moves, positions, rotations, joints, v, a, r, accel_bound)
    dwell_total = float(np.sum(dwell))
    return CycleTime(total=float(seg.sum()) + dwell_total, motion=float(seg.sum()), dwell=dwell_total, segments=seg)


def toolpath_cycle_time(tp) -> CycleTime:
    """Cycle time of a `robot.toolpath.Toolpath` as the controller runs it at full speed slider: its
    waypoints' motion (with the payload rule when it declares a `payload`) plus the grip and release
    dwells."""
    from robot.cell import pose_to_matrix

    W = tp.waypoints
    T = np.array([pose_to_matrix(w.pose) for w in W])
    ops = [w.op for w in W]
    grip = tp.extra.get("grip", {}) or {}
    dwell = [float(grip.get("grip_dwell_s", 0.0)) if o == "grip" else
             float(grip.get("release_dwell_s", 0.0)) if o == "release" else 0.0 for o in ops]
    return cycle_time([w.move for w in W], T[:, :3, 3], T[:, :3, :3], np.array([w.q for w in W], dtype=np.float64),
                      np.array([w.v for w in W]), np.array([w.a for w in W]), np.array([w.r for w in W]), dwell,
                      payload_accel_bounds(ops, tp.extra.get("payload"), tp.robot))
