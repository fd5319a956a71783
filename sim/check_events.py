"""The checks over the configurations a check visits: reach, joint limits, singularities, joint
speeds, contacts (MuJoCo) and the per-waypoint series the report plots.

- `unreachable`: a waypoint's stored joints do not reproduce its pose (linear moves that leave the
  workspace or arrive on other joints are found while interpolating, `sim.interpolate`);
- `joint_limit`: a joint outside the arm's range (+-2 pi, elbow +-pi);
- `singular`: a closed-form singularity factor (`robot.kinematics.singularity_factors`) below
  its threshold (wrist |sin q5|, elbow |sin q3|, shoulder reach in metres);
- `collision`: arm/tool geoms that touch each other or touch obstacles or the panel (named pair,
  depth); the tool against its grip face is expected and excluded in the model (in a program in
  phases gripping different faces: move by move, with the face the phase holds);
- `clearance`: arm/tool closer to an obstacle or the panel than the cell's clearance;
- `speed`: a joint faster than the robot's / cell's joint speed limit at the planned TCP speed,
  or a move asking for more TCP speed or acceleration than the cell allows.

Every function returns `sim.problems.Event` records.
"""
from __future__ import annotations

import math

import sim.gl_backend  # noqa: F401  (MUJOCO_GL before mujoco loads)
import mujoco
import numpy as np

from robot import kinematics as kin
from sim.arm import JOINT_NAMES, part_name
from sim.interpolate import CheckSettings, Dense, Program
from sim.model import GROUP_ARM, GROUP_ENV, GROUP_PANEL, GROUP_TOOL, build_cell_model
from sim.panel import PanelModel
from sim.problems import DEG, Event

__all__ = ["waypoint_events", "limit_events", "singular_events", "joint_speeds", "speed_events", "collision_events",
           "along_path"]


def waypoint_events(model, prog: Program, cell, settings: CheckSettings) -> list:
    """Reachability of every waypoint and the planned speeds/accelerations against the cell."""
    events = []
    valid = np.all(np.isfinite(prog.q), axis=1)
    if valid.any():
        idx = np.flatnonzero(valid)
        dp, dr = kin.pose_error(kin.fk_tcp(model, prog.q[idx], prog.tcp), prog.poses[idx])
        for i, p, r in zip(idx, dp, dr):
            if p > settings.pose_tol_m or r > settings.pose_tol_rad:
                events.append(Event(int(i), "unreachable", "pose", float(p),
                               f"stored joints miss the pose by {p * 1e3:.3f} mm / {r * DEG:.3f}°"))
    for i in np.flatnonzero(~valid):
        n = len(kin.ik(model, prog.poses[i] @ np.linalg.inv(prog.tcp)))
        why = "no inverse kinematics solution" if n == 0 else "no joint solution stored"
        events.append(Event(int(i), "unreachable", "pose", math.nan, f"waypoint has {why}"))
    lim = cell.limits
    for i in range(len(prog)):
        v, a = float(prog.v[i]), float(prog.a[i])
        if prog.moves[i] == "movel":
            if v > lim.tcp_speed:
                events.append(Event(i, "speed", "tcp_speed", v, f"TCP speed {v:.3g} m/s > cell limit {lim.tcp_speed:.3g} m/s"))
            if a > lim.tcp_accel:
                events.append(Event(i, "speed", "tcp_accel", a,
                               f"TCP acceleration {a:.3g} m/s² > cell limit {lim.tcp_accel:.3g} m/s²"))
        elif a > lim.joint_accel:
            events.append(Event(i, "speed", "joint_accel", a,
                           f"joint acceleration {a:.3g} rad/s² > cell limit {lim.joint_accel:.3g} rad/s²"))
    return events


def limit_events(model, dense: Dense) -> list:
    lo, hi = np.array(model.q_min), np.array(model.q_max)
    events = []
    rows, cols = np.nonzero((dense.q < lo) | (dense.q > hi))
    for r, c in zip(rows, cols):
        q = float(dense.q[r, c])
        events.append(Event(int(dense.waypoint[r]), "joint_limit", JOINT_NAMES[c], abs(q),
                       f"{JOINT_NAMES[c]} at {q * DEG:.1f}° outside [{lo[c] * DEG:.0f}°, {hi[c] * DEG:.0f}°]",
                       None, int(r)))
    return events


def singular_events(model, dense: Dense, settings: CheckSettings) -> list:
    f = kin.singularity_factors(model, dense.q)
    events = []
    for name, vals, eps, unit in (("wrist", f.wrist, settings.wrist, "|sin q5|"),
                                  ("elbow", f.elbow, settings.elbow, "|sin q3|"),
                                  ("shoulder", f.shoulder, settings.shoulder_m, "wrist centre to base axis")):
        for r in np.flatnonzero(np.abs(vals) < eps):
            v = abs(float(vals[r]))
            text = (f"{name} singularity: {unit} = {v * 1e3:.1f} mm < {eps * 1e3:.0f} mm" if name == "shoulder"
                    else f"{name} singularity: {unit} = {v:.3f} < {eps:.3f} "
                         f"(q{5 if name == 'wrist' else 3} = {dense.q[r, 4 if name == 'wrist' else 2] * DEG:.1f}°)")
            events.append(Event(int(dense.waypoint[r]), "singular", name, v, text, None, int(r)))
    return events


def joint_speeds(model, cell, dense: Dense):
    """`(speed (M-1, 6) rad/s, limit (6,), dq, dt)` between consecutive configurations at cruise speed."""
    limit = np.minimum(np.array(cell.limits.joint_speed), np.array(model.joint_speed_max))
    dq = np.abs(np.diff(dense.q, axis=0))
    dt = dense.dt[1:]
    moving = np.isfinite(dt)
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(moving[:, None], dq / np.where(dt > 0, dt, np.nan)[:, None], 0.0)
    speed = np.where(np.isnan(speed) & (dq > 0), np.inf, np.nan_to_num(speed))
    return speed, limit, dq, dt


def speed_events(model, cell, dense: Dense) -> list:
    """Joint speeds between consecutive configurations against min(cell, robot) joint speed limits."""
    if len(dense.q) < 2:
        return []
    speed, limit, dq, dt = joint_speeds(model, cell, dense)
    events = []
    rows, cols = np.nonzero(speed > limit)
    for r, c in zip(rows, cols):
        s = float(speed[r, c])
        v = float(dense.move_v[r + 1])
        if s > 10 * limit[c] and dq[r, c] > 0.1:  # not a speed but a jump: say how far in how long
            text = (f"{JOINT_NAMES[c]} jumps {dq[r, c] * DEG:.1f}° in {dt[r] * 1e3:.2g} ms "
                    f"(a configuration flip; limit {limit[c] * DEG:.0f}°/s, move planned at v = {v:.3g})")
        else:
            text = f"{JOINT_NAMES[c]} at {s * DEG:.0f}°/s > {limit[c] * DEG:.0f}°/s limit (move planned at v = {v:.3g})"
        events.append(Event(int(dense.waypoint[r + 1]), "speed", JOINT_NAMES[c], s / limit[c], text, None, int(r + 1)))
    return events


def collision_events(cell, panel: PanelModel | None, dense: Dense, built=None, on_progress=None):
    """MuJoCo contacts at every configuration. Returns (events, min clearance, its pair, names).

    `built`: a `(MjModel, CellNames)` from `build_cell_model(cell, panel)` to reuse.
    """
    m, names = built if built is not None else build_cell_model(cell, panel)
    d = mujoco.MjData(m)
    group = names.geom_group
    robot = (group == GROUP_ARM) | (group == GROUP_TOOL)
    environment = (group == GROUP_ENV) | (group == GROUP_PANEL)
    # the flange (wrist_3) carries the tool that holds the grip face: only penetration counts there
    touch_only = np.zeros((m.ngeom, m.ngeom), dtype=bool)
    robot_pair = np.outer(robot, robot)
    touch_only |= robot_pair
    if names.grip_face is not None:
        grip = np.flatnonzero(names.geom_face == names.grip_face)
        wrist3 = [g for g in range(m.ngeom) if part_name(names.geom[g]) == "wrist_3"]
        touch_only[np.ix_(wrist3, grip)] = touch_only[np.ix_(grip, wrist3)] = True
    per_move = None if panel is None else panel.grip_by_waypoint
    if per_move is not None:   # phases gripping different faces: the held piece per move
        tool = group == GROUP_TOOL
        wrist = np.array([part_name(n) == "wrist_3" for n in names.geom])
        per_move = np.asarray(per_move, dtype=np.int64)
    clearance = float(cell.limits.clearance)
    part = [part_name(n) for n in names.geom]
    events = []
    min_d, min_pair = math.inf, None
    nearest = np.full(len(dense.q), np.inf)  # per configuration: closest obstacle/panel within the window
    qpos = d.qpos
    last_state = None
    kin_fn, col_fn = mujoco.mj_kinematics, mujoco.mj_collision
    total = len(dense.q)
    for j in range(total):
        if on_progress is not None and j % 512 == 0:
            on_progress(j, total)
        qpos[:] = dense.q[j]
        if panel is not None and dense.state[j] != last_state:
            last_state = dense.state[j]
            d.mocap_pos[:], d.mocap_quat[:] = panel.poses_at(last_state)
        kin_fn(m, d)
        col_fn(m, d)
        n = d.ncon
        if not n:
            continue
        con = d.contact
        for g1, g2, dist in zip(con.geom1[:n], con.geom2[:n], con.dist[:n]):
            if robot[g2] and not robot[g1]:
                g1, g2 = g2, g1
            dist = float(dist)
            if per_move is not None and per_move[dense.waypoint[j]] >= 0 and names.geom_face[g2] == \
                    per_move[dense.waypoint[j]] and (tool[g1] or (wrist[g1] and dist >= 0)):
                continue      # the tool on the face it holds (excluded), the flange touching it
            if touch_only[g1, g2]:
                if dist >= 0:
                    continue
            elif environment[g2]:
                if dist < nearest[j]:
                    nearest[j] = dist
                if dist < min_d:
                    min_d, min_pair = dist, (part[g1], part[g2])
                if dist >= clearance:
                    continue
            pair = (part[g1], part[g2])
            label = f"{pair[0]} × {pair[1]}"
            if dist < 0:
                events.append(Event(int(dense.waypoint[j]), "collision", label, dist,
                               f"{label}, {-dist * 1e3:.1f} mm deep", pair, j))
            else:
                events.append(Event(int(dense.waypoint[j]), "clearance", label, dist,
                               f"{label} at {dist * 1e3:.1f} mm (clearance {clearance * 1e3:.0f} mm)", pair, j))
    if on_progress is not None:
        on_progress(total, total)
    return events, (None if not math.isfinite(min_d) else min_d), min_pair, names, nearest


def along_path(model, cell, dense: Dense, nearest: np.ndarray, n_waypoints: int) -> dict:
    """Per waypoint: closest obstacle/panel distance within the measuring window [m] (None: nothing
    that close) and the fastest joint as a fraction of its speed limit, over the configurations of
    the move into it — the series the report plots."""
    wp = np.asarray(dense.waypoint, dtype=np.int64)
    clearance = np.full(n_waypoints, np.inf)
    np.minimum.at(clearance, wp, nearest)
    ratio = np.zeros(n_waypoints)
    if len(dense.q) >= 2:
        speed, limit, _, _ = joint_speeds(model, cell, dense)
        np.maximum.at(ratio, wp[1:], (speed / limit).max(axis=1))
    return {"waypoint": list(range(n_waypoints)),
            "clearance_m": [None if not math.isfinite(c) else float(c) for c in clearance],
            "joint_speed_ratio": [None if not math.isfinite(r) else float(r) for r in ratio]}
