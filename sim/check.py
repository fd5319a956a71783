"""Check a robot program in the MuJoCo cell model before it may be sent.

Every waypoint and the motion between waypoints is checked, at interpolated configurations no
further apart than `CheckSettings.step_joint_rad` of joint motion, `step_tcp_m` of TCP travel and
`step_rot_rad` of tool rotation, with the panel posed at the fold state interpolated alongside:

- `unreachable`: a waypoint's stored joints do not reproduce its pose, a linear move leaves the
  workspace, or a linear move arrives in other joints than the stored ones;
- `joint_limit`: a joint outside the arm's range (+-2 pi, elbow +-pi);
- `singular`: a closed-form singularity factor (`robot.kinematics.singularity_factors`) below
  its threshold (wrist |sin q5|, elbow |sin q3|, shoulder reach in metres);
- `collision`: arm/tool geoms that touch each other or touch obstacles or the panel (named pair,
  depth); the tool against its grip face is expected and excluded in the model;
- `clearance`: arm/tool closer to an obstacle or the panel than the cell's clearance (with the
  distance);
- `speed`: a joint faster than the robot's / cell's joint speed limit at the planned TCP speed,
  or a move asking for more TCP speed or acceleration than the cell allows.

Motion model (how a UR controller executes the program): `movel` runs the TCP on the straight line
between the two poses with the orientation slerped, the joints following by inverse kinematics
continuously from where the arm is; `movej` interpolates joints linearly with the leading joint at
`v` rad/s. Joint speeds are joint change over time at the cruise speed `v` (the fastest part of a
trapezoidal profile; a linear move whose rotation dominates reads `v` as rad/s, as
`robot.motion` times it). Blends (`r`) are not modelled: the check follows the corners exactly,
which a blended path cuts by at most `r` (the report notes it).

Problems found at interpolated configurations belong to the move's target waypoint (the move
instruction that causes them); problems at a waypoint's own configuration belong to it. Runs of the
same problem (same kind and same joint/pair/factor) over consecutive waypoints are reported once,
with the first and last waypoint and the worst value; a pair that breaks the clearance and then
collides is reported once, as the collision.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from robot import kinematics as kin
from sim.arm import JOINT_NAMES, part_name
from sim.model import GROUP_ARM, GROUP_ENV, GROUP_PANEL, GROUP_TOOL, build_cell_model
from sim.panel import PanelModel

__all__ = ["CheckSettings", "Problem", "CheckReport", "Program", "Dense", "interpolate_program",
           "check_program", "check_toolpath", "KINDS"]

KINDS = ("unreachable", "joint_limit", "singular", "collision", "speed", "clearance")
_DEG = 180.0 / math.pi


@dataclass(frozen=True)
class CheckSettings:
    """Step sizes of the interpolation and the singularity thresholds (all in SI units).

    `max_steps_per_move`: cap on the steps of one move; `max_refine`: how much finer a linear move
    whose joints outrun its TCP steps is re-interpolated (once).
    `wrist`/`elbow`: thresholds on |sin q5| and |sin q3| (0.05 ~ 2.9 deg from the singularity);
    `shoulder_m`: threshold on the wrist centre's distance from the base axis. `pose_tol_*`: how
    closely a waypoint's stored joints must reproduce its pose; `end_tol_rad`: how closely a linear
    move must arrive at the stored joints.
    """

    step_joint_rad: float = math.radians(1.0)
    step_tcp_m: float = 0.005
    step_rot_rad: float = math.radians(1.0)
    max_steps_per_move: int = 2000
    max_refine: int = 16
    wrist: float = kin.SINGULARITY_LIMITS.wrist  # one source with the planner (robot.kinematics)
    elbow: float = kin.SINGULARITY_LIMITS.elbow
    shoulder_m: float = kin.SINGULARITY_LIMITS.shoulder_m
    pose_tol_m: float = 1e-6
    pose_tol_rad: float = 1e-6
    end_tol_rad: float = 1e-4


@dataclass(frozen=True)
class Problem:
    """One problem: first `waypoint` (index), `kind` (one of KINDS), human `detail`; `last_waypoint`
    of the run, `subject` (joint, geom pair or factor), `value` the worst value (SI units);
    `config` the index of the first offending configuration in the checked `Dense` sequence (not
    in JSON; it may lie inside the move to `waypoint`)."""

    waypoint: int
    kind: str
    detail: str
    last_waypoint: int
    subject: str = ""
    value: float | None = None
    pair: tuple[str, str] | None = None
    config: int | None = field(default=None, compare=False)

    def to_json(self) -> dict:
        out = {"waypoint": int(self.waypoint), "kind": self.kind, "detail": self.detail,
               "last_waypoint": int(self.last_waypoint), "subject": self.subject,
               "value": None if self.value is None or not math.isfinite(self.value) else float(self.value)}
        if self.pair is not None:
            out["pair"] = list(self.pair)
        return out


@dataclass(frozen=True)
class CheckReport:
    """Result of a check (CHECK.json, format `fabkit.check/1`). `ok` iff there are no problems."""

    toolpath_sha256: str
    ok: bool
    problems: tuple[Problem, ...]
    min_clearance_m: float | None
    cycle_time_s: float
    waypoints: int
    configs_checked: int
    min_clearance_pair: tuple[str, str] | None = None
    clearance_limit_m: float = 0.0
    clearance_window_m: float = 0.0
    panel_window_m: float = 0.0
    cell: str = ""
    robot: str = ""
    panel_faces: int = 0
    notes: tuple[str, ...] = ()
    along_path: dict = field(default_factory=dict)  # per-waypoint clearance and joint-speed ratio

    def to_json(self) -> dict:
        return {
            "format": "fabkit.check/1",
            "toolpath_sha256": self.toolpath_sha256,
            "ok": bool(self.ok),
            "problems": [p.to_json() for p in self.problems],
            "min_clearance_m": self.min_clearance_m,
            "cycle_time_s": float(self.cycle_time_s),
            "min_clearance_pair": list(self.min_clearance_pair) if self.min_clearance_pair else None,
            "clearance_limit_m": self.clearance_limit_m,
            "clearance_window_m": self.clearance_window_m,
            "panel_window_m": self.panel_window_m,
            "waypoints": self.waypoints,
            "configs_checked": self.configs_checked,
            "cell": self.cell,
            "robot": self.robot,
            "panel_faces": self.panel_faces,
            "notes": list(self.notes),
            "along_path": self.along_path,
        }


@dataclass(frozen=True, eq=False)
class Program:
    """A toolpath as arrays: TCP `poses` (N, 4, 4) in the robot base frame, stored joints `q` (N, 6)
    (NaN rows = none stored), `moves` (N,) "movel"/"movej", speeds `v` (N,) (m/s or rad/s),
    accelerations `a` (N,), fold `states` (N,) float, `ops` (N,) str, `tcp` 4x4 in the flange frame,
    blend radii `r` (N,) m and `dwell` (N,) s after each waypoint where known."""

    poses: np.ndarray
    q: np.ndarray
    moves: tuple[str, ...]
    v: np.ndarray
    a: np.ndarray
    states: np.ndarray
    tcp: np.ndarray
    ops: tuple[str, ...] = ()
    sha256: str = ""
    r: np.ndarray | None = None
    dwell: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.q)


@dataclass(frozen=True, eq=False)
class Dense:
    """The configurations the check visits, in program order.

    `q` (M, 6); `waypoint` (M,) the waypoint each configuration's problems belong to; `at_waypoint`
    (M,) True for a waypoint's own configuration; `state` (M,) fractional fold state; `dt` (M,)
    time from the previous configuration at cruise speed (NaN where no motion leads here);
    `move_v` (M,) the planned speed of the move that leads here; `events` problems found while
    interpolating (unreachable moves).
    """

    q: np.ndarray
    waypoint: np.ndarray
    at_waypoint: np.ndarray
    state: np.ndarray
    dt: np.ndarray
    move_v: np.ndarray
    events: list = field(default_factory=list)


# ---- interpolation -----------------------------------------------------------------------------

def _wrap(x):
    return (x + np.pi) % (2 * np.pi) - np.pi


def _track_ik(model, flanges: np.ndarray, q_start: np.ndarray):
    """Joints along flange poses (k, 4, 4), each the IK solution nearest the previous joints.

    The arm moves continuously, so the nearest solution is unwrapped next to the previous joints
    (never clamped into the joint range: a controller running past a limit is a joint-limit problem
    to report). Returns (q (k', 6), index of the first unreachable pose or None).
    """
    out = np.empty((len(flanges), 6))
    prev = np.asarray(q_start, dtype=np.float64)
    with kin.quiet_stdout():
        for k, T in enumerate(flanges):
            S = kin.ik_raw(model, T)
            best = None
            if len(S):
                U = prev + _wrap(S - prev)
                cost = np.max(np.abs(U - prev), axis=1)
                i = int(np.argmin(cost))
                best, best_cost = U[i], cost[i]
            # the raw solver drops the wanted branch at axis-aligned poses (reference section 2.3):
            # ask the wrapped solver whenever the raw answer is missing or far from the last joints
            if best is None or best_cost > 0.2 or len(S) < 8:
                S = kin.ik(model, T)
                if len(S) == 0:
                    return out[:k], k
                U = prev + _wrap(S - prev)
                cost = np.max(np.abs(U - prev), axis=1)
                best = U[int(np.argmin(cost))]
            out[k] = best
            prev = best
    return out, None


@dataclass(frozen=True, eq=False)
class _Moves:
    """Per-move quantities (move i runs from waypoint i to i+1), all (N-1,)."""

    ok: np.ndarray        # both ends have joints
    linear: np.ndarray    # movel (else movej)
    steps: np.ndarray     # interpolation steps
    dt: np.ndarray        # time per step at cruise speed (s)
    rotvec: np.ndarray    # (N-1, 3) relative TCP rotation (base frame of the start pose)


def _moves(model, prog: Program, settings: CheckSettings) -> _Moves:
    """Step counts and step times of every move, vectorised over the program."""
    N = len(prog)
    Q = prog.q
    ok = np.all(np.isfinite(Q[:-1]), axis=1) & np.all(np.isfinite(Q[1:]), axis=1)
    linear = np.array([m == "movel" for m in prog.moves[1:]], dtype=bool)
    dq = np.where(ok, np.max(np.abs(np.nan_to_num(Q[1:] - Q[:-1])), axis=1), 0.0)
    P0, P1 = prog.poses[:-1], prog.poses[1:]
    length = np.linalg.norm(P1[:, :3, 3] - P0[:, :3, 3], axis=1)
    rotvec = Rotation.from_matrix(np.swapaxes(P0[:, :3, :3], 1, 2) @ P1[:, :3, :3]).as_rotvec() if N > 1 \
        else np.zeros((0, 3))
    angle = np.linalg.norm(rotvec, axis=1)
    n = np.maximum(np.ceil(dq / settings.step_joint_rad), 1)
    n = np.where(linear, np.maximum.reduce([n, np.ceil(length / settings.step_tcp_m),
                                            np.ceil(angle / settings.step_rot_rad)]), n)
    # joint moves curve the TCP: bound their TCP travel per step by sampling them at n steps
    for i in np.flatnonzero(ok & ~linear):
        k = int(min(n[i], settings.max_steps_per_move))
        qs = Q[i] + (np.arange(k + 1) / k)[:, None] * (Q[i + 1] - Q[i])
        T = kin.fk_tcp(model, qs, prog.tcp)
        travel = float(np.max(np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1)))
        n[i] = max(n[i], math.ceil(k * travel / settings.step_tcp_m))
    n = np.minimum(n, settings.max_steps_per_move).astype(np.int64)
    v = np.asarray(prog.v[1:], dtype=np.float64)
    # a linear move whose rotation dominates is timed with v read as rad/s (as robot.motion does)
    travel = np.where(linear, np.maximum(length, angle), dq)
    with np.errstate(divide="ignore", invalid="ignore"):
        dt = np.where(v > 0, travel / n / v, np.inf)
    return _Moves(ok=ok, linear=linear, steps=n, dt=dt, rotvec=rotvec)


def _linear_interior(model, prog: Program, i: int, n: int, rotvec: np.ndarray):
    """Joints at t = 1/n .. 1 along the linear move i -> i+1 by continuous IK from waypoint i.

    Returns (q (k, 6), t of the first pose without a solution or None).
    """
    P0, P1 = prog.poses[i], prog.poses[i + 1]
    t = np.arange(1, n + 1) / n
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = P0[:3, :3] @ Rotation.from_rotvec(t[:, None] * rotvec).as_matrix()
    T[:, :3, 3] = P0[:3, 3] + t[:, None] * (P1[:3, 3] - P0[:3, 3])
    q, bad = _track_ik(model, T @ np.linalg.inv(prog.tcp), prog.q[i])
    return q, (None if bad is None else float(t[bad]))


def interpolate_program(model, prog: Program, settings: CheckSettings = CheckSettings()) -> Dense:
    """All configurations to check: waypoints and the interpolated motion between them.

    A linear move of one step whose joints change by at most one joint step needs no inverse
    kinematics: two IK solutions that close are the same branch unless the arm is singular there,
    which the singularity check reports.
    """
    model = kin.get_model(model)
    N = len(prog)
    valid = np.all(np.isfinite(prog.q), axis=1)
    mv = _moves(model, prog, settings) if N > 1 else None
    interior: dict[int, np.ndarray] = {}
    arrived = np.ones(max(N - 1, 0), dtype=bool)  # move i reached waypoint i+1 (for its speed)
    events = []
    for i in (np.flatnonzero(mv.ok & (mv.steps >= 2)) if mv is not None else ()):
        n = int(mv.steps[i])
        if not mv.linear[i]:
            interior[i] = prog.q[i] + (np.arange(1, n) / n)[:, None] * (prog.q[i + 1] - prog.q[i])
            continue
        q, bad = _linear_interior(model, prog, i, n, mv.rotvec[i])
        if bad is None:
            path = np.vstack([prog.q[i][None], q])
            worst = float(np.max(np.abs(np.diff(path, axis=0))))
            if worst > 1.5 * settings.step_joint_rad and n < settings.max_steps_per_move:
                # the joints move faster than the TCP here (near a singularity): refine once, by a
                # bounded factor (a branch flip jumps however finely the line is divided)
                factor = min(math.ceil(worst / settings.step_joint_rad), settings.max_refine)
                n = int(min(n * factor, settings.max_steps_per_move))
                mv.dt[i] *= mv.steps[i] / n
                mv.steps[i] = n
                q, bad = _linear_interior(model, prog, i, n, mv.rotvec[i])
        if bad is not None:
            arrived[i] = False
            interior[i] = q
            events.append((int(i) + 1, "unreachable", "workspace", math.nan,
                           f"the linear move from waypoint {i} leaves the workspace at {100 * bad:.0f}% of the way "
                           f"(no inverse kinematics solution)"))
            continue
        interior[i] = q[:-1]
        diff = np.abs(q[-1] - prog.q[i + 1])
        if float(diff.max()) > settings.end_tol_rad:
            arrived[i] = False  # the jump onto the stored joints is this problem, not a speed one
            j = int(np.argmax(diff))
            events.append((int(i) + 1, "unreachable", "arrival", float(diff.max()),
                           f"the linear move from waypoint {i} arrives with other joints than stored "
                           f"({JOINT_NAMES[j]} off by {diff[j] * _DEG:.1f}°, {kin.branch_label(model, q[-1])} "
                           f"instead of {kin.branch_label(model, prog.q[i + 1])})"))

    qs, wps, atw, st, dts, vs = [], [], [], [], [], []
    for i in range(N):
        if valid[i]:
            lead = i > 0 and mv.ok[i - 1] and arrived[i - 1]
            qs.append(prog.q[i][None])
            wps.append(np.array([i]))
            atw.append(np.array([True]))
            st.append(np.array([prog.states[i]], dtype=float))
            dts.append(np.array([mv.dt[i - 1] if lead else math.nan]))
            vs.append(np.array([prog.v[i]], dtype=float))
        q = interior.get(i)
        if q is not None and len(q):
            m = len(q)
            t = np.arange(1, m + 1) / int(mv.steps[i])
            qs.append(q)
            wps.append(np.full(m, i + 1))
            atw.append(np.zeros(m, dtype=bool))
            st.append(prog.states[i] + t * (prog.states[i + 1] - prog.states[i]))
            dts.append(np.full(m, mv.dt[i]))
            vs.append(np.full(m, float(prog.v[i + 1])))
    if not qs:
        empty = np.zeros(0)
        return Dense(np.zeros((0, 6)), empty.astype(np.int64), empty.astype(bool), empty, empty, empty, events)
    return Dense(q=np.vstack(qs), waypoint=np.concatenate(wps).astype(np.int64), at_waypoint=np.concatenate(atw),
                 state=np.concatenate(st).astype(float), dt=np.concatenate(dts).astype(float),
                 move_v=np.concatenate(vs).astype(float), events=events)


# ---- the checks --------------------------------------------------------------------------------

def _waypoint_events(model, prog: Program, cell, settings: CheckSettings) -> list:
    """Reachability of every waypoint and the planned speeds/accelerations against the cell."""
    events = []
    valid = np.all(np.isfinite(prog.q), axis=1)
    if valid.any():
        idx = np.flatnonzero(valid)
        dp, dr = kin.pose_error(kin.fk_tcp(model, prog.q[idx], prog.tcp), prog.poses[idx])
        for i, p, r in zip(idx, dp, dr):
            if p > settings.pose_tol_m or r > settings.pose_tol_rad:
                events.append((int(i), "unreachable", "pose", float(p),
                               f"stored joints miss the pose by {p * 1e3:.3f} mm / {r * _DEG:.3f}°"))
    for i in np.flatnonzero(~valid):
        n = len(kin.ik(model, prog.poses[i] @ np.linalg.inv(prog.tcp)))
        why = "no inverse kinematics solution" if n == 0 else "no joint solution stored"
        events.append((int(i), "unreachable", "pose", math.nan, f"waypoint has {why}"))
    lim = cell.limits
    for i in range(len(prog)):
        v, a = float(prog.v[i]), float(prog.a[i])
        if prog.moves[i] == "movel":
            if v > lim.tcp_speed:
                events.append((i, "speed", "tcp_speed", v, f"TCP speed {v:.3g} m/s > cell limit {lim.tcp_speed:.3g} m/s"))
            if a > lim.tcp_accel:
                events.append((i, "speed", "tcp_accel", a,
                               f"TCP acceleration {a:.3g} m/s² > cell limit {lim.tcp_accel:.3g} m/s²"))
        elif a > lim.joint_accel:
            events.append((i, "speed", "joint_accel", a,
                           f"joint acceleration {a:.3g} rad/s² > cell limit {lim.joint_accel:.3g} rad/s²"))
    return events


def _limit_events(model, dense: Dense) -> list:
    lo, hi = np.array(model.q_min), np.array(model.q_max)
    events = []
    rows, cols = np.nonzero((dense.q < lo) | (dense.q > hi))
    for r, c in zip(rows, cols):
        q = float(dense.q[r, c])
        events.append((int(dense.waypoint[r]), "joint_limit", JOINT_NAMES[c], abs(q),
                       f"{JOINT_NAMES[c]} at {q * _DEG:.1f}° outside [{lo[c] * _DEG:.0f}°, {hi[c] * _DEG:.0f}°]",
                       None, int(r)))
    return events


def _singular_events(model, dense: Dense, settings: CheckSettings) -> list:
    f = kin.singularity_factors(model, dense.q)
    events = []
    for name, vals, eps, unit in (("wrist", f.wrist, settings.wrist, "|sin q5|"),
                                  ("elbow", f.elbow, settings.elbow, "|sin q3|"),
                                  ("shoulder", f.shoulder, settings.shoulder_m, "wrist centre to base axis")):
        for r in np.flatnonzero(np.abs(vals) < eps):
            v = abs(float(vals[r]))
            text = (f"{name} singularity: {unit} = {v * 1e3:.1f} mm < {eps * 1e3:.0f} mm" if name == "shoulder"
                    else f"{name} singularity: {unit} = {v:.3f} < {eps:.3f} "
                         f"(q{5 if name == 'wrist' else 3} = {dense.q[r, 4 if name == 'wrist' else 2] * _DEG:.1f}°)")
            events.append((int(dense.waypoint[r]), "singular", name, v, text, None, int(r)))
    return events


def _joint_speeds(model, cell, dense: Dense):
    """`(speed (M-1, 6) rad/s, limit (6,), dq, dt)` between consecutive configurations at cruise speed."""
    limit = np.minimum(np.array(cell.limits.joint_speed), np.array(model.joint_speed_max))
    dq = np.abs(np.diff(dense.q, axis=0))
    dt = dense.dt[1:]
    moving = np.isfinite(dt)
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(moving[:, None], dq / np.where(dt > 0, dt, np.nan)[:, None], 0.0)
    speed = np.where(np.isnan(speed) & (dq > 0), np.inf, np.nan_to_num(speed))
    return speed, limit, dq, dt


def _speed_events(model, cell, dense: Dense) -> list:
    """Joint speeds between consecutive configurations against min(cell, robot) joint speed limits."""
    if len(dense.q) < 2:
        return []
    speed, limit, dq, dt = _joint_speeds(model, cell, dense)
    events = []
    rows, cols = np.nonzero(speed > limit)
    for r, c in zip(rows, cols):
        s = float(speed[r, c])
        v = float(dense.move_v[r + 1])
        if s > 10 * limit[c] and dq[r, c] > 0.1:  # not a speed but a jump: say how far in how long
            text = (f"{JOINT_NAMES[c]} jumps {dq[r, c] * _DEG:.1f}° in {dt[r] * 1e3:.2g} ms "
                    f"(a configuration flip; limit {limit[c] * _DEG:.0f}°/s, move planned at v = {v:.3g})")
        else:
            text = f"{JOINT_NAMES[c]} at {s * _DEG:.0f}°/s > {limit[c] * _DEG:.0f}°/s limit (move planned at v = {v:.3g})"
        events.append((int(dense.waypoint[r + 1]), "speed", JOINT_NAMES[c], s / limit[c], text, None, int(r + 1)))
    return events


def _collision_events(cell, panel: PanelModel | None, dense: Dense, built=None, on_progress=None):
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
                events.append((int(dense.waypoint[j]), "collision", label, dist,
                               f"{label}, {-dist * 1e3:.1f} mm deep", pair, j))
            else:
                events.append((int(dense.waypoint[j]), "clearance", label, dist,
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
        speed, limit, _, _ = _joint_speeds(model, cell, dense)
        np.maximum.at(ratio, wp[1:], (speed / limit).max(axis=1))
    return {"waypoint": list(range(n_waypoints)),
            "clearance_m": [None if not math.isfinite(c) else float(c) for c in clearance],
            "joint_speed_ratio": [None if not math.isfinite(r) else float(r) for r in ratio]}


def _worse(kind: str, new: float, old: float) -> bool:
    """Is `new` a worse value than `old` for this kind (distances and factors: smaller is worse)?"""
    if not math.isfinite(new):
        return False
    if not math.isfinite(old):
        return True
    return new < old if kind in ("collision", "clearance", "singular") else new > old


def _merge(events: list) -> list[Problem]:
    """One problem per run of the same (kind, subject) over consecutive waypoints, worst value kept.

    An event is (waypoint, kind, subject, value, detail[, pair[, configuration index]]).
    """
    runs: dict = {}
    done = []
    for ev in sorted(events, key=lambda e: (e[1], e[2], e[0], -1 if len(e) < 7 or e[6] is None else e[6])):
        wp, kind, subject, value, detail = ev[:5]
        pair = ev[5] if len(ev) > 5 else None
        config = ev[6] if len(ev) > 6 else None
        run = runs.get((kind, subject))
        if run is not None and wp <= run["last"] + 1:
            run["last"] = max(run["last"], wp)
            if _worse(kind, value, run["value"]):
                run["value"], run["detail"] = value, detail
            continue
        if run is not None:
            done.append(run)
        runs[(kind, subject)] = {"first": wp, "last": wp, "kind": kind, "subject": subject, "value": value,
                                 "detail": detail, "pair": pair, "config": config}
    done.extend(runs.values())
    problems = []
    for r in done:
        detail = r["detail"]
        if r["last"] > r["first"]:
            detail += f" (waypoints {r['first']}–{r['last']})"
        problems.append(Problem(waypoint=r["first"], kind=r["kind"], detail=detail, last_waypoint=r["last"],
                                subject=r["subject"], value=r["value"], pair=r["pair"], config=r["config"]))
    problems = _fold_clearance_into_collisions(problems)
    problems.sort(key=lambda p: (p.waypoint, KINDS.index(p.kind), p.subject))
    return problems


def _fold_clearance_into_collisions(problems: list[Problem]) -> list[Problem]:
    """A pair that collides also comes closer than the clearance just before and after: keep one
    problem (the collision, its first penetrating waypoint) and say where the near miss began."""
    from dataclasses import replace

    hits = [p for p in problems if p.kind == "collision"]
    keep, closer = [], {}
    for p in problems:
        if p.kind == "clearance":
            c = next((h for h in hits if h.subject == p.subject and p.waypoint <= h.last_waypoint + 1
                      and p.last_waypoint >= h.waypoint - 1), None)
            if c is not None:
                closer[id(c)] = min(closer.get(id(c), p.waypoint), p.waypoint)
                continue
        keep.append(p)
    out = []
    for p in keep:
        if id(p) in closer and closer[id(p)] < p.waypoint:
            p = replace(p, detail=f"{p.detail}; inside the clearance from waypoint {closer[id(p)]}")
        out.append(p)
    return out


def cycle_time(prog: Program, dwell=None) -> float:
    """Program duration (s) by `robot.motion`'s timing model (trapezoidal runs between stops) plus
    per-waypoint dwell (s)."""
    from robot.motion import segment_times

    if len(prog) < 2 or not np.isfinite(prog.q).all():
        return math.nan
    r = prog.r if prog.r is not None else np.zeros(len(prog))
    seg = segment_times(np.asarray(prog.moves), prog.poses[:, :3, 3], prog.poses[:, :3, :3], prog.q,
                        prog.v, prog.a, r)
    return float(seg.sum()) + (0.0 if dwell is None else float(np.sum(dwell)))


def check_program(prog: Program, cell, panel: PanelModel | None = None,
                  settings: CheckSettings = CheckSettings(), on_progress=None) -> tuple[CheckReport, Dense]:
    """Check a program (arrays) in the cell; returns the report and the configurations checked.

    `on_progress(done, total)`: called now and then while the configurations go through MuJoCo.
    """
    model = cell.model
    dense = interpolate_program(model, prog, settings)
    events = list(dense.events)
    events += _waypoint_events(model, prog, cell, settings)
    events += _limit_events(model, dense)
    events += _singular_events(model, dense, settings)
    events += _speed_events(model, cell, dense)
    col, min_d, min_pair, names, nearest = _collision_events(cell, panel, dense, on_progress=on_progress)
    events += col
    problems = tuple(_merge(events))
    notes = []
    if panel is None:
        notes.append("no panel geometry: the robot was checked against the cell's obstacles only")
    if prog.r is not None and len(prog.r) and float(np.max(prog.r)) > 0:
        notes.append(f"blends are not modelled: the checked path takes the corners exactly, a blended "
                     f"path cuts them by up to r = {float(np.max(prog.r)) * 1e3:.1f} mm")
    if panel is not None and panel.fit_residual is not None and panel.fit_residual.size:
        notes.append(f"panel faces follow their fold states rigidly to {panel.fit_residual.max() * 1e3:.3f} mm")
    report = CheckReport(
        toolpath_sha256=prog.sha256, ok=not problems, problems=problems, min_clearance_m=min_d,
        cycle_time_s=cycle_time(prog, prog.dwell), waypoints=len(prog), configs_checked=len(dense.q),
        min_clearance_pair=min_pair, clearance_limit_m=float(cell.limits.clearance),
        clearance_window_m=float(names.margins["environment_m"]),
        panel_window_m=float(names.margins.get("panel_m", 0.0)), cell=cell.name, robot=model.name,
        panel_faces=0 if panel is None else len(panel.pieces), notes=tuple(notes),
        along_path=along_path(model, cell, dense, nearest, len(prog)))
    return report, dense


# ---- toolpaths (PATH.json) ---------------------------------------------------------------------

def program_from_toolpath(tp, cell) -> Program:
    """Arrays of a `robot.toolpath.Toolpath` for `cell`; `InputError` if it was planned for another
    robot model or another TCP (checking it here would check the wrong machine)."""
    from fabkit.errors import InputError
    from robot.cell import pose_to_matrix

    if tp.robot != cell.model.name:
        raise InputError(f"toolpath is for a {tp.robot}, the cell {cell.name!r} has a {cell.model.name}",
                         source=cell.source)
    tcp = pose_to_matrix(tp.tcp)
    if not np.allclose(tcp, cell.tool.tcp, atol=1e-9):
        raise InputError(f"toolpath TCP {list(np.round(tp.tcp, 6))} differs from the cell's tool TCP "
                         "(planned for another tool)", source=cell.source)
    W = tp.waypoints
    poses = np.array([pose_to_matrix(w["pose"]) for w in W])
    grip = tp.extra.get("grip", {}) if isinstance(tp.extra, dict) else {}
    if not (isinstance(grip, dict) and all(isinstance(grip.get(k, 0.0), (int, float)) and not isinstance(
            grip.get(k, 0.0), bool) and 0 <= grip.get(k, 0.0) < 60 for k in ("grip_dwell_s", "release_dwell_s"))):
        raise InputError("grip: expected an object with grip_dwell_s and release_dwell_s in seconds (0..60)")
    dwell = np.array([float(grip.get("grip_dwell_s", 0.0)) if w["op"] == "grip" else
                      float(grip.get("release_dwell_s", 0.0)) if w["op"] == "release" else 0.0 for w in W])
    states = fold_progress(np.array([w["state"] for w in W], dtype=np.float64),
                           tuple(w["op"] for w in W), poses[:, :3, 3])
    return Program(poses=poses, q=np.array([w["q"] for w in W], dtype=np.float64).reshape(-1, 6),
                   moves=tuple(w["move"] for w in W), v=np.array([w["v"] for w in W], dtype=np.float64),
                   a=np.array([w["a"] for w in W], dtype=np.float64), states=states, tcp=tcp,
                   ops=tuple(w["op"] for w in W), sha256=tp.sha256,
                   r=np.array([w["r"] for w in W], dtype=np.float64), dwell=dwell)


def fold_progress(states: np.ndarray, ops, positions: np.ndarray) -> np.ndarray:
    """Fractional fold states for the waypoints that subdivide a fold move.

    The planner labels the points it inserts between fold states s and s+1 with the state being
    left (s). The tool is on the straight line between the two states' grip poses there, so the
    panel is posed at s + (TCP travel so far / travel of the whole move) to stay with the tool.
    """
    out = np.asarray(states, dtype=np.float64).copy()
    n = len(out)
    i = 0
    while i < n:
        j = i
        while j + 1 < n and states[j + 1] == states[i] and ops[j + 1] == "fold":
            j += 1
        nxt = j + 1
        if j > i and nxt < n and ops[nxt] in ("fold", "release") and states[nxt] == states[i] + 1:
            seg = np.linalg.norm(np.diff(positions[i:nxt + 1], axis=0), axis=1)
            total = seg.sum()
            if total > 0:
                out[i + 1:nxt] = states[i] + np.cumsum(seg)[:-1] / total
        i = j + 1
    return out


def fold_file_of(tp, base_dir=None):
    """The FOLD file a toolpath's `source` names (a string value ending in .fold), resolved against
    `base_dir` (the PATH.json's folder) when relative; None if the source names none."""
    from pathlib import Path

    src = tp.source
    values = [src] if isinstance(src, str) else list(src.values()) if isinstance(src, dict) else []
    for v in values:
        if isinstance(v, str) and v.lower().endswith(".fold"):
            p = Path(v)
            if not p.is_absolute() and base_dir is not None and (Path(base_dir) / p).exists():
                return Path(base_dir) / p
            return p
    return None


def grip_face_of(tp):
    """The grip face id (polygon id) a toolpath names in `source` or its `grip` block, or None."""
    for block in (tp.source if isinstance(tp.source, dict) else {}, tp.extra.get("grip", {}) or {}):
        face = block.get("grip_face", block.get("face")) if isinstance(block, dict) else None
        if isinstance(face, int) and not isinstance(face, bool) and face >= 0:
            return face
    return None


def check_toolpath(path, cell, panel: PanelModel | None = None,
                   settings: CheckSettings = CheckSettings()) -> CheckReport:
    """Check a `robot.toolpath.Toolpath` (or a PATH.json path) in `cell` (contract entry point).

    `panel`: the panel pieces and fold states; None = no panel geometry (noted in the report).
    """
    from robot.toolpath import Toolpath

    tp = path if isinstance(path, Toolpath) else Toolpath.load(path)
    prog = program_from_toolpath(tp, cell)
    if panel is not None and len(prog) and prog.states.max() > panel.n_states - 1:
        from fabkit.errors import InputError

        raise InputError(f"waypoints use fold state {int(prog.states.max())} but the panel has "
                         f"{panel.n_states} states", source=str(path) if not isinstance(path, Toolpath) else None)
    report, _ = check_program(prog, cell, panel, settings)
    return report
