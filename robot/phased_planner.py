"""One-arm programs in phases: grip, fold some states, release, regrip (another face or side), fold on.

A phased program is one toolpath whose waypoints run phase after phase. Each phase is a complete
one-arm program over a span of the FOLD file's fold states (`robot.planner.plan_toolpath` on that
span of its grip face's frames): approach, grip, fold through the span, release, retract. Between
phases the arm transfers by a joint move through the cell's home configuration (the one pose the
planner knows to be clear of the panel and the fixture, `movej`), and the next phase starts with
its own approach. Consecutive phases share a fold state (the last of one is the first of the
next), so the panel does not move while the arm is off it: between release and regrip the creases
keep the angles they have (a rigid panel, or aluminium that keeps its fold; springback between the
release and the regrip is not modelled, so a sheet program is not planned in phases).

PATH.json records the phases in `phases` (inside the whole-document hash): per phase its grip
`face`, `side` ("front" | "back"), fold `states` [first, last] and `waypoints` [first, last]
(approach .. retract). The `holds` record names the phase's grip face on every move that carries the
panel. A program of one phase has no `phases` key: it is exactly the program `plan_toolpath`
plans.

The same-crease regrip (`robot.regrip_choice`): a fold that no single grip reaches (a 175 deg
valley closes the wing over a cup on the front; the back of the flat panel faces the bench) is
folded on the front side to an inner state, released, and finished on the back side. Which face,
split state and approach distance is chosen there, by a score (fewer phases, cycle time, least
clearance) among the alternatives that pass the check.

The crease-by-crease regrip (`step_phases`): a FOLD file whose states fold the crease rows one step
after another (`fabkit refold --steps`, `frame_fabkit:step`) is planned one phase per step, each
gripping the middle-row face that the step moves farthest (the strip beyond the crease it folds).
What holds the strips the step does not fold (a strip still flat, a strip folded in an earlier
step) is not assumed: a folded crease does not stay folded because it was folded, and a wing lying
still is not held by its weight. The cell's jigs hold them where a face lies on a jig
(`robot.jig_holds`), and the check proves the holds in every state; without them the check refuses
the program naming the free crease.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fabkit.errors import InputError
from robot.holds_record import HOLDING_OPS
from robot.transfer import TRANSFER_LIFTS, TransferError, lifted_waypoint

__all__ = ["PhaseSpec", "plan_phases", "phases_of", "step_phases", "with_regrip"]


@dataclass(frozen=True)
class PhaseSpec:
    """One phase to plan: grip `face` (polygon id) on `side` ("front" | "back") through fold states
    `first`..`last` (indices of the FOLD file's states, `first` < `last`)."""

    face: int
    side: str
    first: int
    last: int

    def to_json(self) -> dict:
        return {"face": int(self.face), "side": self.side, "states": [int(self.first), int(self.last)]}


def _check_specs(specs, n_states: int) -> None:
    if not specs:
        raise InputError("a phased program needs at least one phase")
    for k, p in enumerate(specs):
        if p.side not in ("front", "back"):
            raise InputError(f"phase {k}: grip side must be front or back, got {p.side!r}")
        if not 0 <= p.first < p.last <= n_states - 1:
            raise InputError(f"phase {k}: fold states {p.first}..{p.last} are not a span of states 0..{n_states - 1}")
        if k and p.first != specs[k - 1].last:
            raise InputError(f"phase {k} starts at fold state {p.first}, the phase before ends at {specs[k - 1].last}")
    if specs[0].first != 0 or specs[-1].last != n_states - 1:
        raise InputError(f"the phases must run from fold state 0 to {n_states - 1}")


def plan_phases(cell, frames, specs, *, options, source: dict | None = None, clamped_faces=(),
                placement: dict | None = None, standoffs: dict | None = None, lifts=TRANSFER_LIFTS,
                via_home: bool = True):
    """Plan the phases `specs` (`PhaseSpec`, covering the states in order) for the middle-row frames
    `frames` (`fabkit.frames.FaceFrames`) in `cell` -> `robot.planner.PlanResult` of the whole
    program (module docstring). `options`: the planner's `PlanOptions` (its `grip_side` is each
    phase's); `standoffs`: {side: grip standoff} (default `options.grip_standoff`); `lifts`: the
    transfer's lifts over the retract and over the next approach, each the first its branch reaches
    (none: that leg goes straight; `robot.transfer`);
    `via_home`: the transfer passes through the home configuration. Raises
    `robot.planner.PlanningError` for the first phase that does not plan (its waypoint numbered
    from the phase's start in the whole program, before the transfers)."""
    from robot.motion import toolpath_cycle_time
    from robot.planner import PlanningError, PlanResult, plan_toolpath
    from robot.toolpath import Toolpath

    specs = tuple(specs)
    _check_specs(specs, frames.n_states)
    parts, offset = [], 0
    for k, p in enumerate(specs):
        opt = replace(options, grip_side=p.side,
                      grip_standoff=(standoffs or {}).get(p.side, options.grip_standoff))
        try:
            res = plan_toolpath(cell, frames.of_face(p.face)[p.first:p.last + 1], options=opt, grip_face=p.face,
                                clamped_faces=clamped_faces, placement=placement, source=source)
        except PlanningError as exc:
            raise PlanningError(exc.waypoint + offset, exc.op, exc.state + p.first, exc.kind,
                                f"phase {k} ({p.side} side, face {p.face}): {exc.detail}") from None
        parts.append(res)
        offset += len(res.toolpath.waypoints) - (1 if k + 1 < len(specs) else 0)
    if len(parts) == 1:
        return parts[0]
    waypoints, rows, phases = [], [], []
    for k, (p, res) in enumerate(zip(specs, parts)):
        shifted = [replace(w, state=w.state + p.first) for w in res.toolpath.waypoints]
        if k:   # the transfer: lift off the retract, home, over the next approach (robot.transfer)
            home = shifted[0]
            off = _first_lift(cell, waypoints[-2], lifts, home)      # over the retract
            on = _first_lift(cell, shifted[1], lifts, home)          # over the next approach
            up = [*off, *([replace(home, state=waypoints[-1].state)] if via_home else []), *on]
            waypoints.pop()         # the phase before's home, now between the two lifts
            rows.pop()
            shifted = up + shifted[1:]
        start = len(waypoints)
        waypoints += shifted
        ops = [w.op for w in shifted]
        rows += [int(p.face) if op in HOLDING_OPS else None for op in ops]
        first = start + ops.index("approach")
        last = start + len(ops) - 1 - ops[::-1].index("retract")
        phases.append({**p.to_json(), "waypoints": [first, last]})
    head = parts[0].toolpath
    extra = dict(head.extra)
    extra["holds"] = {**head.extra["holds"], "arms": {"a": rows}}
    extra["phases"] = phases
    checks = [r.toolpath.extra["checks"] for r in parts]
    extra["checks"] = {**checks[0],
                       **{k: max(c[k] for c in checks) for k in ("max_joint_step_rad", "max_fold_joint_step_rad",
                                                                  "joint_speed_ratio")},
                       "min_singularity": {k: min(c["min_singularity"][k] for c in checks)
                                           for k in checks[0]["min_singularity"]}}
    tp = Toolpath(robot=head.robot, cell=head.cell, tcp=head.tcp, source=head.source, waypoints=tuple(waypoints),
                  extra=extra, cell_sha256=head.cell_sha256)
    total = toolpath_cycle_time(tp).total
    tp = Toolpath(robot=head.robot, cell=head.cell, tcp=head.tcp, source=head.source, waypoints=tuple(waypoints),
                  extra={**extra, "cycle_time_s": total}, cell_sha256=head.cell_sha256)
    return PlanResult(toolpath=tp, grip_face=int(specs[0].face), branch=parts[0].branch,
                      max_joint_step=max(r.max_joint_step for r in parts),
                      joint_speed_ratio=max(r.joint_speed_ratio for r in parts),
                      min_singularity=extra["checks"]["min_singularity"], cycle_time=total)


def _first_lift(cell, wp, lifts, home) -> list:
    """[the waypoint lifted over `wp` by the first of `lifts` its branch reaches], or [] (the transfer
    leg goes straight to `wp`)."""
    for h in lifts:
        try:
            return [lifted_waypoint(cell, wp, h, v=home.v, a=home.a)]
        except TransferError:
            continue
    return []


def phases_of(tp) -> list[dict] | None:
    """The validated `phases` record of a toolpath (None for a program of one phase); `ValueError`
    naming the key for a malformed one."""
    ph = tp.extra.get("phases") if isinstance(tp.extra, dict) else None
    if ph is None:
        return None
    n = len(tp.waypoints)

    def pair(v, top):
        return (isinstance(v, list) and len(v) == 2 and all(isinstance(x, int) and not isinstance(x, bool)
                                                            for x in v) and 0 <= v[0] <= v[1] <= top)

    if not isinstance(ph, list) or len(ph) < 2:
        raise ValueError("phases: expected a list of two or more phases")
    for k, p in enumerate(ph):
        if not (isinstance(p, dict) and isinstance(p.get("face"), int) and p.get("side") in ("front", "back")
                and pair(p.get("states"), 10**6) and pair(p.get("waypoints"), n - 1)):
            raise ValueError(f"phases[{k}]: expected {{face, side: front|back, states: [first, last], "
                             "waypoints: [first, last]}")
        if k and p["waypoints"][0] <= ph[k - 1]["waypoints"][1]:
            raise ValueError(f"phases[{k}]: its waypoints overlap the phase before")
    return ph


def step_phases(fold_model, frames) -> list[PhaseSpec] | None:
    """The phases of a FOLD file folded step by step (module docstring): one front-side `PhaseSpec`
    per step over the state before its first and its states, gripping the middle-row face of
    `frames` (`fabkit.frames.FaceFrames`) whose centroid travels farthest during the step (ties by
    its final centroid's coordinates, never by face order). None for a file of one step (or none)."""
    steps = [f.data.get("fabkit:step") for f in fold_model.frames]
    if len(steps) + 1 == frames.n_states:       # a flat key frame put first (fabkit.frames.fold_positions)
        steps = [-1] + steps
    if len(steps) != frames.n_states or not all(isinstance(k, int) and not isinstance(k, bool) for k in steps):
        return None
    labels = sorted({k for k in steps if k >= 0})
    if len(labels) < 2:
        return None
    specs = []
    for k in labels:
        idx = [i for i, v in enumerate(steps) if v == k]
        first, last = max(idx[0] - 1, 0), idx[-1]
        if idx != list(range(idx[0], last + 1)) or (specs and first != specs[-1].last):
            return None                          # steps not folded one after another
        best = None
        for f in frames.faces:
            c = frames.of_face(int(f))[first:last + 1, :3, 3]
            key = (-round(float(np.linalg.norm(c - c[:1], axis=1).max()), 9), *np.round(c[-1], 9).tolist())
            if best is None or key < best[0]:
                best = (key, int(f))
        specs.append(PhaseSpec(best[1], "front", first, last))
    if specs[0].first != 0 or specs[-1].last != frames.n_states - 1:
        return None
    return specs


def with_regrip(cell, frames, fold_model, *, options, source: dict | None = None, clamped_faces=(), placement: dict | None = None,
                accept, variants=(), footprint=None):
    """`robot.grip_choice.plan_panel` with the checker `accept`, and when no single grip passes
    (none plans, or the checker refuses every one) the regrip programs compared by
    `robot.regrip_choice.pick_alternative`: a regrip per fold step when the FOLD file `fold_model`
    folds step by step (`step_phases`), and the same-crease regrips
    (`robot.regrip_choice.same_crease_alternatives` on the `regrip_faces` of `fold_model`; the
    back side at the standoff of the back-side variant in `variants`). The least clearance of a
    passing check is read from `accept.clearances` ({toolpath sha256: m}) when the checker keeps
    it. Returns the chosen program, else the single-grip program the check will refuse (its `tried`
    naming the regrips refused too); raises `PlanningError` when nothing plans. `footprint`: the
    cup on a face (`robot.grip_choice.cup_order`), faces that carry it first, single grip and regrip."""
    from fabkit.frames import face_frames_of
    from robot.grip_choice import plan_panel
    from robot.planner import PlanningError
    from robot.regrip_choice import Alternative, pick_alternative, regrip_faces, same_crease_alternatives

    verdicts = {}

    def judged(res):
        verdicts[id(res.toolpath)] = problem = accept(res)
        return problem

    try:
        single, failure = plan_panel(cell, frames, options=options, source=source, clamped_faces=clamped_faces,
                                     placement=placement, accept=judged, variants=variants,
                                     footprint=footprint), None
    except PlanningError as exc:
        single, failure = None, exc
    if single is not None and id(single.toolpath) in verdicts and verdicts[id(single.toolpath)] is None:
        return single   # checked and passed (a face the cup does not fit is refused unchecked)
    alternatives = []
    specs = step_phases(fold_model, frames)
    if specs is not None:        # folded step by step: a regrip per step
        label = "regrip per fold step (" + ", ".join(f"face {p.face} states {p.first}-{p.last}" for p in specs) + ")"
        alternatives.append(Alternative(label=label, face=specs[0].face, plan=lambda: plan_phases(
            cell, frames, specs, options=options, source={**(source or {}), "grip_face": specs[0].face},
            clamped_faces=clamped_faces, placement=placement)))
    back = next(v for v in variants if v.grip_side == "back")
    middle = {int(f) for f in frames.faces}
    alternatives += same_crease_alternatives(
        cell, lambda f: frames if f in middle else face_frames_of(fold_model, f),
        regrip_faces(fold_model, clamped_faces, footprint=footprint), options=options, source=source, clamped_faces=clamped_faces,
        placement=placement, back_standoff=back.grip_standoff)
    clearances = getattr(accept, "clearances", None)
    best, tried = pick_alternative(alternatives, accept=accept, clearance_of=None if clearances is None else
                                   (lambda res: clearances.get(res.toolpath.sha256)))
    before = single.tried if single is not None else ()
    if best is not None:
        return replace(best.result, tried=tuple(before) + tuple(tried))
    if single is not None:
        return replace(single, tried=tuple(before) + tuple(tried))
    raise PlanningError(failure.waypoint, failure.op, failure.state, failure.kind,
                        f"{failure.detail}; a regrip in phases did not plan either: "
                        + "; ".join(t for _, t in tried))
