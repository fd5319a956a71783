"""The planner entry for any cell: the panel placed on the clamp, then one arm or two.

`plan_in_cell` is what `fabkit toolpath` and `fabkit.pipeline.plan` call. It puts the FOLD file's
clamped face on the cell's clamp (`robot.panel_placement`), records the clamped faces, and plans
with `robot.grip_choice.plan_panel` for a one-arm cell (PATH.json `fabkit.toolpath/2`; when every
grip of one side fails, a same-crease regrip in phases, `robot.phased_planner.with_regrip`) or with
`robot.two_arm_planner.plan_two_arms` for a cell with two arms (`fabkit.toolpath/3`). Rigid
programs try the grip faces that carry the cell's cup first (`cup_footprint_of`).
"""
from __future__ import annotations

from fabkit.errors import InputError

__all__ = ["plan_in_cell", "cup_footprint_of"]


def plan_in_cell(cell, fold_model, frames, *, grip_face: int | None = None, options=None, source: dict | None = None,
                 accept=None, variants=(), sheet: bool = False, fold_file=None):
    """Plan the fold of `fold_model` (its planning frames `frames`) in `cell` (module docstring).
    `grip_face`: the face to grip (a two-arm cell: one of the two); `accept`: the checker
    (`sim.grip_search.checked_acceptor`), asked for each candidate that plans; `variants`: further
    `PlanOptions` a one-arm cell tries per face; `sheet`: the program follows a sheet's compensated
    states (a one-arm cell then tries no regrip; a two-arm cell plans as for a rigid panel, the
    sheet records are added by `robot.arms_sheet`). Returns a `robot.planner.PlanResult` or a
    `robot.two_arm_planner.ArmsPlanResult`; raises `robot.planner.PlanningError`."""
    from robot.holds_record import clamped_faces_of
    from robot.panel_placement import placed_cell, placement_for
    from robot.grip_choice import plan_panel
    from robot.planner import PlanOptions

    options = options or PlanOptions()
    placement = placement_for(cell, fold_model)   # the clamped face on the cell's clamp
    placed = placed_cell(cell, placement)
    clamped = clamped_faces_of(fold_model)
    footprint = None if sheet else cup_footprint_of(cell, fold_model)
    if len(cell.arms) == 1:
        if accept is None or grip_face is not None or sheet or options.grip_side != "front" or not any(
                v.grip_side == "back" for v in variants):
            return plan_panel(placed, frames, grip_face=grip_face, options=options, source=source,
                              clamped_faces=clamped, placement=placement, accept=accept, variants=variants,
                              footprint=footprint)
        from robot.phased_planner import with_regrip

        return with_regrip(placed, frames, fold_model, options=options, source=source, clamped_faces=clamped,
                           placement=placement, accept=accept, variants=variants, footprint=footprint)
    from robot.two_arm_planner import hold_pairs, plan_two_arms

    name = None if fold_file is None else str(fold_file)
    grip_faces = None
    if grip_face is not None:
        pairs = [p for p in hold_pairs(fold_model, frames, clamped, source=name) if int(grip_face) in p]
        if not pairs:
            raise InputError(f"face {grip_face} is in no pair of faces that holds the panel with two arms",
                             source="--grip-face")
        grip_faces = pairs[0]
    return plan_two_arms(placed, fold_model, frames, options=options, source=source, clamped_faces=clamped,
                         placement=placement, grip_faces=grip_faces, accept=accept, fold_source_name=name,
                         footprint=footprint)


def cup_footprint_of(cell, fold_model):
    """`footprint(face) -> problem or None`: the cell's cup (`tool.cup_radius`) on a grip face of
    `fold_model` (`fabkit.grip_footprint.cup_fit`, measured once per face), what the check
    (`sim.check_cup`) refuses on; None when the cell declares no cup."""
    radius = getattr(cell.tool, "cup_radius", None)
    if radius is None:
        return None
    from fabkit.grip_footprint import cup_fit

    fit = cup_fit(fold_model, radius)
    return lambda face: fit(face).problem or None
