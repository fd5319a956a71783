"""The configurations of a blended run as the controller drives it, for the check.

A run of two or more moves with blends (`robot.ur_motion.run_bounds`) does not pass through its
inner waypoints: the arm takes each corner on a Bezier blend (`robot.ur_motion`'s geometry, the
one the controller stand-in executes). Here the run's path is sampled at steps no coarser than the
check's step sizes; movel runs follow the blended TCP path by inverse kinematics continuously from
the run's first joints (as the controller does: it never jumps to stored joints mid-run), movej
runs interpolate the blended joint path. The middle of each blend stands for its waypoint.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot import kinematics as kin
from robot import ur_motion as U

__all__ = ["track_ik", "RunSamples", "sample_run"]


def track_ik(model, flanges: np.ndarray, q_start: np.ndarray):
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
                D = prev + kin.wrap_angle(S - prev)
                cost = np.max(np.abs(D - prev), axis=1)
                i = int(np.argmin(cost))
                best, best_cost = D[i], cost[i]
            # the raw solver drops the wanted branch at axis-aligned poses (reference section 2.3):
            # ask the wrapped solver whenever the raw answer is missing or far from the last joints
            if best is None or best_cost > 0.2 or len(S) < 8:
                S = kin.ik(model, T)
                if len(S) == 0:
                    return out[:k], k
                D = prev + kin.wrap_angle(S - prev)
                cost = np.max(np.abs(D - prev), axis=1)
                best = D[int(np.argmin(cost))]
            out[k] = best
            prev = best
    return out, None


@dataclass(frozen=True, eq=False)
class RunSamples:
    """Samples strictly inside a run (its first and last waypoints excluded), in order.

    `q` (m, 6); `s` (m,) path parameter within the run; `waypoint` (m,) program index of the
    waypoint each sample belongs to; `corner` (m,) True at the middle of a blend (that waypoint's
    own configuration); `state_seg`, `state_frac` where the sample lies along the program's
    segments (for the fold state); `v` (m,) speed cap of the piece (path units/s); `end_q` the
    joints where the run ends (None if it left the workspace); `unreachable_at` the program
    waypoint whose move left the workspace and the fraction of the way, or None; `geometry` the
    run's `robot.ur_motion.RunGeometry`."""

    q: np.ndarray
    s: np.ndarray
    waypoint: np.ndarray
    corner: np.ndarray
    state_seg: np.ndarray
    state_frac: np.ndarray
    v: np.ndarray
    end_q: np.ndarray | None
    unreachable_at: tuple | None
    geometry: U.RunGeometry


def _parameters(geom: U.RunGeometry, steps: np.ndarray, cap: int, factor: int = 1) -> np.ndarray:
    """Path parameters inside the run: every piece divided into steps (the segment's steps times
    the share of it the piece covers, at least one), the blend middles included."""
    e = geom.edges
    k = len(geom.f0)
    out = []
    for p in range(2 * k - 1):
        if geom.length[p] <= 0:
            continue
        if p % 2 == 0:
            j = p // 2
            n = steps[j] * (geom.f1[j] - geom.f0[j])
        else:
            c = (p + 1) // 2
            n = steps[c - 1] * (1 - geom.f1[c - 1]) + steps[c] * geom.f0[c]
        n = int(min(max(math.ceil(n * factor), 1), cap))
        out.append(e[p] + (np.arange(1, n + 1) / n) * geom.length[p])
    s = np.concatenate(out) if out else np.zeros(0)
    s = s[s < e[-1] * (1 - 1e-12)]
    # no two samples closer than a tiny fraction of the run, and the blend middles exactly
    inner = geom.corner[1:-1]
    if len(inner) and len(s):
        k = np.clip(np.searchsorted(inner, s), 1, len(inner)) - 1
        near = np.minimum(np.abs(s - inner[k]), np.abs(s - inner[np.minimum(k + 1, len(inner) - 1)]))
        s = s[near > 1e-9 * e[-1]]
    return np.unique(np.r_[s, inner])


def sample_run(model, prog, first: int, last: int, steps: np.ndarray, settings, accel_bound: float) -> RunSamples:
    """Samples of the blended run from waypoint `first` to `last` of `prog` (`sim.interpolate.Program`);
    `steps` (last - first,) the check's step count of each of its moves. `robot.ur_motion.BlendOverlap`
    when its blends overlap."""
    sl = slice(first, last + 1)
    r = np.asarray(prog.r[sl], dtype=np.float64).copy()
    r[-1] = 0.0
    P, R = prog.poses[sl, :3, 3], prog.poses[sl, :3, :3]
    linear = prog.moves[last] == "movel"
    if linear:
        geom = U.cart_run(P, R, prog.v[sl], prog.a[sl], r)
    else:
        geom = U.joint_run(prog.q[sl], P, prog.v[sl], prog.a[sl], r, accel_bound)
    cap = settings.max_steps_per_move
    s = _parameters(geom, steps, cap)
    unreachable, end_q = None, None
    if linear:
        tcp_inv = np.linalg.inv(prog.tcp)
        for attempt in range(2):
            T = U.eval_cart(geom, np.r_[s, geom.edges[-1]])
            q, bad = track_ik(model, T @ tcp_inv, prog.q[first])
            if bad is not None or attempt == 1:
                break
            worst = float(np.max(np.abs(np.diff(np.vstack([prog.q[first][None], q]), axis=0))))
            if worst <= 1.5 * settings.step_joint_rad:
                break
            # the joints move faster than the TCP here (near a singularity): refine once, bounded
            s = _parameters(geom, steps, cap, min(math.ceil(worst / settings.step_joint_rad), settings.max_refine))
        if bad is None:
            end_q, q = q[-1], q[:-1]
        else:
            q = q[:min(bad, len(s))]
            seg, frac = U.segment_position(geom, np.r_[s, geom.edges[-1]][bad:bad + 1])
            unreachable = (first + int(seg[0]) + 1, float(frac[0]))
            s = s[:len(q)]
    else:
        q = U.eval_joint(geom, s)
        end_q = prog.q[last]
    seg, frac = U.segment_position(geom, s)
    p, _ = geom.locate(s)
    corner = np.isin(s, geom.corner[1:-1])
    waypoint = first + seg + 1
    # the middle of a blend is the corner's own configuration: it belongs to that waypoint
    waypoint[corner] = first + ((p[corner] + 1) // 2)
    return RunSamples(q=q, s=s, waypoint=waypoint.astype(np.int64), corner=corner, state_seg=first + seg,
                      state_frac=frac, v=geom.v[p], end_q=end_q, unreachable_at=unreachable, geometry=geom)
