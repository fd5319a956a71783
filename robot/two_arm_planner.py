"""Programs for a cell with two arms: each arm holds a face, both fold the panel together.

With the clamped face(s) of the FOLD file fixed on the clamp, the two arms grip two middle-row faces
that move, chosen so that the holds fix the panel (`fabkit.holds.hold_analysis` in the folded and
a middle state: every part left by cutting a crease row holds a held face, no free motion): on the
tri-fold, with the clamp on one end strip, one arm on each of the other strips. Candidate pairs
come largest motion first (`robot.grip_choice.grip_order`); each face goes to the arm whose base is
nearer to it (the other way round when that does not plan).

Each arm's program is planned by the one-arm planner (`robot.planner.plan_toolpath`) in the cell
as that arm sees it (`robot.arm_cells.arm_cell`), then the two are put in lockstep:

- every move into a fold state is cut into the same number of straight pieces for both arms
  (`PlanOptions.fold_pieces`), so waypoint i is the same fractional fold state for both;
- while the arms hold the panel (the moves into `fold` and `release` waypoints) the arm with the
  longer piece keeps its speed and acceleration and the other's are scaled by the length ratio
  (length = max(TCP travel m, tool rotation rad), as `robot.ur_motion` measures a movel), with
  no blends: each piece is a trapezoid of the same duration for both arms, so in the controller's
  motion model they pass every fractional state at the same moment;
- `sync` (the grip, every fold state, the release) are the waypoints where each arm waits for the
  other (`robot.lockstep`); approach and retract run freely between sync points.

The result is a `robot.arms_toolpath.ArmsToolpath` (PATH.json `fabkit.toolpath/3`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import permutations

import numpy as np
from scipy.spatial.transform import Rotation

from fabkit.errors import InputError
from robot.arm_cells import arm_cell, arm_names
from robot.arms_toolpath import ArmsToolpath
from robot.grip_choice import grip_order
from robot.holds_record import HOLDING_OPS
from robot.planner import PlanningError, PlanOptions, plan_toolpath
from robot.toolpath import Toolpath, Waypoint

__all__ = ["ArmsPlanResult", "plan_two_arms", "hold_pairs", "lockstep_timing"]

#: Planning rounds to make both arms' fold moves the same number of pieces.
ALIGN_ROUNDS = 4


@dataclass(frozen=True, eq=False)
class ArmsPlanResult:
    """A planned two-arm program: `toolpath` (`ArmsToolpath`), `grips` {arm: face}, and what the
    planner measured (as `robot.planner.PlanResult`: `grip_face` the faces in arm order, `branch`
    per arm, the largest fold joint step, joint speed ratio, singularity factors over both arms;
    `cycle_time` the lockstep program's duration), `tried` (faces, problem) of pairs that failed,
    `refusal` the checker's problem when it refused every pair (this is the first that planned)."""

    toolpath: ArmsToolpath
    grips: dict
    grip_face: tuple
    branch: str
    max_joint_step: float
    joint_speed_ratio: float
    min_singularity: dict
    cycle_time: float
    per_arm: dict
    tried: tuple = ()
    refusal: str | None = None


def hold_pairs(fold_model, frames, clamped_faces, source: str | None = None) -> list[tuple[int, int]]:
    """Pairs of moving middle-row faces which, with the clamped faces, fix the panel in the last and
    a middle fold state, best first (largest motion first)."""
    from fabkit.hold_model_fold import hold_model_from_fold
    from fabkit.holds import hold_analysis

    model, angles = hold_model_from_fold(fold_model, source=source)
    order = [f for f in grip_order(frames) if f not in set(clamped_faces)]
    probes = [angles[-1], angles[len(angles) // 2]] if len(angles) > 2 else [angles[-1]]
    out = []
    for i, f in enumerate(order):
        for g in order[i + 1:]:
            held = tuple(clamped_faces) + (f, g)
            if all(hold_analysis(model, rho, held).ok for rho in probes):
                out.append((f, g))
    return out


def _assignments(cell, frames, pair) -> list[dict]:
    """Both ways of giving the pair's faces to the two arms, the nearer-base one first."""
    names = arm_names(cell)[:2]
    ends = {f: (cell.fixture @ frames.of_face(f)[-1])[:3, 3] for f in pair}
    bases = {n: m.base_pose[:3, 3] for n, m in cell.arms}
    ways = [dict(zip(names, p)) for p in permutations(pair)]
    return sorted(ways, key=lambda w: sum(np.linalg.norm((ends[f] - bases[n])[:2]) for n, f in w.items()))


def _pieces(tp: Toolpath) -> dict:
    """{state: number of straight pieces of the move into it} of a one-arm program."""
    out, count = {}, 0
    W = tp.waypoints
    for i in range(1, len(W)):
        if W[i].op not in HOLDING_OPS:
            continue
        count += 1
        if W[i].state != W[i - 1].state or W[i].op == "release":
            out[W[i].state] = count
            count = 0
    return out


def _length(wa: Waypoint, wb: Waypoint) -> float:
    """A movel's length as the motion model measures it: max(TCP travel m, tool rotation rad)."""
    d = float(np.linalg.norm(np.subtract(wb.pose[:3], wa.pose[:3])))
    rot = (Rotation.from_rotvec(wa.pose[3:]).inv() * Rotation.from_rotvec(wb.pose[3:])).magnitude()
    return max(d, float(rot))


def _lockstep(arms: dict) -> tuple[dict, list[int]]:
    """Per-arm toolpaths with equal-duration holding moves and no blends from the grip to the
    release; the sync waypoints."""
    names = list(arms)
    W = {n: list(arms[n].waypoints) for n in names}
    n_wp = len(W[names[0]])
    sync = []
    for i in range(1, n_wp):
        op = W[names[0]][i].op
        if op == "grip":
            sync.append(i)
        if op not in HOLDING_OPS:
            continue
        if W[names[0]][i].state != W[names[0]][i - 1].state or op == "release":
            sync.append(i)
        L = {n: _length(W[n][i - 1], W[n][i]) for n in names}
        longest = max(L.values())
        k = {n: (L[n] / longest if longest > 0 else 1.0) for n in names}
        v = min(W[n][i].v / k[n] for n in names if k[n] > 0)
        a = min(W[n][i].a / k[n] for n in names if k[n] > 0)
        for n in names:
            kk = max(k[n], 1e-6)
            W[n][i] = replace(W[n][i], v=v * kk, a=a * kk)
    for n in names:
        for i, w in enumerate(W[n]):
            if w.op == "grip" or w.op in HOLDING_OPS:
                W[n][i] = replace(W[n][i], r=0.0)
    out = {}
    for n in names:
        tp = arms[n]
        tp = Toolpath(robot=tp.robot, cell=tp.cell, tcp=tp.tcp, source=tp.source, waypoints=tuple(W[n]),
                      extra=tp.extra, cell_sha256=tp.cell_sha256)
        from robot.motion import toolpath_cycle_time

        out[n] = Toolpath(robot=tp.robot, cell=tp.cell, tcp=tp.tcp, source=tp.source, waypoints=tp.waypoints,
                          extra={**tp.extra, "cycle_time_s": toolpath_cycle_time(tp).total},
                          cell_sha256=tp.cell_sha256)
    return out, sorted(set(sync))


def lockstep_timing(atp: ArmsToolpath) -> dict:
    """The lockstep program's timing in the motion model: per segment between sync points, each
    arm's duration (moves + dwells at its end); the program's duration is the sum of the slowest."""
    from robot.motion import toolpath_cycle_time

    bounds = [0, *atp.sync, len(atp) - 1]
    per = {}
    for name, tp in atp.arms:
        ct = toolpath_cycle_time(tp)
        grip = tp.extra.get("grip") or {}
        dwell = [float(grip.get("grip_dwell_s", 0.0)) if w.op == "grip" else
                 float(grip.get("release_dwell_s", 0.0)) if w.op == "release" else 0.0 for w in tp.waypoints]
        per[name] = [float(ct.segments[a:b].sum() + dwell[b]) for a, b in zip(bounds[:-1], bounds[1:])]
    total = float(sum(max(per[n][k] for n in per) for k in range(len(bounds) - 1)))
    return {"segments": [[a, b] for a, b in zip(bounds[:-1], bounds[1:])], "arms": per, "total_s": total}


def _plan_pair(cell, frames, grips: dict, options, source, clamped_faces, placement) -> dict:
    pieces: dict = {}
    for _ in range(ALIGN_ROUNDS):
        opt = replace(options, fold_pieces=tuple(sorted(pieces.items())))
        res = {n: plan_toolpath(arm_cell(cell, n), frames.of_face(f), options=opt,
                                source={**source, "grip_face": f}, grip_face=f, clamped_faces=clamped_faces,
                                placement=placement) for n, f in grips.items()}
        counts = [_pieces(r.toolpath) for r in res.values()]
        want = {s: max(c.get(s, 1) for c in counts) for s in set().union(*counts)}
        if all(c == want for c in counts):
            return res
        pieces = want
    raise PlanningError(0, "fold", 0, "discontinuous", "the two arms' fold moves could not be cut into the same "
                        "number of pieces")


def plan_two_arms(cell, fold_model, frames, *, options: PlanOptions = PlanOptions(), source: dict | None = None,
                  clamped_faces=(), placement: dict | None = None, grip_faces=None, accept=None,
                  fold_source_name: str | None = None, footprint=None) -> ArmsPlanResult:
    """The two-arm program (module docstring) for `frames` (`fabkit.frames.FaceFrames`) of
    `fold_model` in `cell` (already placed: `robot.panel_placement`). `grip_faces` (two faces)
    fixes the pair; `accept(result) -> problem or None` (the checker) is asked for each pair that
    plans, and the first it passes wins (else the first that planned). Raises `PlanningError` when
    no pair of faces holds the panel or none plans, `InputError` when the cell has not two arms.
    `footprint(face) -> problem or None`: the pairs whose two faces carry the cup are tried first."""
    names = arm_names(cell)
    if len(names) != 2:
        raise InputError(f"a two-arm program needs a cell with two arms, {cell.name!r} has {len(names)}",
                         source=cell.source or None)
    source = dict(source or {})
    clamped = tuple(int(f) for f in clamped_faces)
    pairs = [tuple(int(f) for f in grip_faces)] if grip_faces is not None else \
        hold_pairs(fold_model, frames, clamped, source=fold_source_name)
    if footprint is not None and grip_faces is None:   # stable: pairs where both cups fit first
        pairs = sorted(pairs, key=lambda p: sum(footprint(f) is not None for f in p))
    if not pairs:
        raise PlanningError(0, "grip", 0, "holds", f"no two middle-row faces hold the panel with the clamped faces "
                            f"{list(clamped)} (every crease must be folded by something held)")
    tried, refused, refusal, errors = [], None, None, []
    for pair in pairs:
        for grips in _assignments(cell, frames, pair):
            try:
                res = _plan_pair(cell, frames, grips, options, source, clamped, placement)
            except PlanningError as exc:
                errors.append(exc)
                tried.append((tuple(grips.values()), str(exc)))
                continue
            out = _result(cell, res, grips, source, clamped, placement, tuple(tried))
            problem = accept(out) if accept is not None and grip_faces is None else None
            if problem is None:
                return out
            tried.append((tuple(grips.values()), problem))
            if refused is None:
                refused, refusal = out, problem
            break
    if refused is not None:
        return replace(refused, tried=tuple(tried), refusal=refusal)
    first = max(errors, key=lambda e: e.waypoint)
    raise PlanningError(first.waypoint, first.op, first.state, first.kind,
                        f"{first.detail} (no pair of faces plans for both arms: tried {[p for p, _ in tried]})")


def _result(cell, res: dict, grips: dict, source, clamped, placement, tried) -> ArmsPlanResult:
    arms, sync = _lockstep({n: r.toolpath for n, r in res.items()})
    holds = {"clamped_faces": sorted(set(clamped)),
             "arms": {n: [grips[n] if w.op in HOLDING_OPS else None for w in arms[n].waypoints] for n in arms}}
    first = next(iter(arms.values()))
    shared = {"units": first.extra["units"], "holds": holds,
              "lockstep": {"rule": "every arm reaches each sync waypoint before any arm moves on; holding moves "
                                   "take the same time for every arm (speeds scaled by length, no blends)"},
              **({"placement": placement} if placement is not None else {})}
    src = {**source, "grip_faces": {n: int(f) for n, f in grips.items()}}
    atp = ArmsToolpath.build(cell.name, cell.sha256, src, [(n, arms[n]) for n in arms], sync, shared)
    timing = lockstep_timing(atp)
    checks = {"max_fold_joint_step_rad": max(r.max_joint_step for r in res.values()),
              "joint_speed_ratio": max(r.joint_speed_ratio for r in res.values()),
              "branch": {n: r.branch for n, r in res.items()}}
    atp = ArmsToolpath.build(cell.name, cell.sha256, src, [(n, arms[n]) for n in arms], sync,
                             {**shared, "cycle_time_s": timing["total_s"], "checks": checks})
    sing = {k: min(r.min_singularity[k] for r in res.values()) for k in next(iter(res.values())).min_singularity}
    return ArmsPlanResult(toolpath=atp, grips=dict(grips), grip_face=tuple(grips.values()),
                          branch=", ".join(f"{n}: {r.branch}" for n, r in res.items()),
                          max_joint_step=checks["max_fold_joint_step_rad"],
                          joint_speed_ratio=checks["joint_speed_ratio"], min_singularity=sing,
                          cycle_time=timing["total_s"], per_arm=res, tried=tried)
