"""What goes on the wire: ur_rtde's argument ranges, the blend rule, movePath chunks and the rounding
of ur_rtde's path printing, and the pose distances the sender measures with.

Path numbers pass through ur_rtde's script injection printed with 6 significant digits
(`printed`); `chunk_entries` measures that rounding and shrinks blend radii so that blends cannot
overlap after it. Waypoints are `robot.toolpath.Waypoint` records (or PATH.json waypoint objects).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from robot.rtde_limits import MAX_BLEND, MAX_JOINT_ACCEL, MAX_JOINT_SPEED, MAX_TOOL_ACCEL, MAX_TOOL_SPEED

__all__ = ["SendError", "MAX_JOINT_SPEED", "MAX_JOINT_ACCEL", "MAX_TOOL_SPEED", "MAX_TOOL_ACCEL", "MAX_BLEND",
           "validate_waypoints", "printed", "chunk_entries", "pose_distance", "point_segment_distance",
           "point_segment_distance_nd"]



class SendError(Exception):
    """The toolpath cannot be sent as given (no matching check, a limit broken, bad motion
    arguments, the arm not where the send would start). Nothing was sent."""


def validate_waypoints(waypoints) -> None:
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


def chunk_entries(waypoints, start: int, stop: int) -> tuple[list, float, float, float]:
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
