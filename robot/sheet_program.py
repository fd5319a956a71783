"""A fold program for a real sheet: the springback-compensated states it is planned on, and the
records PATH.json carries for it (`sheet`: the sheet, design and programmed angles per state, the
fold-load verdicts; `payload`: what the program declares to the controller).

`compensated_states(model, spec)` is what the planner follows (the FOLD keeps the design angles);
`sheet_records(tp, spec, design_model, compensated, cell, grip_face, tool_mass)` adds the records to
a planned toolpath. The `sheet` record holds the material as its TOML text, so the check re-derives
the same sheet (`sheet_of_toolpath`) whether the material was a packaged one or a calibrated file:
the record is inside the toolpath's hash, and the check recomputes the loads from it, the FOLD
file and the cell rather than trusting the verdicts recorded at planning.
"""
from __future__ import annotations

from dataclasses import replace

from robot.loads import LoadReport, payload_record, toolpath_loads
from robot.motion import toolpath_cycle_time
from robot.ur_motion import PayloadError

__all__ = ["DEFAULT_TOOL_MASS", "compensated_states", "sheet_records", "sheet_record", "sheet_of_toolpath",
           "toolpath_load_check", "grip_side_of"]

#: Gripper mass [kg] assumed when none is given (an estimate; the command says so).
DEFAULT_TOOL_MASS = 1.0


def compensated_states(model, spec, source: str = "SEQ.fold"):
    """`fabkit.sheet.compensate.CompensatedSequence` of `model` for `spec`, or None for a rigid sheet
    (the program then follows the design states, as without a material)."""
    if spec.rigid:
        return None
    from fabkit.sheet.compensate import compensate_sequence

    return compensate_sequence(model, spec, source=source)


def sheet_records(tp, spec, design_model, compensated, cell, grip_face: int,
                  tool_mass: float | None = None, design_surface: str = "top"):
    """The toolpath with its `sheet` and `payload` records (module docstring) and the
    `robot.loads.LoadReport` of its fold loads; `cell` the cell file's cell (the toolpath's
    placement is applied here). `tool_mass` None: `DEFAULT_TOOL_MASS`;
    `design_surface`: which surface of the sheet the FOLD's faces are (top, mid, bottom), the
    planner having added `fabkit.sheet.front_face_offset` to the grip standoff."""
    from fabkit.sheet import panel_mass
    from robot.panel_placement import placed_cell, placement_of

    mass = DEFAULT_TOOL_MASS if tool_mass is None else float(tool_mass)
    flat = design_model.mesh()
    pm = panel_mass(spec, flat.vertices, flat.triangulate()[0])
    # the panel's CoG where the program placed the panel (its placement record), not the cell's fixture
    payload = payload_record(placed_cell(cell, placement_of(tp.extra)), tp.waypoints, pm.mass, pm.cog, mass)
    loads = toolpath_loads(spec, design_model, compensated.creases, grip_face, cell, mass + pm.mass,
                           side=grip_side_of(tp))
    sheet = sheet_record(spec, compensated, tool_mass, design_surface, loads.summary())
    tp = replace(tp, extra={**tp.extra, "sheet": sheet, "payload": payload})
    try:  # the declared payload lowers the joint acceleration bound (robot.ur_motion)
        tp = replace(tp, extra={**tp.extra, "cycle_time_s": toolpath_cycle_time(tp).total})
    except PayloadError:  # over the arm's rating: the check refuses the toolpath and says so
        pass
    return tp, loads


def sheet_record(spec, compensated, tool_mass: float | None, design_surface: str, loads: dict) -> dict:
    """PATH.json's `sheet` record: the compensated states' summary, the material as TOML, the tool
    mass (`DEFAULT_TOOL_MASS` when None, said so), the design surface and the fold loads' summary."""
    from fabkit.materials import material_toml
    from fabkit.sheet import front_face_offset

    return {**compensated.summary(), "material_toml": material_toml(spec.material),
            "tool_mass_kg": DEFAULT_TOOL_MASS if tool_mass is None else float(tool_mass),
            "tool_mass_assumed": tool_mass is None, "design_surface": design_surface,
            "front_face_offset_mm": front_face_offset(spec, design_surface) * 1000, "loads": loads}


def sheet_of_toolpath(tp):
    """The `fabkit.sheet.SheetSpec` a toolpath was planned for (from its `sheet` record), or None
    when it has none. `InputError` when the record does not describe a sheet."""
    from fabkit.errors import InputError

    rec = tp.extra.get("sheet") if isinstance(tp.extra, dict) else None
    if rec is None:
        return None
    import tomllib

    from fabkit.materials import parse_material
    from fabkit.sheet import sheet_spec

    try:
        material = parse_material(tomllib.loads(rec["material_toml"]), "PATH.json sheet.material_toml")
        mm = 1e-3
        lig = rec.get("ligament_mm")
        return sheet_spec(material, float(rec["thickness_mm"]) * mm, rec["crease_preparation"],
                          ligament=None if lig is None else float(lig) * mm,
                          uncut_fraction=rec.get("uncut_fraction"),
                          inside_radius=float(rec["inside_radius_mm"]) * mm)
    except (KeyError, TypeError, ValueError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"sheet: not a sheet record fabkit toolpath wrote ({type(exc).__name__}: {exc})",
                         source="PATH.json") from None


def toolpath_load_check(tp, spec, design_model, cell, grip_face: int) -> LoadReport:
    """The fold loads of a toolpath's program (`robot.loads.toolpath_loads`) on `cell`, with the
    payload the toolpath declares while it holds the panel (`payload.held_mass_kg`; without a payload
    record: `DEFAULT_TOOL_MASS` + the panel's mass). For one arm of a two-arm program (its view
    `ArmsToolpath.arm`), the creases the other arms' grips fold are not its own
    (`robot.arms_sheet.other_grips`)."""
    from fabkit.sheet import panel_mass
    from fabkit.sheet.creases import panel_creases

    pay = tp.extra.get("payload") if isinstance(tp.extra, dict) else None
    if isinstance(pay, dict) and isinstance(pay.get("held_mass_kg"), (int, float)):
        held = float(pay["held_mass_kg"])
    else:
        flat = design_model.mesh()
        held = DEFAULT_TOOL_MASS + panel_mass(spec, flat.vertices, flat.triangulate()[0]).mass
    from robot.arms_sheet import other_grips

    return toolpath_loads(spec, design_model, panel_creases(design_model), grip_face, cell, held,
                          side=grip_side_of(tp), other_grips=other_grips(tp, grip_face))


def grip_side_of(tp) -> str:
    """The side of the sheet the toolpath's cup grips (PATH.json `grip.side`; front when absent)."""
    grip = tp.extra.get("grip") if isinstance(tp.extra, dict) else None
    return str(grip.get("side", "front")) if isinstance(grip, dict) else "front"
