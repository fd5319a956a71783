"""How a UR controller executes movej/movel: the one motion model of the planner's cycle time, the
checker's interpolation and the controller stand-in's arm.

A program is cut into *runs*: consecutive moves of one kind (movej or movel) whose inner waypoints
all have a blend radius r > 0. A run starts and ends at rest; a waypoint with r = 0, the last one,
and a change between movej and movel end a run (the stand-in, like fabkit's planner, does not blend
between the two kinds).

Geometry of a run (`joint_run`, `cart_run`): straight segments in joint space (movej) or in
Cartesian space (movel: position on the line, orientation by slerp); at an inner waypoint with
r > 0 a quadratic Bezier blend from the point `r` of TCP travel before the waypoint to the point `r`
after it (the blend never passes through the waypoint). The share of a segment a blend takes is
r / (TCP travel of the segment) for both kinds; two blends that together need more than their
segment are an error (`BlendOverlap`), as on a controller ("blends cannot overlap").

Path parameter and speeds: movej measures its path by the largest joint move (rad), so `v` and `a`
bound the leading joint; movel by the larger of the TCP travel (m) and the tool rotation (rad) of a
segment, so `v` bounds both. A blend is taken at the smaller `v` and `a` of its two segments and
measured so that the speed is continuous where it meets them (joint blends by their largest joint
move, movel blends by TCP travel weighted from one segment's path-per-metre to the other's).

Time law (`time_law`, in `robot.time_law`): the time-optimal profile along the run's path parameter with each piece's
speed limit and acceleration, starting and ending at rest: accelerate, cruise, decelerate per
piece, exact for piecewise-constant limits (forward/backward passes over the piece boundaries).
A run too short to reach its speed follows a triangle profile.

Controller limits (`joint_accel_bound`): the joint acceleration a movej may use is capped at the
controller's bound, which falls linearly with the declared payload, to `1 - PAYLOAD_ACCEL_DERATE`
of the unloaded bound at the rated payload; a payload over the rated one is refused
(`PayloadError`). This is the stand-in's model of "the control software adjusts accelerations to the
payload" (UR manuals): UR publishes no law, so the numbers here are fabkit's, not UR's. A movel run
whose executed joint accelerations would exceed the bound is slowed as a whole (`stretch_factor`),
as the controller's trajectory limiter would. The speed slider `f` time-scales every run (speeds
x f, accelerations x f^2, durations / f, the path unchanged).

Hand-written: no library plans UR blends; scipy does the rotations.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from robot.time_law import Profile, time_law

__all__ = ["JOINT_ACCEL_MAX", "PAYLOAD_ACCEL_DERATE", "MIN_TRANSLATION", "MIN_BLEND_SEGMENT", "BlendOverlap",
           "PayloadError", "joint_accel_bound", "stretch_factor", "Profile", "time_law", "RunGeometry",
           "run_bounds", "joint_run", "cart_run", "run_geometry", "eval_joint", "eval_cart", "segment_position",
           "segment_times"]

#: The controller's joint acceleration bound without payload (rad/s^2; URSim 5.8's jointMaxAcceleration).
JOINT_ACCEL_MAX = 40.0
#: Share of the joint acceleration bound lost at the rated payload (linear in the payload mass).
PAYLOAD_ACCEL_DERATE = 0.5
#: Segments with less TCP travel than this (m) are pure rotations.
MIN_TRANSLATION = 1e-7
#: Segments shorter than this (m of TCP travel) are not blended: the arm stops at their corners.
MIN_BLEND_SEGMENT = 1e-5
#: Points of the arc-length table of a Bezier blend.
_BEZIER_TABLE = 65


class BlendOverlap(ValueError):
    """Two blends need more than the segment between them (the controller refuses the program)."""


class PayloadError(ValueError):
    """A declared payload the arm is not rated for (the controller refuses it)."""


def joint_accel_bound(payload_kg: float, rated_kg: float, unloaded: float = JOINT_ACCEL_MAX) -> float:
    """Joint acceleration bound (rad/s^2) with `payload_kg` declared on an arm rated for `rated_kg`:
    `unloaded * (1 - PAYLOAD_ACCEL_DERATE * payload / rated)`; `PayloadError` over the rating."""
    m, rated = float(payload_kg), float(rated_kg)
    if not (np.isfinite(m) and m >= 0.0):
        raise PayloadError(f"payload mass {payload_kg!r} kg is not a mass")
    if m > rated * (1 + 1e-9):
        raise PayloadError(f"payload {m:g} kg exceeds the arm's rated payload of {rated:g} kg")
    return float(unloaded) * (1.0 - PAYLOAD_ACCEL_DERATE * m / rated)


def stretch_factor(peak_accel: float, bound: float) -> float:
    """Time-scaling factor (>= 1) that brings a run's peak joint acceleration within `bound`
    (accelerations scale by 1 / factor^2 when a run is slowed uniformly)."""
    if not (peak_accel > bound > 0):
        return 1.0
    return float(np.sqrt(peak_accel / bound))


# ---- geometry ------------------------------------------------------------------------------------

def run_bounds(moves, r) -> list[tuple[int, int]]:
    """Runs of a program as (first, last) waypoint indices (the run moves from `first` to `last`):
    consecutive moves of one kind whose inner waypoints all have r > 0 (module docstring)."""
    n = len(moves)
    out, start = [], 0
    r = np.asarray(r, dtype=np.float64)
    for j in range(1, n):
        if j == n - 1 or r[j] <= 0 or moves[j + 1] != moves[j]:
            out.append((start, j))
            start = j
    return out


@dataclass(frozen=True, eq=False)
class RunGeometry:
    """The path of one run of k segments as 2k - 1 pieces in order: line of segment j at index 2j,
    blend at inner waypoint c (1..k-1) at index 2c - 1 (zero length where there is none).

    `length` (2k-1,) path-parameter length of each piece; `v`, `a` (2k-1,) their limits; `f0`, `f1`
    (k,) the stretch of each segment its line covers (fractions of the segment); `corner` (k+1,) path
    parameter at which the run passes each waypoint (the middle of a blend); `kind` "movej" | "movel";
    `nodes` (k+1, d) the waypoints (joints, or TCP positions); `rotations` the TCP orientations
    (movel) and `rotvec` (k, 3) each segment's rotation; `tables` the blends' cumulative arc lengths
    (k-1, _BEZIER_TABLE)."""

    kind: str
    length: np.ndarray
    v: np.ndarray
    a: np.ndarray
    f0: np.ndarray
    f1: np.ndarray
    corner: np.ndarray
    nodes: np.ndarray
    rotations: object = None
    rotvec: np.ndarray | None = None
    tables: np.ndarray | None = None

    @property
    def edges(self) -> np.ndarray:
        return np.r_[0.0, np.cumsum(self.length)]

    def profile(self) -> Profile:
        return time_law(self.length, self.v, self.a)

    def locate(self, s) -> tuple[np.ndarray, np.ndarray]:
        """(piece index, fraction within the piece) of path parameters `s`."""
        e = self.edges
        s = np.clip(np.asarray(s, dtype=np.float64), 0.0, e[-1])
        p = np.clip(np.searchsorted(e, s, side="right") - 1, 0, len(self.length) - 1)
        # a parameter on a boundary belongs to the piece that starts there
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.where(self.length[p] > 0, (s - e[p]) / self.length[p], 0.0)
        return p, np.clip(f, 0.0, 1.0)


def _blend_shares(tcp_travel: np.ndarray, r: np.ndarray, blendable: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fractions (before, after) of the segments each inner waypoint's blend takes: before[c] on
    segment c-1, after[c] on segment c (index c = inner waypoint 1..k-1; entries 0 and k unused)."""
    k = len(tcp_travel)
    before, after = np.zeros(k + 1), np.zeros(k + 1)
    for c in range(1, k):
        if r[c] > 0 and blendable[c - 1] and blendable[c]:
            before[c] = r[c] / tcp_travel[c - 1]
            after[c] = r[c] / tcp_travel[c]
    used = after[:-1] + before[1:]  # per segment j: the blend leaving corner j plus the one entering j+1
    bad = np.flatnonzero(used > 1 + 1e-9)
    if len(bad):
        raise BlendOverlap(f"blend radius overlap on the segment to waypoint {int(bad[0]) + 1} of the run "
                           "(blends cannot overlap)")
    return before, after


def _bezier(A, P, C, u):
    u = u[..., None]
    return (1 - u) ** 2 * A + 2 * u * (1 - u) * P + u ** 2 * C


def _bezier_lengths(A, P, C, rho_in=None, rho_out=None, joint: bool = False) -> np.ndarray:
    """Path-parameter tables (nb, _BEZIER_TABLE) of quadratic Beziers A-P-C (nb, d): cumulative
    length (Euclidean; the largest component for joint blends, as movej measures its lines),
    weighted by a path-per-metre ratio going linearly from `rho_in` to `rho_out` (nb,) so that the
    speed along the path is continuous where the blend meets its segments."""
    u = np.linspace(0.0, 1.0, _BEZIER_TABLE)
    pts = _bezier(A[:, None], P[:, None], C[:, None], np.broadcast_to(u, (len(A), len(u))))
    step = np.diff(pts, axis=1)
    ds = np.max(np.abs(step), axis=2) if joint else np.linalg.norm(step, axis=2)
    if rho_in is not None:
        mid = 0.5 * (u[1:] + u[:-1])
        ds = ds * ((1 - mid)[None] * rho_in[:, None] + mid[None] * rho_out[:, None])
    return np.concatenate([np.zeros((len(A), 1)), np.cumsum(ds, axis=1)], axis=1)


def _assemble(kind, plen, v, a, before, after, blend_len, nodes, **extra) -> RunGeometry:
    k = len(plen)
    f0, f1 = after[:-1], 1.0 - before[1:]
    lines = np.maximum(f1 - f0, 0.0) * plen
    length = np.zeros(2 * k - 1)
    length[0::2] = lines
    blends = np.zeros(max(k - 1, 0))
    if k > 1:
        blends = np.where(before[1:-1] > 0, blend_len, 0.0)
        length[1::2] = blends
    vv, aa = np.zeros(2 * k - 1), np.zeros(2 * k - 1)
    vv[0::2], aa[0::2] = v, a
    if k > 1:
        # a blend is taken at the slower of its segments; an inner corner without one is a stop
        vv[1::2] = np.where(before[1:-1] > 0, np.minimum(v[:-1], v[1:]), 0.0)
        aa[1::2] = np.minimum(a[:-1], a[1:])
    e = np.r_[0.0, np.cumsum(length)]
    corner = np.empty(k + 1)
    corner[0], corner[-1] = 0.0, e[-1]
    corner[1:-1] = 0.5 * (e[1:-2:2] + e[2:-1:2])
    return RunGeometry(kind=kind, length=length, v=vv, a=aa, f0=f0, f1=f1, corner=corner, nodes=nodes, **extra)


def joint_run(Q, P, v, a, r, accel_bound: float = np.inf) -> RunGeometry:
    """A movej run through joints `Q` (k+1, 6) whose TCP positions are `P` (k+1, 3); `v`, `a`, `r`
    (k+1,) of the move to each waypoint (entry 0 unused; `a` capped at `accel_bound`)."""
    Q = np.asarray(Q, dtype=np.float64)
    d = np.diff(Q, axis=0)
    plen = np.max(np.abs(d), axis=1)
    travel = np.linalg.norm(np.diff(np.asarray(P, dtype=np.float64), axis=0), axis=1)
    before, after = _blend_shares(travel, np.asarray(r, dtype=np.float64),
                                  (travel > MIN_BLEND_SEGMENT) & (plen > 1e-12))
    k = len(d)
    blend_len, tables = np.zeros(max(k - 1, 0)), None
    if k > 1:
        c = np.arange(1, k)
        A = Q[c] - d[c - 1] * before[c][:, None]
        C = Q[c] + d[c] * after[c][:, None]
        tables = _bezier_lengths(A, Q[c], C, joint=True)
        blend_len = np.maximum(tables[:, -1], 1e-12)
    aa = np.minimum(np.asarray(a, dtype=np.float64)[1:], accel_bound)
    return _assemble("movej", plen, np.asarray(v, dtype=np.float64)[1:], aa, before, after, blend_len, Q,
                     tables=tables)


def cart_run(P, R, v, a, r) -> RunGeometry:
    """A movel run through TCP positions `P` (k+1, 3) and orientations `R` (k+1, 3, 3); `v`, `a`, `r`
    (k+1,) of the move to each waypoint (entry 0 unused)."""
    P = np.asarray(P, dtype=np.float64)
    rots = Rotation.from_matrix(np.asarray(R, dtype=np.float64))
    d = np.diff(P, axis=0)
    travel = np.linalg.norm(d, axis=1)
    rotvec = (rots[:-1].inv() * rots[1:]).as_rotvec()
    ang = np.linalg.norm(rotvec, axis=1)
    trans = travel > MIN_TRANSLATION
    plen = np.where(trans, np.maximum(travel, ang), ang)
    before, after = _blend_shares(np.where(trans, travel, 1.0), np.asarray(r, dtype=np.float64),
                                  trans & (travel > MIN_BLEND_SEGMENT))
    k = len(d)
    blend_len, tables = np.zeros(max(k - 1, 0)), None
    if k > 1:
        c = np.arange(1, k)
        A = P[c] - d[c - 1] * before[c][:, None]
        C = P[c] + d[c] * after[c][:, None]
        rho = plen / np.where(trans, travel, 1.0)  # path per metre of travel on each segment (>= 1)
        tables = _bezier_lengths(A, P[c], C, rho[c - 1], rho[c])
        blend_len = np.maximum(tables[:, -1], 1e-12)
    return _assemble("movel", plen, np.asarray(v, dtype=np.float64)[1:], np.asarray(a, dtype=np.float64)[1:],
                     before, after, blend_len, P, rotations=rots, rotvec=rotvec, tables=tables)


def _blend_u(geom: RunGeometry, c: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Bezier parameter at arc-length fraction `f` of the blends at inner waypoints `c`."""
    u = np.linspace(0.0, 1.0, _BEZIER_TABLE)
    out = np.empty(len(c))
    for cc in np.unique(c):
        m = c == cc
        tab = geom.tables[cc - 1]
        out[m] = np.interp(f[m] * tab[-1], tab, u)
    return out


def _blend_ends(geom: RunGeometry, c: np.ndarray):
    """Start A, corner, end C of the blends at inner waypoints `c`, and the segment fractions there."""
    N = geom.nodes
    fA, fC = geom.f1[c - 1], geom.f0[c]
    A = N[c - 1] + (N[c] - N[c - 1]) * fA[:, None]
    C = N[c] + (N[c + 1] - N[c]) * fC[:, None]
    return A, N[c], C, fA, fC


def segment_position(geom: RunGeometry, s) -> tuple[np.ndarray, np.ndarray]:
    """Where path parameters `s` lie as (segment index, fraction along that segment's chord): on a
    line its own segment; in the first half of a blend the segment into the corner, else the next
    (the fraction is that of the blend's end on its segment, interpolated along the blend)."""
    p, f = geom.locate(s)
    seg = p // 2
    frac = geom.f0[seg] + f * (geom.f1[seg] - geom.f0[seg])
    blend = p % 2 == 1
    if np.any(blend):
        c = (p[blend] + 1) // 2
        fb = f[blend]
        first = fb < 0.5
        fA, fC = geom.f1[c - 1], geom.f0[c]
        seg_b = np.where(first, c - 1, c)
        frac_b = np.where(first, fA + (1 - fA) * 2 * fb, fC * (2 * fb - 1))
        seg[blend], frac[blend] = seg_b, frac_b
    return seg, np.clip(frac, 0.0, 1.0)


def eval_joint(geom: RunGeometry, s) -> np.ndarray:
    """Joints (n, 6) of a movej run at path parameters `s`."""
    p, f = geom.locate(s)
    Q = geom.nodes
    out = np.empty((len(p), Q.shape[1]))
    line = p % 2 == 0
    j = p[line] // 2
    g = geom.f0[j] + f[line] * (geom.f1[j] - geom.f0[j])
    out[line] = Q[j] + (Q[j + 1] - Q[j]) * g[:, None]
    if np.any(~line):
        c = (p[~line] + 1) // 2
        A, M, C, _, _ = _blend_ends(geom, c)
        out[~line] = _bezier(A, M, C, _blend_u(geom, c, f[~line]))
    return out


def eval_cart(geom: RunGeometry, s) -> np.ndarray:
    """TCP poses (n, 4, 4) of a movel run at path parameters `s`."""
    p, f = geom.locate(s)
    P, rots, rv = geom.nodes, geom.rotations, geom.rotvec
    T = np.tile(np.eye(4), (len(p), 1, 1))
    line = p % 2 == 0
    if np.any(line):
        j = p[line] // 2
        g = geom.f0[j] + f[line] * (geom.f1[j] - geom.f0[j])
        T[line, :3, 3] = P[j] + (P[j + 1] - P[j]) * g[:, None]
        T[line, :3, :3] = (rots[j] * Rotation.from_rotvec(rv[j] * g[:, None])).as_matrix()
    if np.any(~line):
        c = (p[~line] + 1) // 2
        A, M, C, fA, fC = _blend_ends(geom, c)
        u = _blend_u(geom, c, f[~line])
        T[~line, :3, 3] = _bezier(A, M, C, u)
        RA = rots[c - 1] * Rotation.from_rotvec(rv[c - 1] * fA[:, None])
        RC = rots[c] * Rotation.from_rotvec(rv[c] * fC[:, None])
        T[~line, :3, :3] = (RA * Rotation.from_rotvec((RA.inv() * RC).as_rotvec() * u[:, None])).as_matrix()
    return T


def run_geometry(moves, positions, rotations, joints, v, a, r, first: int, last: int,
                 accel_bound: float = np.inf) -> RunGeometry:
    """The geometry of the run from waypoint `first` to `last` of a program (arrays as in `segment_times`)."""
    sl = slice(first, last + 1)
    rr = np.asarray(r, dtype=np.float64)[sl].copy()
    rr[-1] = 0.0
    if moves[last] == "movel":
        return cart_run(np.asarray(positions)[sl], np.asarray(rotations)[sl], np.asarray(v)[sl], np.asarray(a)[sl], rr)
    return joint_run(np.asarray(joints)[sl], np.asarray(positions)[sl], np.asarray(v)[sl], np.asarray(a)[sl], rr,
                     accel_bound)


def segment_times(moves, positions, rotations, joints, v, a, r, accel_bound=np.inf) -> np.ndarray:
    """Duration (s) of each segment i -> i+1 (n - 1 values): from passing waypoint i to passing
    waypoint i+1 (the middle of a blend) under the time law, at full speed slider.

    moves (n,) "movej"|"movel" (the move *to* each waypoint); positions (n, 3) TCP [m]; rotations
    (n, 3, 3); joints (n, 6) [rad]; v, a, r (n,) of the move to each waypoint; `accel_bound` the
    joint acceleration bound (rad/s^2, scalar or (n,) per waypoint) that caps movej accelerations.
    """
    n = len(moves)
    out = np.zeros(max(n - 1, 0))
    if n < 2:
        return out
    bound = np.broadcast_to(np.asarray(accel_bound, dtype=np.float64), (n,))
    runs = run_bounds(moves, r)
    single = np.array([first for first, last in runs if last == first + 1], dtype=np.int64)
    if len(single):  # one-move runs, vectorised: a rest-to-rest trapezoid over the move's path length
        out[single] = _single_move_times(moves, positions, rotations, joints, v, a, bound, single)
    for first, last in runs:
        if last == first + 1:
            continue
        geom = run_geometry(moves, positions, rotations, joints, v, a, r, first, last,
                            float(np.min(bound[first + 1:last + 1])))
        prof = geom.profile()
        out[first:last] = np.diff(prof.time_at(geom.corner))
    return out


def _single_move_times(moves, positions, rotations, joints, v, a, bound, i) -> np.ndarray:
    """Durations of the moves i -> i+1 that are runs of their own (the time law of one piece)."""
    P, R, Q = np.asarray(positions, dtype=np.float64), np.asarray(rotations, dtype=np.float64), \
        np.asarray(joints, dtype=np.float64)
    travel = np.linalg.norm(P[i + 1] - P[i], axis=1)
    ang = Rotation.from_matrix(np.swapaxes(R[i], 1, 2) @ R[i + 1]).magnitude()
    linear = np.asarray(moves)[i + 1] == "movel"
    length = np.where(linear, np.where(travel > MIN_TRANSLATION, np.maximum(travel, ang), ang),
                      np.max(np.abs(Q[i + 1] - Q[i]), axis=1))
    vv = np.asarray(v, dtype=np.float64)[i + 1]
    aa = np.asarray(a, dtype=np.float64)[i + 1]
    aa = np.where(linear, aa, np.minimum(aa, bound[i + 1]))
    if not (np.all(aa > 0) and np.all(vv > 0)):
        raise ValueError("speeds and accelerations must be > 0")
    full = length >= vv * vv / aa
    return np.where(full, length / vv + vv / aa, 2.0 * np.sqrt(length / aa))
