"""The toolpath planner: fold states -> TCP poses -> joint solutions with one branch -> `Toolpath`.

The operations for one panel (design.md): `home` (movej to the cell's home joints), `approach`
(movej to a pose `approach_distance` in front of the grip face), `grip` (movel onto the face; the
gripper output switches on after arriving), `fold` (movel through the grip face's frame in every
fold state; subdivided so that no joint moves more than `max_joint_step` between waypoints),
`release` (the last fold state; the gripper switches off after arriving), `retract` (movel back
along the approach axis) and `home` again.

TCP pose = base^-1 . fixture . face frame(state) . grip offset, where the grip offset turns the
tool about the face's x axis by pi (the tool's z points into the face, so it approaches from the
front side) and backs off along the approach by the standoff.

Branch selection is ours: every IK solution of the approach pose starts a candidate branch
(shoulder/elbow/wrist signature); the branch is propagated through all linear moves by the
wrap-aware nearest solution *of the same branch*, and each linear segment is also checked at
intermediate poses (what the controller's straight-line interpolation will ask for). A configuration
change, a jump, an unreachable pose or a singularity inside a linear move is a `PlanningError`
naming the waypoint. Of the branches that work, the one with the least joint travel wins.

The file format (PATH.json) is `robot.toolpath`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from fabkit.errors import FabkitError, InputError
from robot import kinematics as K
from robot.cell import Cell, matrix_to_pose, pose_to_matrix
from robot.motion import (MotionParams, blend_overlaps, blend_radii, cycle_time, joint_speed_estimates,
                          limited_params)
from robot.blends import cap_blend_radii
from robot.branch_bounds import IKMemo, reach_bound, travel_bound
from robot.grip_choice import approach_variants, grip_order
from robot.holds_record import holds_record
from robot.toolpath import Toolpath, Waypoint

__all__ = ["PlanOptions", "PlanningError", "PlanResult", "grip_offset", "tcp_targets", "plan_toolpath",
           "grip_order", "approach_variants", "check_toolpath_kinematics"]


class PlanningError(FabkitError):
    """A toolpath that cannot be executed: names the waypoint (index, op, fold state) and the reason."""

    def __init__(self, waypoint: int, op: str, state: int, kind: str, detail: str):
        self.waypoint, self.op, self.state, self.kind, self.detail = waypoint, op, state, kind, detail
        super().__init__(f"waypoint {waypoint} ({op}, fold state {state}): {kind}: {detail}")

    def as_problem(self) -> dict:
        return {"waypoint": self.waypoint, "op": self.op, "state": self.state, "kind": self.kind,
                "detail": self.detail}


@dataclass(frozen=True)
class PlanOptions:
    """Planner settings (lengths m, angles rad).

    approach_distance: how far in front of the face the approach/retract poses are;
    grip_standoff: TCP distance from the face centroid when gripping (along the face normal);
    tool_yaw: turn of the tool about its z axis (rad); None = automatic for tools whose TCP lies on
    the flange axis (a suction cup or any tool symmetric about its axis): the yaw that keeps wrist 3
    at its home angle at the approach pose; max_joint_step: largest joint change between
    consecutive waypoints of a linear move (subdivide otherwise); check_substeps: intermediate poses
    checked on every linear segment; singular_*: refuse waypoints closer than this to a singularity
    (|sin q3|, |sin q5|, shoulder term in m); params: speeds and blends; fold_pieces: at least this
    many straight pieces for the move into a fold state (arms that fold together move in as many);
    grip_side: which side of the sheet the cup grips, "front" (the side the face normals point to;
    the tool approaches along -normal) or "back" (the tool approaches along +normal;
    `grip_standoff` is then measured behind the design surface).
    """

    approach_distance: float = 0.08
    grip_standoff: float = 0.0
    tool_yaw: float | None = None
    max_joint_step: float = math.radians(5.0)
    check_substeps: int = 4
    max_subdivisions: int = 256
    singular_elbow: float = K.SINGULARITY_LIMITS.elbow  # the checker's limits: planned paths pass the check
    singular_wrist: float = K.SINGULARITY_LIMITS.wrist
    singular_shoulder: float = K.SINGULARITY_LIMITS.shoulder_m
    params: MotionParams = MotionParams()
    fold_pieces: tuple = ()  # ((state, n), ...): the move into fold state `state` in at least n pieces
    grip_side: str = "front"


#: Face frame -> the same frame seen from the back side (x kept, y and z reversed).
BACK_SIDE = np.diag([1.0, -1.0, -1.0, 1.0])


def grip_offset(standoff: float = 0.0, tool_yaw: float = 0.0) -> np.ndarray:
    """Face frame -> TCP: turn pi about the face x axis (tool z into the face), yaw, back off `standoff`."""
    G = np.eye(4)
    G[:3, :3] = Rotation.from_euler("XZ", [np.pi, tool_yaw]).as_matrix()  # Rx(pi) @ Rz(yaw)
    back = np.eye(4)
    back[2, 3] = -float(standoff)
    return G @ back


def tcp_targets(cell: Cell, face_frames: np.ndarray, options: PlanOptions = PlanOptions()) -> dict:
    """TCP poses in the robot base frame for one grip face's frames `(S, 4, 4)` (panel frame):
    `grip` (S, 4, 4) per fold state, `approach` and `retract` (4, 4)."""
    F = np.asarray(face_frames, dtype=np.float64)
    if options.grip_side not in ("front", "back"):
        raise InputError(f"grip side must be front or back, got {options.grip_side!r}", source="grip_side")
    if options.grip_side == "back":  # the cup on the back: grip the frame turned over
        F = F @ BACK_SIDE
    M = cell.panel_to_base
    yaw = options.tool_yaw or 0.0
    G = grip_offset(options.grip_standoff, yaw)
    back = grip_offset(options.grip_standoff + options.approach_distance, yaw)
    return {"grip": M @ F @ G, "approach": M @ F[0] @ back, "retract": M @ F[-1] @ back}


@dataclass
class _Target:
    T: np.ndarray          # TCP pose in base frame (4, 4)
    move: str
    op: str
    state: int
    q: np.ndarray | None = None


def _interp(Ta: np.ndarray, Tb: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """Poses along the straight TCP line from Ta to Tb (position lerp, orientation slerp): (k, 4, 4)."""
    rots = Rotation.from_matrix(np.stack([Ta[:3, :3], Tb[:3, :3]]))
    R = Slerp([0.0, 1.0], rots)(ts).as_matrix()
    out = np.zeros((len(ts), 4, 4))
    out[:, :3, :3] = R
    out[:, :3, 3] = Ta[:3, 3] + np.outer(ts, Tb[:3, 3] - Ta[:3, 3])
    out[:, 3, 3] = 1.0
    return out


def _tool_is_axial(tcp: np.ndarray) -> bool:
    """True if the TCP lies on the flange z axis with its z along it (yaw about it = wrist 3 alone)."""
    return bool(np.hypot(tcp[0, 3], tcp[1, 3]) < 1e-12 and abs(tcp[2, 2] - 1.0) < 1e-12)


def _singular_problem(model, q, opt: PlanOptions) -> str | None:
    f = K.singularity_factors(model, q)
    if abs(f.wrist) < opt.singular_wrist:
        return f"wrist singularity (sin q5 = {float(f.wrist):.3g})"
    if abs(f.elbow) < opt.singular_elbow:
        return f"elbow singularity (sin q3 = {float(f.elbow):.3g}, arm stretched or folded)"
    if abs(f.shoulder) < opt.singular_shoulder:
        return f"shoulder singularity (wrist centre {float(f.shoulder):.3g} m from the base axis)"
    return None


class _Fail(Exception):
    def __init__(self, index: int, kind: str, detail: str):
        self.index, self.kind, self.detail = index, kind, detail


def _propagate(model, tcp, chain: list[_Target], q0: np.ndarray, branch, opt: PlanOptions,
               solve=None) -> list[_Target]:
    """Joint solutions along a chain of linear moves on one branch (raises _Fail).

    Fold moves are subdivided (straight TCP lines between fold states) until no joint changes by
    more than `max_joint_step` between waypoints; every linear segment is then checked at
    intermediate poses for reach, branch and joint swings. `solve(T)`: the IK of a TCP pose
    (`robot.branch_bounds.IKMemo`; default `K.ik` with `tcp`).
    """
    solve = solve or IKMemo(model, tcp)
    out = [replace(chain[0], q=q0)]
    for i in range(1, len(chain)):
        prev, tgt = out[-1], chain[i]
        subdivide = tgt.op in ("fold", "release")
        pieces, last_worst = (dict(opt.fold_pieces).get(tgt.state, 1) if subdivide else 1), np.inf
        while True:
            ts = np.arange(1, pieces + 1) / pieces
            poses = _interp(prev.T, tgt.T, ts) if pieces > 1 else tgt.T[None]
            qs, q_ref, worst = [], prev.q, 0.0
            for T in poses:
                q = _solve_on_branch(model, solve, T, q_ref, branch, index=i)
                why = _singular_problem(model, q, opt)
                if why:
                    raise _Fail(i, "singular", why)
                worst = max(worst, float(np.max(np.abs(q - q_ref))))
                qs.append(q)
                q_ref = q
            if not subdivide or worst <= opt.max_joint_step:
                break
            if pieces > 1 and worst > 0.75 * last_worst:  # halving the pieces did not shrink the jump
                raise _Fail(i, "discontinuous", f"joints jump by {math.degrees(worst):.3g} deg however finely the "
                            "move is divided (a flip near a singularity or a joint limit)")
            pieces = max(2 * pieces, int(np.ceil(worst / opt.max_joint_step * 1.2)) * pieces)
            last_worst = worst
            if pieces > opt.max_subdivisions:
                raise _Fail(i, "discontinuous", f"joints jump by more than {math.degrees(opt.max_joint_step):.3g} deg "
                            f"even with {opt.max_subdivisions} subdivisions (near a singularity or a joint limit)")
        for k, (T, q) in enumerate(zip(poses, qs)):
            last = k == len(qs) - 1
            # intermediate fold points belong to the state being left
            out.append(_Target(T=T, move=tgt.move, op=tgt.op if last else "fold",
                               state=tgt.state if last else prev.state, q=q))
    # the straight lines between consecutive waypoints (what movel interpolates)
    for i in range(1, len(out)):
        a, b = out[i - 1], out[i]
        if b.move != "movel":
            continue
        n_sub = max(opt.check_substeps, 2 * int(np.ceil(np.max(np.abs(b.q - a.q)) / opt.max_joint_step)))
        ts = np.arange(1, n_sub + 1) / (n_sub + 1)
        q_ref = a.q
        for T in _interp(a.T, b.T, ts):
            q = _solve_on_branch(model, solve, T, q_ref, branch, index=i, between=True)
            if np.max(np.abs(q - q_ref)) > opt.max_joint_step:
                raise _Fail(i, "discontinuous", "joints swing on the straight line from the previous waypoint")
            q_ref = q
        if np.max(np.abs(b.q - q_ref)) > opt.max_joint_step:
            raise _Fail(i, "discontinuous", "joints swing on the straight line from the previous waypoint")
    return out


def _solve_on_branch(model, solve, T, q_ref, branch, index: int, between: bool = False) -> np.ndarray:
    S = solve(T)
    where = "on the line to this waypoint" if between else "pose"
    if len(S) == 0:
        raise _Fail(index, "unreachable", f"no joint solution reaches the TCP {where} "
                    f"{np.round(matrix_to_pose(T), 4).tolist()}")
    try:
        return K.select_nearest(S, q_ref, model=model, branch=branch)
    except LookupError:
        raise _Fail(index, "configuration_change",
                    f"the {K.branch_text(branch)} configuration cannot reach the TCP {where}; "
                    "following it needs a configuration change inside a linear move") from None


@dataclass(frozen=True, eq=False)
class PlanResult:
    """A planned toolpath plus what the planner measured (for reports)."""

    toolpath: Toolpath
    grip_face: int
    branch: str
    max_joint_step: float          # rad, largest joint change between consecutive waypoints of fold moves
    joint_speed_ratio: float       # largest estimated joint speed / cell limit
    min_singularity: dict          # smallest |factor| over the waypoints
    cycle_time: float              # s
    tried: tuple = ()              # (face, problem) of grip faces that did not work
    refusal: str | None = None     # the checker refused every candidate: this one's problem (None: passed or unchecked)


def plan_toolpath(cell: Cell, face_frames: np.ndarray, *, options: PlanOptions = PlanOptions(),
                  source: dict | None = None, grip_face: int = -1, clamped_faces=(),
                  placement: dict | None = None) -> PlanResult:
    """Plan the operations for one grip face's frames `(S, 4, 4)` (panel frame) in `cell`;
    `clamped_faces` (polygon ids) are recorded with the grip face in PATH.json's `holds`;
    `placement` (`robot.panel_placement`, already applied to `cell`) is recorded as it is.

    Raises `PlanningError` naming the first waypoint that no branch can execute.
    """
    model, tcp = cell.model, cell.tool.tcp
    F = np.asarray(face_frames, dtype=np.float64)
    if F.ndim != 3 or F.shape[1:] != (4, 4) or not np.all(np.isfinite(F)):
        raise InputError(f"face frames must be a finite (S, 4, 4) array, got shape {F.shape}")
    S = F.shape[0]
    if S < 2:
        raise InputError(f"a fold needs at least 2 fold states (flat and folded), got {S}")
    q_home = np.asarray(cell.robot.home, dtype=np.float64)
    T_home = K.fk_tcp(model, q_home, tcp)
    auto_yaw = options.tool_yaw is None and _tool_is_axial(tcp)
    home_branch = K.branch_signs(model, q_home)

    def chain_for(opt: PlanOptions) -> list[_Target]:
        tg = tcp_targets(cell, F, opt)
        chain = [_Target(tg["approach"], "movej", "approach", 0), _Target(tg["grip"][0], "movel", "grip", 0)]
        for s in range(1, S):
            chain.append(_Target(tg["grip"][s], "movel", "release" if s == S - 1 else "fold", s))
        chain.append(_Target(tg["retract"], "movel", "retract", S - 1))
        return chain

    base_opt = replace(options, tool_yaw=options.tool_yaw or 0.0)
    base_chain = chain_for(base_opt)
    starts = K.ik(model, base_chain[0].T, tcp)
    if len(starts) == 0:
        raise PlanningError(1, "approach", 0, "unreachable", "no joint solution reaches the approach pose "
                            f"{np.round(matrix_to_pose(base_chain[0].T), 4).tolist()}")
    solve = IKMemo(model, tcp)
    runs = []  # (start, opt, chain, q0, branch, reach bound) per IK solution of the approach pose
    for k, q_start in enumerate(starts):
        opt, chain, q0 = base_opt, base_chain, K.unwrap_near(q_start, q_home, model)
        if auto_yaw:  # turning the tool about its axis moves wrist 3 alone: bring it to its home angle
            delta = float(K.wrap_angle(np.array(q_home[5] - q0[5])))
            opt = replace(base_opt, tool_yaw=base_opt.tool_yaw + delta)
            chain = chain_for(opt)
            q0 = q0.copy()
            q0[5] += delta
        branch = K.branch_signs(model, q0)
        runs.append((k, opt, chain, q0, branch, reach_bound(model, chain, branch, opt, solve)))
    # Only branches whose every target pose is reachable on them can plan; the others are
    # propagated only when one of them may be the failure that got farthest (the explanation).
    # Of those, the least cost wins (the first of equals in the order of the starts): they are tried
    # from the least lower bound of their cost up, and one whose bound exceeds the best cost found
    # cannot win.
    reachable = [(travel_bound(model, chain, q0, q_home, branch, solve) + np.pi * np.sum(branch != home_branch),
                  k, opt, chain, q0, branch) for k, opt, chain, q0, branch, bound in runs if bound == len(chain)]
    best, best_cost, best_k, fails = None, np.inf, -1, {}
    for low, k, opt, chain, q0, branch in sorted(reachable, key=lambda r: (r[0], r[1])):
        if low > best_cost + 1e-9 * (1.0 + best_cost):  # the margin covers the bound's rounding
            continue
        try:
            path = _propagate(model, tcp, chain, q0, branch, opt, solve)
        except _Fail as f:
            fails[k] = (f, chain)
            continue
        Q = np.array([t.q for t in path])
        # least joint travel; a branch other than the home configuration's costs pi per changed sign
        cost = (np.abs(Q[0] - q_home).sum() + np.abs(np.diff(Q, axis=0)).sum()
                + np.pi * np.sum(branch != home_branch))
        if cost < best_cost or (cost == best_cost and k < best_k):
            best, best_cost, best_k = path, cost, k
    if best is None:
        # the branch that got farthest explains best (the first of equals, in the order of the starts):
        # a branch whose reach bound is short of the farthest failure known cannot be it
        for k, opt, chain, q0, branch, bound in sorted((r for r in runs if r[5] < len(r[2])),
                                                       key=lambda r: (-r[5], r[0])):
            top = max(fails.items(), key=lambda kv: (kv[1][0].index, -kv[0]), default=None)
            if top is not None and (bound, -k) < (top[1][0].index, -top[0]):
                continue
            try:
                _propagate(model, tcp, chain, q0, branch, opt, solve)
            except _Fail as f:
                fails[k] = (f, chain)
                continue
            raise RuntimeError("planner bug: a branch with an unreachable target pose propagated")
        f, chain = max(fails.items(), key=lambda kv: (kv[1][0].index, -kv[0]))[1]
        t = chain[min(f.index, len(chain) - 1)]
        raise PlanningError(f.index + 1, t.op, t.state, f.kind, f.detail)

    home_t = _Target(T_home, "movej", "home", 0, q_home)
    end_t = _Target(T_home, "movej", "home", S - 1, q_home)
    targets = [home_t] + best + [end_t]
    return _finish(cell, targets, options, source or {}, grip_face, clamped_faces, placement)


def _finish(cell: Cell, targets: list[_Target], opt: PlanOptions, source: dict, grip_face: int,
            clamped_faces=(), placement: dict | None = None) -> PlanResult:
    """Speeds, blends, timing and joint-speed limits for the waypoint list; builds the Toolpath."""
    p = limited_params(opt.params, cell.limits)
    n = len(targets)
    moves = np.array([t.move for t in targets])
    ops = [t.op for t in targets]
    P = np.array([t.T[:3, 3] for t in targets])
    R = np.array([t.T[:3, :3] for t in targets])
    Q = np.array([t.q for t in targets])
    speed_of = {"approach": p.approach_speed, "grip": p.approach_speed, "fold": p.fold_speed,
                "release": p.fold_speed, "retract": p.retract_speed}
    v = np.array([p.joint_speed if m == "movej" else speed_of[o] for m, o in zip(moves, ops)])
    a = np.array([p.joint_accel if m == "movej" else p.tcp_accel for m in moves])
    # stops: every movej, grip/release/retract, a change of move kind, and the last waypoint
    stops = np.array([m == "movej" or o in ("grip", "release", "retract", "home") for m, o in zip(moves, ops)])
    stops[:-1] |= moves[1:] != moves[:-1]
    r = cap_blend_radii(P, blend_radii(P, stops, p.blend_max))  # neighbours <= 90 % of their segment
    dwell = np.array([p.grip_dwell if o == "grip" else p.release_dwell if o == "release" else 0.0 for o in ops])
    limit = np.asarray(cell.limits.joint_speed)
    # lower movel speeds where the joints would exceed their limits (near singularities)
    for _ in range(4):
        ct = cycle_time(moves, P, R, Q, v, a, r, dwell)
        qd = joint_speed_estimates(Q, ct.segments)
        ratio = (qd / limit).max(axis=1)
        over = np.flatnonzero((ratio > 0.95) & (moves[1:] == "movel"))
        if len(over) == 0:
            break
        v[over + 1] = v[over + 1] * 0.9 / ratio[over]
    ct = cycle_time(moves, P, R, Q, v, a, r, dwell)
    qd = joint_speed_estimates(Q, ct.segments)
    ratio = float((qd / limit).max()) if len(qd) else 0.0
    lin = moves == "movel"
    steps = np.abs(np.diff(Q, axis=0))[lin[1:] & lin[:-1]]
    max_step = float(steps.max()) if len(steps) else 0.0
    fold_pairs = np.array([o in ("fold", "release") for o in ops[1:]], dtype=bool)
    fold_steps = np.abs(np.diff(Q, axis=0))[fold_pairs]
    max_fold_step = float(fold_steps.max()) if len(fold_steps) else 0.0
    f = K.singularity_factors(cell.model, Q[1:-1] if n > 2 else Q)
    min_sing = {"elbow": float(np.abs(f.elbow).min()), "wrist": float(np.abs(f.wrist).min()),
                "shoulder_m": float(np.abs(f.shoulder).min())}
    overlaps = blend_overlaps(P, r)
    if len(overlaps):  # blend_radii rules this out: reaching here is a bug, never a path to send
        raise RuntimeError(f"planner bug: blend radii overlap at waypoints {overlaps.tolist()}")
    waypoints = [Waypoint(pose=matrix_to_pose(t.T), q=t.q, move=t.move, v=v[i], a=a[i], r=r[i], state=t.state,
                          op=t.op) for i, t in enumerate(targets)]
    branch = K.branch_label(cell.model, Q[1]) if n > 1 else K.branch_label(cell.model, Q[0])
    extra = {
        "units": {"length": "m", "angle": "rad", "time": "s", "pose": "TCP in the robot base frame, rotation vector",
                  "movel": "v m/s, a m/s^2", "movej": "v rad/s, a rad/s^2", "r": "m"},
        "grip": {"output": cell.tool.grip_output, "kind": cell.tool.grip_output_kind,
                 "grip_dwell_s": p.grip_dwell, "release_dwell_s": p.release_dwell, "face": int(grip_face),
                 **({"side": opt.grip_side} if opt.grip_side != "front" else {})},  # absent: the front
        "cycle_time_s": ct.total,
        "holds": holds_record(ops, grip_face, clamped_faces),
        **({"placement": placement} if placement is not None else {}),
        "checks": {"branch": branch, "max_joint_step_rad": max_step, "max_fold_joint_step_rad": max_fold_step,
                   "joint_speed_ratio": ratio,
                   "min_singularity": min_sing, "fk_tolerance_m": K.IK_TOL_POS},
    }
    tp = Toolpath(robot=cell.model.name, cell=cell.name, tcp=tuple(matrix_to_pose(cell.tool.tcp)),
                  source=source, waypoints=tuple(waypoints), extra=extra, cell_sha256=cell.sha256)
    return PlanResult(toolpath=tp, grip_face=int(grip_face), branch=branch, max_joint_step=max_fold_step,
                      joint_speed_ratio=ratio, min_singularity=min_sing, cycle_time=ct.total)


def check_toolpath_kinematics(tp: Toolpath, tcp=None) -> dict:
    """Re-check a toolpath: FK of every `q` against its pose, joint steps inside linear moves, and
    blend overlaps. Returns {"fk_pos_max", "fk_rot_max", "max_linear_joint_step", "blend_overlaps"}."""
    model = K.get_model(tp.robot)
    tcp = pose_to_matrix(tp.tcp) if tcp is None else tcp
    Q = tp.joints
    T = np.array([pose_to_matrix(p) for p in tp.poses])
    dp, dr = K.pose_error(K.fk_tcp(model, Q, tcp), T)
    moves = np.array([w.move for w in tp.waypoints])
    lin = (moves[1:] == "movel") & (moves[:-1] == "movel")
    steps = np.abs(np.diff(Q, axis=0))[lin]
    r = np.array([w.r for w in tp.waypoints])
    return {"fk_pos_max": float(dp.max()), "fk_rot_max": float(dr.max()),
            "max_linear_joint_step": float(steps.max()) if len(steps) else 0.0,
            "blend_overlaps": blend_overlaps(T[:, :3, 3], r).tolist()}
