"""The configurations a check visits: a program as arrays and its interpolated motion.

Every waypoint and the motion between waypoints is visited at interpolated configurations no
further apart than `CheckSettings.step_joint_rad` of joint motion, `step_tcp_m` of TCP travel and
`step_rot_rad` of tool rotation, with the fold state interpolated alongside.

Motion model: `robot.ur_motion`, the model the planner's cycle time and the controller stand-in
use. `movel` runs the TCP on the straight line between the two poses with the orientation slerped,
the joints following by inverse kinematics continuously from where the arm is; `movej` interpolates
joints linearly. A run of blended moves is checked on the path the controller drives
(`sim.blended_runs`: Bezier blends that cut each corner, the middle of a blend standing for its
waypoint), not on the corners. `Dense.dt` is the time between configurations at the cruise speed of
their piece (`v`; a linear move whose rotation dominates reads `v` as rad/s), an upper bound on the
joint speeds; `Dense.t` the time from the program start by the controller's time law, with the
dwells after waypoints.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from robot import kinematics as kin
from robot import ur_motion
from sim.arm import JOINT_NAMES
from sim.blended_runs import sample_run, track_ik
from sim.problems import DEG, Event

__all__ = ["CheckSettings", "Program", "Dense", "interpolate_program"]


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



@dataclass(frozen=True, eq=False)
class Program:
    """A toolpath as arrays: TCP `poses` (N, 4, 4) in the robot base frame, stored joints `q` (N, 6)
    (NaN rows = none stored), `moves` (N,) "movel"/"movej", speeds `v` (N,) (m/s or rad/s),
    accelerations `a` (N,), fold `states` (N,) float, `ops` (N,) str, `tcp` 4x4 in the flange frame,
    blend radii `r` (N,) m and `dwell` (N,) s after each waypoint where known; `accel_bound` (N,)
    the joint acceleration bound (rad/s^2) of the move to each waypoint under the declared payload
    (`robot.motion.payload_accel_bounds`; None: the unloaded bound)."""

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
    accel_bound: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.q)


@dataclass(frozen=True, eq=False)
class Dense:
    """The configurations the check visits, in program order.

    `q` (M, 6); `waypoint` (M,) the waypoint each configuration's problems belong to; `at_waypoint`
    (M,) True for a waypoint's own configuration; `state` (M,) fractional fold state; `dt` (M,)
    time from the previous configuration at cruise speed (NaN where no motion leads here);
    `move_v` (M,) the planned speed of the move that leads here; `events` problems (`Event`) found
    while interpolating (unreachable moves, overlapping blends); `t` (M,) time from the program
    start by the controller's time law (NaN where the program cannot be timed).
    """

    q: np.ndarray
    waypoint: np.ndarray
    at_waypoint: np.ndarray
    state: np.ndarray
    dt: np.ndarray
    move_v: np.ndarray
    events: tuple = ()
    t: np.ndarray | None = None




@dataclass(frozen=True, eq=False)
class _Moves:
    """Per-move quantities (move i runs from waypoint i to i+1), all (N-1,)."""

    ok: np.ndarray        # both ends have joints
    linear: np.ndarray    # movel (else movej)
    steps: np.ndarray     # interpolation steps
    dt: np.ndarray        # time per step at cruise speed (s)
    rotvec: np.ndarray    # (N-1, 3) relative TCP rotation (base frame of the start pose)
    travel: np.ndarray    # path parameter length (robot.ur_motion: m or rad)


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
    return _Moves(ok=ok, linear=linear, steps=n, dt=dt, rotvec=rotvec, travel=travel)


def _linear_interior(model, prog: Program, i: int, n: int, rotvec: np.ndarray):
    """Joints at t = 1/n .. 1 along the linear move i -> i+1 by continuous IK from waypoint i.

    Returns (q (k, 6), t of the first pose without a solution or None).
    """
    P0, P1 = prog.poses[i], prog.poses[i + 1]
    t = np.arange(1, n + 1) / n
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = P0[:3, :3] @ Rotation.from_rotvec(t[:, None] * rotvec).as_matrix()
    T[:, :3, 3] = P0[:3, 3] + t[:, None] * (P1[:3, 3] - P0[:3, 3])
    q, bad = track_ik(model, T @ np.linalg.inv(prog.tcp), prog.q[i])
    return q, (None if bad is None else float(t[bad]))


def _blended_runs(model, prog: Program, mv: _Moves, settings: CheckSettings, bound: np.ndarray, events: list):
    """The blended runs of the program (`sim.blended_runs`), {first: (last, RunSamples)}; their
    overlap, workspace and arrival problems go to `events`."""
    out = {}
    r = np.zeros(len(prog)) if prog.r is None else np.asarray(prog.r, dtype=np.float64)
    valid = np.all(np.isfinite(prog.q), axis=1)
    for first, last in ur_motion.run_bounds(prog.moves, r):
        if last - first < 2 or not valid[first:last + 1].all():
            continue
        try:
            rs = sample_run(model, prog, first, last, mv.steps[first:last], settings,
                            float(bound[first + 1:last + 1].min()))
        except ur_motion.BlendOverlap as exc:
            events.append(Event(first + 1, "unreachable", "blend", math.nan,
                                f"the controller refuses the blended moves from waypoint {first} to {last}: {exc}"))
            continue
        out[first] = (last, rs)
        if rs.unreachable_at is not None:
            w, frac = rs.unreachable_at
            events.append(Event(w, "unreachable", "workspace", math.nan,
                                f"the linear move from waypoint {w - 1} leaves the workspace at {100 * frac:.0f}% of the "
                                f"way (no inverse kinematics solution)"))
            continue
        diff = np.abs(rs.end_q - prog.q[last])
        if float(diff.max()) > settings.end_tol_rad:
            j = int(np.argmax(diff))
            events.append(Event(last, "unreachable", "arrival", float(diff.max()),
                                f"the blended moves from waypoint {first} arrive with other joints than stored "
                                f"({JOINT_NAMES[j]} off by {diff[j] * DEG:.1f}°, {kin.branch_label(model, rs.end_q)} "
                                f"instead of {kin.branch_label(model, prog.q[last])})"))
    return out


def _times(prog: Program, mv: _Moves, blended: dict, bound: np.ndarray, s_wp: np.ndarray, s: np.ndarray,
           wp: np.ndarray) -> np.ndarray:
    """Times (s) of configurations at program path parameters `s` belonging to waypoints `wp`: the
    whole program as one `robot.ur_motion` profile with stops between runs, plus the dwells."""
    N = len(prog)
    lengths, vs, accs, stops = [], [], [], [True]
    i = 0
    while i < N - 1:
        if i in blended:
            last, rs = blended[i]
            g = rs.geometry
            lengths.append(g.length)
            vs.append(g.v)
            accs.append(g.a)
            stops += [False] * (len(g.length) - 1) + [True]
            i = last
            continue
        a = float(prog.a[i + 1]) if mv.linear[i] else min(float(prog.a[i + 1]), float(bound[i + 1]))
        lengths.append([mv.travel[i] if mv.ok[i] else 0.0])
        vs.append([float(prog.v[i + 1])])
        accs.append([a])
        stops.append(True)
        i += 1
    dwell = np.zeros(N) if prog.dwell is None else np.asarray(prog.dwell, dtype=np.float64)
    passed = np.r_[0.0, np.cumsum(dwell)]
    try:
        prof = ur_motion.time_law(np.concatenate(lengths), np.concatenate(vs), np.concatenate(accs), stops)
    except ValueError:
        return np.full(len(s), math.nan)
    return prof.time_at(s) + passed[wp]


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
    bound = np.full(N, ur_motion.JOINT_ACCEL_MAX) if prog.accel_bound is None else \
        np.asarray(prog.accel_bound, dtype=np.float64)
    events: list = []
    blended = _blended_runs(model, prog, mv, settings, bound, events) if N > 2 else {}
    in_run = np.zeros(max(N - 1, 0), dtype=bool)
    for first, (last, _) in blended.items():
        in_run[first:last] = True
    interior: dict[int, np.ndarray] = {}
    arrived = np.ones(max(N - 1, 0), dtype=bool)  # move i reached waypoint i+1 (for its speed)
    for first, (last, rs) in blended.items():
        arrived[last - 1] = rs.unreachable_at is None and not any(
            e.waypoint == last and e.subject == "arrival" for e in events)
    for i in (np.flatnonzero(mv.ok & (mv.steps >= 2) & ~in_run) if mv is not None else ()):
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
            events.append(Event(int(i) + 1, "unreachable", "workspace", math.nan,
                                f"the linear move from waypoint {i} leaves the workspace at {100 * bad:.0f}% of the "
                                f"way (no inverse kinematics solution)"))
            continue
        interior[i] = q[:-1]
        diff = np.abs(q[-1] - prog.q[i + 1])
        if float(diff.max()) > settings.end_tol_rad:
            arrived[i] = False  # the jump onto the stored joints is this problem, not a speed one
            j = int(np.argmax(diff))
            events.append(Event(int(i) + 1, "unreachable", "arrival", float(diff.max()),
                                f"the linear move from waypoint {i} arrives with other joints than stored "
                                f"({JOINT_NAMES[j]} off by {diff[j] * DEG:.1f}°, {kin.branch_label(model, q[-1])} "
                                f"instead of {kin.branch_label(model, prog.q[i + 1])})"))

    # path parameter of every waypoint along the whole program (robot.ur_motion's units)
    s_wp = np.zeros(N)
    i = 0
    while i < N - 1:
        if i in blended:
            last, rs = blended[i]
            s_wp[i + 1:last + 1] = s_wp[i] + rs.geometry.corner[1:]
            i = last
        else:
            s_wp[i + 1] = s_wp[i] + (mv.travel[i] if mv.ok[i] else 0.0)
            i += 1

    qs, wps, atw, st, dts, vs, ss = [], [], [], [], [], [], []
    i = 0
    while i < N:
        if valid[i]:
            lead = i > 0 and mv.ok[i - 1] and arrived[i - 1]
            dt = math.nan
            if lead:
                dt = mv.dt[i - 1] if not in_run[i - 1] else _run_end_dt(blended, i, s_wp)
            qs.append(prog.q[i][None])
            wps.append(np.array([i]))
            atw.append(np.array([True]))
            st.append(np.array([prog.states[i]], dtype=float))
            dts.append(np.array([dt]))
            vs.append(np.array([prog.v[i]], dtype=float))
            ss.append(np.array([s_wp[i]]))
        if i in blended:
            last, rs = blended[i]
            if len(rs.q):
                seg, frac = rs.state_seg, rs.state_frac
                qs.append(rs.q)
                wps.append(rs.waypoint)
                atw.append(rs.corner)
                st.append(prog.states[seg] + frac * (prog.states[seg + 1] - prog.states[seg]))
                dts.append(np.diff(np.r_[0.0, rs.s]) / rs.v)
                vs.append(np.asarray(prog.v, dtype=float)[rs.waypoint])
                ss.append(s_wp[i] + rs.s)
            i = last
            continue
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
            ss.append(s_wp[i] + t * mv.travel[i])
        i += 1
    if not qs:
        empty = np.zeros(0)
        return Dense(np.zeros((0, 6)), empty.astype(np.int64), empty.astype(bool), empty, empty, empty, tuple(events),
                     empty)
    wp = np.concatenate(wps).astype(np.int64)
    t = _times(prog, mv, blended, bound, s_wp, np.concatenate(ss), wp) if N > 1 else np.zeros(len(wp))
    return Dense(q=np.vstack(qs), waypoint=wp, at_waypoint=np.concatenate(atw),
                 state=np.concatenate(st).astype(float), dt=np.concatenate(dts).astype(float),
                 move_v=np.concatenate(vs).astype(float), events=tuple(events), t=t)


def _run_end_dt(blended: dict, last: int, s_wp: np.ndarray) -> float:
    """Time at cruise speed from a blended run's last sample to its end waypoint `last`."""
    for first, (end, rs) in blended.items():
        if end == last:
            s_end = rs.geometry.edges[-1]
            s_prev = rs.s[-1] if len(rs.s) else 0.0
            return float((s_end - s_prev) / rs.geometry.v[-1])
    return math.nan
