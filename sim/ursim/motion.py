"""Motion planning of the controller stand-in: UR-style movej/movel sequences with blends.

`plan_moves` turns a run of `Waypoint`s (what `movej`/`movel`/`movep` statements, ur_rtde's
register moves and its injected paths ask for) into joint samples at the controller period:

- geometry: straight segments in joint space (movej) or Cartesian space (movel/movep: position
  on a line, orientation by slerp) and, where a waypoint has a blend radius, a quadratic Bezier
  blend from the point `r` before the waypoint to the point `r` after it (UR blends never pass
  through the waypoint; overlapping blend zones are a runtime error, as on a controller);
- timing: a trapezoidal profile along the path parameter with each segment's speed `v` and
  acceleration `a`, full stops at waypoints with r = 0 and where movej and movel meet (the
  stand-in does not blend between the two kinds);
- Cartesian runs go through `robot.kinematics.ik` at knots a few millimetres apart (branch nearest
  the previous knot) and a cubic spline in joint space between knots; the knots include every
  segment end, so the arm ends exactly on the IK of each stopping waypoint.

The path parameter is the largest joint move (rad) for movej, as UR's movej lets the leading joint
run at `v`, and for movel the larger of the TCP travel (m) and the tool rotation (rad) per segment,
so that `v` bounds both (the timing model of `robot.motion`). Hand-written: no library plans UR blends; scipy does the rotations and splines.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from robot import kinematics as K
from robot.cell import matrix_to_pose, pose_to_matrix  # noqa: F401 (re-exported for the stand-in)

#: Knot spacing of Cartesian runs for IK: metres of TCP travel and radians of tool rotation.
KNOT_STEP_M = 0.004
KNOT_STEP_RAD = 0.02
#: Segments shorter than this (m) count as pure rotations.
MIN_TRANSLATION = 1e-7
#: Segments shorter than this (m, or rad for movej) are not blended (the arm is already there).
MIN_BLEND_SEGMENT = 1e-5
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
    sample (`speed`, in the unit of its segment), and `markers`: (sample index, progress value)."""

    q: np.ndarray
    speed: np.ndarray
    dt: float
    markers: list = field(default_factory=list)

    @property
    def duration(self) -> float:
        return (len(self.q) - 1) * self.dt


# ---- time parametrisation ----------------------------------------------------------------------

def _time_law(length: float, vlim, alim, dt: float):
    """Sample times of a path of parameter length `length` with speed limit `vlim(s)` and
    acceleration `alim(s)` (callables over arrays), starting and ending at rest.

    Forward/backward pass on a grid of the parameter (exact for constant acceleration between grid
    points, since v^2 is linear in s there); returns (s, sdot) at multiples of `dt`, the last sample
    exactly at `length`.
    """
    if length <= 0:
        return np.zeros(1), np.zeros(1)
    n = int(min(4000, max(50, length / 1e-5)))
    s = np.linspace(0.0, length, n + 1)
    mid = 0.5 * (s[1:] + s[:-1])
    vmax = np.minimum(vlim(s), np.r_[vlim(mid), np.inf])  # limit at nodes and in the next cell
    vmax[0] = vmax[-1] = 0.0
    acc = alim(mid)
    ds = s[1] - s[0]
    v2 = np.minimum(vmax, 1e9) ** 2
    for k in range(n):  # forward
        v2[k + 1] = min(v2[k + 1], v2[k] + 2 * acc[k] * ds)
    for k in range(n - 1, -1, -1):  # backward
        v2[k] = min(v2[k], v2[k + 1] + 2 * acc[k] * ds)
    v = np.sqrt(np.maximum(v2, 0.0))
    vsum = v[1:] + v[:-1]
    if np.any(vsum <= 0):
        raise PlanError("speed or acceleration is zero along the path")
    cell_t = 2 * ds / vsum
    t = np.r_[0.0, np.cumsum(cell_t)]
    samples = np.arange(0.0, t[-1], dt)
    k = np.clip(np.searchsorted(t, samples, side="right") - 1, 0, n - 1)
    tau = samples - t[k]
    a_cell = (v[k + 1] ** 2 - v[k] ** 2) / (2 * ds)
    s_out = np.minimum(s[k] + v[k] * tau + 0.5 * a_cell * tau ** 2, length)
    sd = v[k] + a_cell * tau
    return np.r_[s_out, length], np.r_[sd, 0.0]


# ---- geometry ----------------------------------------------------------------------------------

@dataclass
class _Piece:
    s0: float
    s1: float
    kind: str  # "line" | "blend"
    data: tuple
    v: float
    a: float


def _bezier(A, P, C, u):
    u = u[:, None]
    return (1 - u) ** 2 * A + 2 * u * (1 - u) * P + u ** 2 * C


def _bezier_table(A, P, C):
    """Arc-length table of a quadratic Bezier: (u grid, cumulative length)."""
    u = np.linspace(0.0, 1.0, 65)
    pts = _bezier(A, P, C, u)
    L = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]
    return u, L


def _blend_lengths(r: np.ndarray, seg_len: np.ndarray, blendable: np.ndarray, labels):
    """Blend distances on each side of every interior waypoint; overlap is an error, as on UR."""
    n = len(seg_len)
    before, after = np.zeros(n), np.zeros(n)  # before[i]: on segment i, after[i]: on segment i+1
    for i in range(n - 1):
        if r[i] > 0 and blendable[i] and blendable[i + 1]:
            before[i] = r[i] * seg_len[i][1]
            after[i] = r[i] * seg_len[i + 1][1]
    for i in range(n):
        used = before[i] + (after[i - 1] if i > 0 else 0.0)
        if used > seg_len[i][0] * (1 + 1e-9) + 1e-12:
            raise PlanError(f"blend radius overlap at waypoint {labels[i]} (blends cannot overlap)")
    return before, after


def _joint_run(model, q0, targets, v, a, r, tcp):
    """Pieces of a movej run in joint space (parameter = largest joint move, rad)."""
    Q = np.vstack([q0, targets])
    d = np.diff(Q, axis=0)
    plen = np.max(np.abs(d), axis=1)
    P = K.fk_tcp(model, Q, tcp)[:, :3, 3]
    tlen = np.linalg.norm(np.diff(P, axis=0), axis=1)
    # blend: r metres of TCP travel -> parameter units per segment
    seg = [(plen[i], plen[i] / tlen[i] if tlen[i] > 1e-9 else 0.0) for i in range(len(d))]
    blendable = plen > MIN_BLEND_SEGMENT
    before, after = _blend_lengths(np.asarray(r), seg, blendable, list(range(len(d))))
    pieces, s, begins = [], 0.0, [0.0]
    start_off = 0.0
    for i in range(len(d)):
        if plen[i] <= 1e-12:
            start_off = 0.0
            begins.append(s)
            continue
        dirn = d[i] / plen[i]
        a0, a1 = start_off, plen[i] - before[i]
        if a1 > a0:
            pieces.append(_Piece(s, s + a1 - a0, "line", (Q[i] + dirn * a0, Q[i] + dirn * a1), v[i], a[i]))
            s += a1 - a0
        begins.append(s)
        if before[i] > 0:
            A, C = Q[i + 1] - dirn * before[i], Q[i + 1] + d[i + 1] / plen[i + 1] * after[i]
            u, L = _bezier_table(A, Q[i + 1], C)
            length = max(L[-1], 1e-12)
            pieces.append(_Piece(s, s + length, "blend", (A, Q[i + 1], C, u, L), min(v[i], v[i + 1]),
                                 min(a[i], a[i + 1])))
            s += length
        start_off = after[i]
    return pieces, s, begins[:len(d)]


def _eval_joint(pieces, s):
    out = np.empty((len(s), 6))
    for pc in pieces:
        m = (s >= pc.s0) & (s <= pc.s1)
        if not np.any(m):
            continue
        f = (s[m] - pc.s0) / max(pc.s1 - pc.s0, 1e-300)
        if pc.kind == "line":
            qa, qb = pc.data
            out[m] = qa + (qb - qa) * f[:, None]
        else:
            A, P, C, u, L = pc.data
            out[m] = _bezier(A, P, C, np.interp(f * L[-1], L, u))
    return out


def _cart_run(P0, R0, poses, v, a, r):
    """Pieces of a movel run. The path parameter of a segment is the larger of its TCP travel (m)
    and its tool rotation (rad), so `v` also bounds the rotation speed (as `robot.motion` times
    moves); blends are measured in metres of travel."""
    Ps = np.vstack([P0, poses[:, :3]])
    Rs = Rotation.concatenate([R0, Rotation.from_rotvec(poses[:, 3:])])
    d = np.diff(Ps, axis=0)
    tl = np.linalg.norm(d, axis=1)
    ang = np.array([(Rs[i].inv() * Rs[i + 1]).magnitude() for i in range(len(d))])
    trans = tl > MIN_TRANSLATION
    plen = np.where(trans, np.maximum(tl, ang), ang)
    seg = [(tl[i], 1.0) for i in range(len(d))]
    before, after = _blend_lengths(np.asarray(r), seg, trans & (tl > MIN_BLEND_SEGMENT), list(range(len(d))))
    pieces, s, start_off, begins, stops = [], 0.0, 0.0, [0.0], []
    for i in range(len(d)):
        if plen[i] <= 1e-12:
            start_off = 0.0
            begins.append(s)
            continue
        slerp = Slerp([0.0, 1.0], Rotation.concatenate([Rs[i], Rs[i + 1]]))
        f0, f1 = (start_off / tl[i], (tl[i] - before[i]) / tl[i]) if trans[i] else (0.0, 1.0)
        if f1 > f0:
            pieces.append(_Piece(s, s + (f1 - f0) * plen[i], "line", (Ps[i], Ps[i + 1], slerp, f0, f1), v[i], a[i]))
            s += (f1 - f0) * plen[i]
        begins.append(s)
        if before[i] == 0:
            stops.append(s)
        if before[i] > 0:
            A = Ps[i + 1] - d[i] / tl[i] * before[i]
            C = Ps[i + 1] + d[i + 1] / tl[i + 1] * after[i]
            RA = slerp([f1])[0]
            RC = Slerp([0.0, 1.0], Rotation.concatenate([Rs[i + 1], Rs[i + 2]]))([after[i] / tl[i + 1]])[0]
            u, L = _bezier_table(A, Ps[i + 1], C)
            length = max(L[-1], (RA.inv() * RC).magnitude())
            pieces.append(_Piece(s, s + length, "blend",
                                 (A, Ps[i + 1], C, u, L, Slerp([0.0, 1.0], Rotation.concatenate([RA, RC]))),
                                 min(v[i], v[i + 1]), min(a[i], a[i + 1])))
            s += length
        start_off = after[i]
    return pieces, s, begins[:len(d)], stops


def _eval_cart(pieces, s) -> np.ndarray:
    """TCP poses (n, 4, 4) at path parameters `s`."""
    T = np.tile(np.eye(4), (len(s), 1, 1))
    for pc in pieces:
        m = (s >= pc.s0) & (s <= pc.s1)
        if not np.any(m):
            continue
        f = (s[m] - pc.s0) / max(pc.s1 - pc.s0, 1e-300)
        if pc.kind == "line":
            pa, pb, slerp, f0, f1 = pc.data
            g = f0 + (f1 - f0) * f
            T[m, :3, 3] = pa + (pb - pa) * g[:, None]
            T[m, :3, :3] = slerp(g).as_matrix()
        else:
            A, P, C, u, L, slerp = pc.data
            uu = np.interp(f * L[-1], L, u)
            T[m, :3, 3] = _bezier(A, P, C, uu)
            T[m, :3, :3] = slerp(uu).as_matrix()
    return T


def _limits(pieces, attr):
    s0 = np.array([p.s0 for p in pieces])
    vals = np.array([getattr(p, attr) for p in pieces])

    def f(s):
        k = np.clip(np.searchsorted(s0, s, side="right") - 1, 0, len(pieces) - 1)
        return vals[k]
    return f


def _ik_near(model, T, tcp, q_ref, what: str) -> np.ndarray:
    sols = K.ik(model, T, tcp)
    if len(sols) == 0:
        raise PlanError(f"{what}: inverse kinematics found no solution (pose out of reach)")
    return K.select_nearest(sols, q_ref, model=model)


def _plan_cart_run(model, tcp, q0, wps, dt):
    T0 = K.fk_tcp(model, q0, tcp)
    poses = np.array([w.pose for w in wps], dtype=np.float64)
    for i, p in enumerate(poses):  # a target out of reach fails before the arm moves
        if len(K.ik(model, pose_to_matrix(p), tcp)) == 0:
            raise PlanError(f"movel: inverse kinematics found no solution for target {i} (pose out of reach)")
    pieces, length, begins, stops = _cart_run(T0[:3, 3], Rotation.from_matrix(T0[:3, :3]), poses,
                               [w.v for w in wps], [w.a for w in wps], [w.r for w in wps])
    if not pieces:
        return np.array([q0]), np.zeros(1), []
    s, sd = _time_law(length, _limits(pieces, "v"), _limits(pieces, "a"), dt)
    # IK knots: piece ends plus a grid fine enough for the cubic spline
    knots = [0.0]
    for pc in pieces:
        Tm = _eval_cart([pc], np.array([pc.s0, pc.s1]))
        ang = Rotation.from_matrix(Tm[0, :3, :3]).inv() * Rotation.from_matrix(Tm[1, :3, :3])
        travel = np.linalg.norm(Tm[1, :3, 3] - Tm[0, :3, 3])
        n = int(np.ceil(max(travel / KNOT_STEP_M, ang.magnitude() / KNOT_STEP_RAD, 1)))
        knots.extend(np.linspace(pc.s0, pc.s1, n + 1)[1:])
    knots = np.unique(np.asarray(knots))
    Tk = _eval_cart(pieces, knots)
    qk = np.empty((len(knots), 6))
    q_prev = np.asarray(q0, dtype=np.float64)
    for j in range(len(knots)):
        qk[j] = q_prev if j == 0 else _ik_near(model, Tk[j], tcp, q_prev, "movel")
        if np.max(np.abs(qk[j] - q_prev)) > MAX_KNOT_JUMP:
            raise PlanError("movel: the joint solution jumps along the path (passing a singularity?)")
        q_prev = qk[j]
    # exact ends for every stopping waypoint: the spline passes its knots
    stop_idx = np.searchsorted(knots, np.asarray(stops) - 1e-12)
    breaks = sorted({0, len(knots) - 1, *(int(j) for j in stop_idx if 0 < j < len(knots) - 1)})
    from scipy.interpolate import CubicSpline  # imported here: it costs ~0.5 s at stand-in start-up

    q = np.empty((len(s), 6))
    for b0, b1 in zip(breaks[:-1], breaks[1:]):
        m = (s >= knots[b0]) & (s <= knots[b1])
        if b1 - b0 >= 2:
            q[m] = CubicSpline(knots[b0:b1 + 1], qk[b0:b1 + 1], axis=0)(s[m])
        else:
            f = (s[m] - knots[b0]) / (knots[b1] - knots[b0])
            q[m] = qk[b0] + (qk[b1] - qk[b0]) * f[:, None]
    q[0], q[-1] = q0, qk[-1]
    return q, sd, _markers(begins, wps, s)


def _markers(begins, wps, s):
    """Sample indices where the move toward each waypoint begins (URScript returns from a blended
    move when its blend starts, so the next `signal_async_progress` runs there)."""
    return [(int(np.searchsorted(s, begins[i] - 1e-12)), w.progress) for i, w in enumerate(wps) if w.progress >= 0]


def _plan_joint_run(model, tcp, q0, wps, dt):
    targets, q_prev = [], np.asarray(q0, dtype=np.float64)
    for w in wps:
        if w.q is not None:
            qt = np.asarray(w.q, dtype=np.float64)
        else:
            qt = _ik_near(model, pose_to_matrix(w.pose), tcp, q_prev, "movej")
        targets.append(qt)
        q_prev = qt
    pieces, length, begins = _joint_run(model, np.asarray(q0, dtype=np.float64), np.array(targets),
                                [w.v for w in wps], [w.a for w in wps], [w.r for w in wps], tcp)
    if not pieces:
        return np.array([q0, targets[-1]]), np.zeros(2), []
    s, sd = _time_law(length, _limits(pieces, "v"), _limits(pieces, "a"), dt)
    q = _eval_joint(pieces, s)
    q[0], q[-1] = q0, targets[-1]
    return q, sd, _markers(begins, wps, s)


def plan_moves(model, tcp: np.ndarray, q0, waypoints: list[Waypoint], dt: float) -> Trajectory:
    """Joint samples for a sequence of moves from `q0` (see the module docstring)."""
    model = K.get_model(model)
    for w in waypoints:
        if not (w.v > 0 and w.a > 0 and w.r >= 0):
            raise PlanError(f"{w.kind}: speed and acceleration must be positive and the blend radius >= 0")
    runs, cur = [], []
    for w in waypoints:
        kind = "j" if w.kind == "movej" else "l"
        if cur and cur[0][0] != kind:
            runs.append(cur)
            cur = []
        cur.append((kind, w))
    if cur:
        runs.append(cur)
    q_parts, sd_parts, markers = [np.asarray(q0, dtype=np.float64)[None]], [np.zeros(1)], []
    q_cur, offset = np.asarray(q0, dtype=np.float64), 0
    for run in runs:
        wps = [w for _, w in run]
        wps = wps[:-1] + [Waypoint(**{**wps[-1].__dict__, "r": 0.0})]  # a run ends at rest
        plan = _plan_joint_run if run[0][0] == "j" else _plan_cart_run
        q, sd, mk = plan(model, tcp, q_cur, wps, dt)
        markers += [(offset + i, p) for i, p in mk]
        q_parts.append(q[1:])
        sd_parts.append(sd[1:])
        offset += len(q) - 1
        q_cur = q[-1]
    return Trajectory(q=np.vstack(q_parts), speed=np.concatenate(sd_parts), dt=dt, markers=markers)
