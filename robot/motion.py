"""Motion parameters for a waypoint list: speeds, blend radii, cycle time, joint-speed estimates.

Units: movel speeds in m/s and accelerations in m/s^2 (TCP); movej speeds in rad/s and rad/s^2
(joints); blend radii in metres (TCP); times in seconds.

Timing model (an estimate, not the controller's planner): a *run* is a stretch of moves of one
kind between two stops (a waypoint with r = 0 is a stop). Each run follows a trapezoidal profile:
it accelerates at `a` to the segment speeds, cruises, and decelerates to the stop; blended corners
inside a run are taken at speed. A run too short to reach its speed follows a triangle profile.
A movel segment's duration also respects rotation: UR interpolates orientation alongside
position, so a segment whose rotation dominates is timed with the same numbers read as rad/s.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

__all__ = ["MotionParams", "limited_params", "trapezoid_time", "blend_radii", "blend_overlaps",
           "segment_times", "joint_speed_estimates", "CycleTime", "cycle_time"]


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


def segment_times(moves, positions, rotations, joints, v, a, r) -> np.ndarray:
    """Duration [s] of each segment i -> i+1 (`n - 1` values) under the module's timing model.

    moves (n,) "movej"|"movel" (the move *to* each waypoint); positions (n, 3) TCP [m];
    rotations (n, 3, 3) TCP orientation; joints (n, 6) [rad]; v, a, r (n,) per waypoint (the
    parameters of the move to it).
    """
    n = len(moves)
    if n < 2:
        return np.zeros(0)
    P = np.asarray(positions, dtype=np.float64)
    R = np.asarray(rotations, dtype=np.float64)
    Q = np.asarray(joints, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    a = np.asarray(a, dtype=np.float64)
    r = np.asarray(r, dtype=np.float64)
    lin = np.linalg.norm(np.diff(P, axis=0), axis=1)
    cosang = np.clip((np.einsum("nij,nij->n", R[:-1], R[1:]) - 1.0) / 2.0, -1.0, 1.0)
    ang = np.arccos(cosang)
    joint = np.max(np.abs(np.diff(Q, axis=0)), axis=1)
    # distance each segment covers in its own units (movel: m, or rad if rotation dominates; movej: rad)
    dist = np.where(np.asarray(moves[1:]) == "movel", np.maximum(lin, ang), joint)
    vs, as_ = v[1:], a[1:]
    t = np.zeros(n - 1)
    # runs: consecutive segments of one kind with no stop in between
    start = 0
    while start < n - 1:
        end = start
        while (end + 1 < n - 1 and r[end + 1] > 0 and moves[end + 2] == moves[end + 1]):
            end += 1
        seg = slice(start, end + 1)
        d, vv, aa = dist[seg], vs[seg], as_[seg]
        total = d.sum()
        cruise = d / vv
        if total >= vv[0] ** 2 / (2 * aa[0]) + vv[-1] ** 2 / (2 * aa[-1]):
            extra = np.zeros_like(d)
            extra[0] += vv[0] / (2 * aa[0])
            extra[-1] += vv[-1] / (2 * aa[-1])
            t[seg] = cruise + extra
        else:  # triangle profile over the whole run, shared in proportion to distance
            tt = 2.0 * np.sqrt(total / aa.min()) if total > 0 else 0.0
            t[seg] = tt * (d / total) if total > 0 else 0.0
        start = end + 1
    return t


def joint_speed_estimates(joints: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Mean joint speeds |dq| / dt [rad/s] per segment, `(n - 1, 6)` (0 for zero-time segments)."""
    dq = np.abs(np.diff(np.asarray(joints, dtype=np.float64), axis=0))
    t = np.asarray(times, dtype=np.float64)[:, None]
    return np.divide(dq, t, out=np.zeros_like(dq), where=t > 0)


@dataclass(frozen=True)
class CycleTime:
    """Cycle-time estimate: `total` [s] = motion + dwell; `segments` (n-1,) motion time per segment."""

    total: float
    motion: float
    dwell: float
    segments: np.ndarray


def cycle_time(moves, positions, rotations, joints, v, a, r, dwell) -> CycleTime:
    """Cycle-time estimate of a waypoint list (`segment_times`) plus per-waypoint dwell [s]."""
    seg = segment_times(moves, positions, rotations, joints, v, a, r)
    dwell_total = float(np.sum(dwell))
    return CycleTime(total=float(seg.sum()) + dwell_total, motion=float(seg.sum()), dwell=dwell_total, segments=seg)
