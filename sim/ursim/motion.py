"""Motion planning of the controller stand-in: UR-style movej/movel sequences with blends.

`plan_moves` turns a list of `Waypoint`s (what `movej`/`movel`/`movep` statements, ur_rtde's
register moves and its injected paths ask for) into joint samples at the controller period, by
`robot.ur_motion` (the motion model the planner's cycle time and the checker's interpolation use):
runs, blend geometry, the time law and the joint acceleration bound are all there. What is the
stand-in's own:

- movel runs go through `robot.kinematics.ik` at knots a few millimetres apart (the branch nearest
  the previous knot) and a cubic spline in joint space between knots; the knots include every
  piece end, so the arm ends exactly on the IK of each stopping waypoint;
- movej targets given as poses are solved by IK nearest the previous target;
- the joint acceleration bound (`joint_accel_max`, lowered by the declared payload): movej runs use
  at most it as `a`; a run whose executed joint accelerations (second differences of the samples)
  would still exceed it is slowed as a whole (`robot.ur_motion.stretch_factor`);
- a target out of reach, a joint jump along a movel (a singularity) or overlapping blends is a
  `PlanError` (the stand-in turns it into a runtime error before the arm moves).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robot import kinematics as K
from robot import ur_motion as U
from robot.cell import matrix_to_pose, pose_to_matrix  # noqa: F401 (re-exported for the stand-in)

#: Knot spacing of Cartesian runs for IK: metres of TCP travel and radians of tool rotation.
KNOT_STEP_M = 0.004
KNOT_STEP_RAD = 0.02
#: Largest joint jump between neighbouring IK knots before the move is declared discontinuous.
MAX_KNOT_JUMP = 0.35


class PlanError(Exception):
    """The controller cannot execute the move (the stand-in turns it into a runtime error)."""


@dataclass(frozen=True)
class Waypoint:
    """One move target. `kind` is "movej", "movel" or "movep"; give `q` (joints, rad) or `pose`
    ([x, y, z, rx, ry, rz] of the TCP in the base frame); `v`/`a` in rad/s, rad/s^2 (movej) or
    m/s, m/s^2 (movel); `r` blend radius (m); `progress` the index written to the async progress
    register when the move toward this waypoint begins (-1: none)."""

    kind: str
    v: float
    a: float
    r: float = 0.0
    q: tuple | None = None
    pose: tuple | None = None
    progress: int = -1


@dataclass
class Trajectory:
    """Joint samples `q` (n, 6) at period `dt` (sample 0 is the start), the path speed of each
    sample (`speed`, in the unit of its segment), `markers`: (sample index, progress value), and
    `stretch`: the largest factor by which a run was slowed for the joint acceleration bound."""

    q: np.ndarray
    speed: np.ndarray
    dt: float
    markers: list = field(default_factory=list)
    stretch: float = 1.0

    @property
    def duration(self) -> float:
        return (len(self.q) - 1) * self.dt


def _samples(prof: U.Profile, dt: float):
    t = np.r_[np.arange(0.0, prof.duration, dt), prof.duration]
    return prof.state_at(t)


def _peak_accel(q: np.ndarray, dt: float) -> float:
    return float(np.max(np.abs(np.diff(q, 2, axis=0)))) / dt ** 2 if len(q) > 2 else 0.0


def _timed(geom: U.RunGeometry, joints_at, dt: float, bound: float):
    """Samples (s, sdot, q) of a run at period `dt`, slowed as a whole if its joint accelerations
    exceed `bound`; and the factor it was slowed by."""
    lengths, v, a = geom.length, geom.v, geom.a
    stretch = 1.0
    for _ in range(4):
        s, sd = _samples(U.time_law(lengths, v / stretch, a / stretch ** 2), dt)
        q = joints_at(s)
        k = U.stretch_factor(_peak_accel(q, dt), bound)
        if k <= 1.0:
            break
        stretch *= k * 1.002
    else:
        raise PlanError(f"the move cannot keep its joint accelerations within {bound:.3g} rad/s^2")
    return s, sd, q, stretch


def _markers(geom: U.RunGeometry, wps, s):
    """Sample indices where the move toward each waypoint begins: where the blend before it starts
    (URScript returns from a blended move when its blend starts, so the next
    `signal_async_progress` runs there)."""
    e = geom.edges
    begins = [0.0] + [e[2 * j - 1] for j in range(1, len(wps))]
    return [(int(np.searchsorted(s, begins[i] - 1e-12)), w.progress) for i, w in enumerate(wps) if w.progress >= 0]


def _ik_near(model, T, tcp, q_ref, what: str) -> np.ndarray:
    sols = K.ik(model, T, tcp)
    if len(sols) == 0:
        raise PlanError(f"{what}: inverse kinematics found no solution (pose out of reach)")
    return K.select_nearest(sols, q_ref, model=model)


def _geometry(build, *args):
    try:
        return build(*args)
    except U.BlendOverlap as exc:
        raise PlanError(str(exc)) from None


def _plan_cart_run(model, tcp, q0, wps, dt, bound):
    T0 = K.fk_tcp(model, q0, tcp)
    targets = np.array([pose_to_matrix(w.pose) for w in wps])
    for i, T in enumerate(targets):  # a target out of reach fails before the arm moves
        if len(K.ik(model, T, tcp)) == 0:
            raise PlanError(f"movel: inverse kinematics found no solution for target {i} (pose out of reach)")
    T_all = np.concatenate([T0[None], targets])
    geom = _geometry(U.cart_run, T_all[:, :3, 3], T_all[:, :3, :3], np.r_[0.0, [w.v for w in wps]],
                     np.r_[0.0, [w.a for w in wps]], np.r_[0.0, [w.r for w in wps]])
    e = geom.edges
    if e[-1] <= 0:
        return np.array([q0]), np.zeros(1), [], 1.0
    # IK knots: piece ends plus a grid fine enough for the cubic spline
    Te = U.eval_cart(geom, e)
    travel = np.linalg.norm(np.diff(Te[:, :3, 3], axis=0), axis=1)
    turn = np.array([np.arccos(np.clip((np.trace(Te[i, :3, :3].T @ Te[i + 1, :3, :3]) - 1) / 2, -1, 1))
                     for i in range(len(e) - 1)])
    knots = [0.0]
    for p in np.flatnonzero(geom.length > 0):
        n = int(np.ceil(max(travel[p] / KNOT_STEP_M, turn[p] / KNOT_STEP_RAD, 1)))
        knots.extend(np.linspace(e[p], e[p + 1], n + 1)[1:])
    knots = np.unique(np.asarray(knots))
    Tk = U.eval_cart(geom, knots)
    qk = np.empty((len(knots), 6))
    q_prev = np.asarray(q0, dtype=np.float64)
    for j in range(len(knots)):
        qk[j] = q_prev if j == 0 else _ik_near(model, Tk[j], tcp, q_prev, "movel")
        if np.max(np.abs(qk[j] - q_prev)) > MAX_KNOT_JUMP:
            raise PlanError("movel: the joint solution jumps along the path (passing a singularity?)")
        q_prev = qk[j]
    # the spline passes its knots: break it at corners without a blend (the arm stops there)
    stops = geom.corner[1:-1][geom.length[1::2] == 0]
    stop_idx = np.searchsorted(knots, stops - 1e-12)
    breaks = sorted({0, len(knots) - 1, *(int(j) for j in stop_idx if 0 < j < len(knots) - 1)})
    from scipy.interpolate import CubicSpline  # imported here: it costs ~0.5 s at stand-in start-up

    def joints_at(s):
        q = np.empty((len(s), 6))
        for b0, b1 in zip(breaks[:-1], breaks[1:]):
            m = (s >= knots[b0]) & (s <= knots[b1])
            if b1 - b0 >= 2:
                q[m] = CubicSpline(knots[b0:b1 + 1], qk[b0:b1 + 1], axis=0)(s[m])
            else:
                f = (s[m] - knots[b0]) / (knots[b1] - knots[b0])
                q[m] = qk[b0] + (qk[b1] - qk[b0]) * f[:, None]
        q[0], q[-1] = q0, qk[-1]
        return q

    s, sd, q, stretch = _timed(geom, joints_at, dt, bound)
    return q, sd, _markers(geom, wps, s), stretch


def _plan_joint_run(model, tcp, q0, wps, dt, bound):
    targets, q_prev = [], np.asarray(q0, dtype=np.float64)
    for w in wps:
        qt = np.asarray(w.q, dtype=np.float64) if w.q is not None else \
            _ik_near(model, pose_to_matrix(w.pose), tcp, q_prev, "movej")
        targets.append(qt)
        q_prev = qt
    Q = np.vstack([q0, targets])
    geom = _geometry(U.joint_run, Q, K.fk_tcp(model, Q, tcp)[:, :3, 3], np.r_[0.0, [w.v for w in wps]],
                     np.r_[0.0, [w.a for w in wps]], np.r_[0.0, [w.r for w in wps]], bound)
    if geom.edges[-1] <= 0:
        return np.array([q0, targets[-1]]), np.zeros(2), [], 1.0

    def joints_at(s):
        q = U.eval_joint(geom, s)
        q[0], q[-1] = q0, targets[-1]
        return q

    s, sd, q, stretch = _timed(geom, joints_at, dt, bound)
    return q, sd, _markers(geom, wps, s), stretch


def plan_moves(model, tcp: np.ndarray, q0, waypoints: list[Waypoint], dt: float, *,
               joint_accel_max: float = U.JOINT_ACCEL_MAX) -> Trajectory:
    """Joint samples for a sequence of moves from `q0` (see the module docstring);
    `joint_accel_max` the controller's joint acceleration bound (rad/s^2) with the current payload."""
    model = K.get_model(model)
    for w in waypoints:
        if not (w.v > 0 and w.a > 0 and w.r >= 0):
            raise PlanError(f"{w.kind}: speed and acceleration must be positive and the blend radius >= 0")
    kinds = ["movej" if w.kind == "movej" else "movel" for w in waypoints]
    runs = U.run_bounds(["start"] + kinds, [0.0] + [w.r for w in waypoints])
    q_parts, sd_parts, markers = [np.asarray(q0, dtype=np.float64)[None]], [np.zeros(1)], []
    q_cur, offset, stretch = np.asarray(q0, dtype=np.float64), 0, 1.0
    for first, last in runs:
        wps = waypoints[first:last]
        wps = wps[:-1] + [Waypoint(**{**wps[-1].__dict__, "r": 0.0})]  # a run ends at rest
        plan = _plan_joint_run if kinds[last - 1] == "movej" else _plan_cart_run
        q, sd, mk, k = plan(model, tcp, q_cur, wps, dt, float(joint_accel_max))
        stretch = max(stretch, k)
        markers += [(offset + i, p) for i, p in mk]
        q_parts.append(q[1:])
        sd_parts.append(sd[1:])
        offset += len(q) - 1
        q_cur = q[-1]
    return Trajectory(q=np.vstack(q_parts), speed=np.concatenate(sd_parts), dt=dt, markers=markers, stretch=stretch)
