"""Which grip faces, sides and approach distances the planner tries, in which order.

`grip_order`: the middle-row faces that move, largest motion first (the far end of the row, refold
clamping the first strip); `approach_variants`: other approach/retract distances for a face that
does not plan or pass at the given one; `grip_variants`: those on the front side, then the back
side (the cup's approach axis along +normal instead of -normal, its standoff measured behind the
design surface: a valley folded to 175 deg closes the wing over a cup on the front).
`plan_panel` tries every face on the front side before any on the back (on each side the faces
that carry the cell's cup first: `cup_order`), and with the
checker (`sim.grip_search`) takes the first whose program passes the check, so a panel whose front
grip passes keeps exactly the program it had.

Sides: the front of a face is the side its normal points to (faces counter-clockwise seen from the
front; +z of the flat pattern); a sheet's design surface is its top face unless `--design-surface`
says otherwise (`fabkit.sheet.front_face_offset` / `back_face_offset`).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from fabkit.errors import InputError

__all__ = ["grip_order", "cup_order", "approach_variants", "grip_variants", "plan_panel", "GRIP_SIDES"]

#: The sides a cup can grip, in the order they are tried.
GRIP_SIDES = ("front", "back")


def approach_variants(options):
    """Other approach/retract distances to try when a face does not plan or pass at the given one
    (a retract line through a near-singularity, the tool retracting into the folded panel)."""
    d = options.approach_distance
    return tuple(replace(options, approach_distance=x) for x in (0.6 * d, 1.6 * d))


def grip_variants(options, *, vary_approach: bool = True, back_standoff: float | None = None,
                  sides=GRIP_SIDES):
    """The `PlanOptions` tried after `options` (a front-side grip): with `vary_approach` the front
    side's `approach_variants`, then for "back" in `sides` the back side at `back_standoff` (the TCP
    distance behind the design surface; default `options.grip_standoff`, a sheet of no thickness)
    at the given approach distance only (a back grip that fails there rarely passes at another, and
    each refused candidate costs a plan and a check)."""
    unknown = set(sides) - set(GRIP_SIDES)
    if unknown:
        raise InputError(f"unknown grip side(s) {sorted(unknown)} (choose {', '.join(GRIP_SIDES)})",
                         source="--grip-side")
    out = []
    if "front" in sides and vary_approach:
        out += approach_variants(options)
    if "back" in sides:
        back = replace(options, grip_side="back",
                       grip_standoff=options.grip_standoff if back_standoff is None else float(back_standoff))
        out.append(back)
    return tuple(out)


def grip_order(frames, grip_face: int | None = None) -> list[int]:
    """The grip faces `plan_panel` tries, in order: `grip_face` alone when given (`InputError` if it
    is not a middle-row face), else the middle-row faces that move, largest motion first (more
    leverage far from the clamp; the far end of the row first), ties by the face frames' turn."""
    faces = [int(f) for f in frames.faces]
    if grip_face is not None:
        if int(grip_face) not in faces:
            raise InputError(f"face {grip_face} is not a middle-row face (middle row: {faces})", source="--grip-face")
        return [int(grip_face)]
    C = frames.frames[:, :, :3, 3]
    Z = frames.frames[:, :, :3, 2]
    turn = np.arccos(np.clip(np.einsum("ski,ki->sk", Z, Z[0]), -1.0, 1.0)).max(axis=0)
    motion = np.linalg.norm(C - C[0], axis=-1).max(axis=0) + 1e-6 * turn
    moving = [faces[k] for k in np.argsort(-motion, kind="stable") if motion[k] > 1e-9]
    return moving or faces


def cup_order(faces, footprint=None) -> list[int]:
    """`faces` with those whose cup fits (`footprint(face)` None) first, each part in its order;
    unchanged without `footprint`."""
    faces = [int(f) for f in faces]
    if footprint is None:
        return faces
    return [f for f in faces if footprint(f) is None] + [f for f in faces if footprint(f) is not None]


def plan_panel(cell, frames, *, grip_face: int | None = None, options=None, source: dict | None = None,
               clamped_faces=(), placement: dict | None = None, accept=None, variants=None, footprint=None):
    """Plan for a panel's middle-row frames (`fabkit.frames.FaceFrames`) in `cell` with
    `robot.planner.plan_toolpath`, trying grip faces and `PlanOptions` -> `robot.planner.PlanResult`.

    With `grip_face` None the face is chosen automatically: faces that move (not the clamped
    strip) are tried from the largest motion down (`grip_order`) and the first that plans is used,
    or with `accept(PlanResult) -> problem or None` (the checker: `sim.grip_search`) the first that
    plans and that `accept` passes; when `accept` refuses every face that plans, the first of them
    is returned (its check will say why), with `refusal` its problem. `variants`: further
    `PlanOptions` tried for each face after `options` (e.g. `robot.grip_choice.grip_variants`), in
    order; variants gripping another side (`grip_side`) are tried after every face on the first
    side. Raises `InputError` for a grip face not in the middle row, `PlanningError` when no face
    plans (the error of the face that got farthest).
    `footprint(face) -> problem or None` (the cup on that face: `cup_order`): faces whose cup fits
    are tried first on each side, the others after them, never sent to `accept` and planned only
    until one plans when nothing else did (the program returned for the check to refuse, naming the
    cup).
    """
    from robot.planner import PlanningError, PlanOptions, plan_toolpath  # it imports this module

    options = options or PlanOptions()
    order = cup_order(grip_order(frames, grip_face), None if grip_face is not None else footprint)
    tried, refused, refusal = [], None, None
    every = (options, *(variants or ()))
    sides = [[o for o in every if o.grip_side == side] for side in dict.fromkeys(o.grip_side for o in every)]
    for face, opt in ((f, o) for group in sides for f in order for o in group):  # every face's front first
        misfit = footprint(face) if footprint is not None and accept is not None and grip_face is None else None
        if misfit and refused is not None:   # a program to refuse is there already: no plan for this one
            tried.append((face, f"{opt.grip_side} side: the cup: {misfit} (not planned)"))
            continue
        try:
            res = plan_toolpath(cell, frames.of_face(face), options=opt,
                                source={**(source or {}), "grip_face": face}, grip_face=face,
                                clamped_faces=clamped_faces, placement=placement)
        except PlanningError as exc:
            tried.append((face, exc))
            continue
        problem = (f"{opt.grip_side} side: the cup: {misfit} (not checked)" if misfit
                   else accept(res) if accept is not None and grip_face is None else None)
        if problem is None:
            return replace(res, tried=tuple(tried))
        tried.append((face, problem))
        if refused is None:
            refused, refusal = res, problem
    if refused is not None:
        return replace(refused, tried=tuple(tried), refusal=refusal)
    tried = [(f, e) for f, e in tried if isinstance(e, PlanningError)]
    first = max(tried, key=lambda fe: fe[1].waypoint)[1] if len(tried) > 1 else tried[0][1]
    if len(tried) > 1:
        raise PlanningError(first.waypoint, first.op, first.state, first.kind,
                            f"{first.detail} (no middle-row face works: tried {[f for f, _ in tried]})")
    raise first
