"""The configurations a check visits: a program as arrays and its interpolated motion.

Every waypoint and the motion between waypoints is visited at interpolated configurations no
further apart than `CheckSettings.step_joint_rad` of joint motion, `step_tcp_m` of TCP travel and
`step_rot_rad` of tool rotation, with the fold state interpolated alongside.

Motion model (how a UR controller executes the program): `movel` runs the TCP on the straight line
between the two poses with the orientation slerped, the joints following by inverse kinematics
continuously from where the arm is; `movej` interpolates joints linearly with the leading joint at
`v` rad/s. Times between configurations are at the cruise speed `v` (a linear move whose rotation
dominates reads `v` as rad/s, as `robot.motion` times it). Blends are not modelled here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from robot import kinematics as kin
from sim.arm import JOINT_NAMES
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
    `move_v` (M,) the planned speed of the move that leads here; `events` problems (`Event`) found
    while interpolating (unreachable moves).
    """

    q: np.ndarray
    waypoint: np.ndarray
    at_waypoint: np.ndarray
    state: np.ndarray
    dt: np.ndarray
    move_v: np.ndarray
    events: tuple = ()




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
                U = prev + kin.wrap_angle(S - prev)
                cost = np.max(np.abs(U - prev), axis=1)
                i = int(np.argmin(cost))
                best, best_cost = U[i], cost[i]
            # the raw solver drops the wanted branch at axis-aligned poses (reference section 2.3):
            # ask the wrapped solver whenever the raw answer is missing or far from the last joints
            if best is None or best_cost > 0.2 or len(S) < 8:
                S = kin.ik(model, T)
                if len(S) == 0:
                    return out[:k], k
                U = prev + kin.wrap_angle(S - prev)
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
        return Dense(np.zeros((0, 6)), empty.astype(np.int64), empty.astype(bool), empty, empty, empty, tuple(events))
    return Dense(q=np.vstack(qs), waypoint=np.concatenate(wps).astype(np.int64), at_waypoint=np.concatenate(atw),
                 state=np.concatenate(st).astype(float), dt=np.concatenate(dts).astype(float),
                 move_v=np.concatenate(vs).astype(float), events=tuple(events))
