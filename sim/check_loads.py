"""The sheet part of a toolpath check: which sheet the program folds, the fold states the panel is
posed in, and the fold-load verdicts per state.

A toolpath planned with a material carries a `sheet` record (`robot.sheet_program`): its program
follows the springback-compensated states, so the check poses the panel in those (recomputed from
the FOLD file and the sheet), with the sheet's real thickness on the side of the design surface
where the sheet lies (behind its top face, which the cup grips), and recomputes the fold loads of
every crease the arm folds, per state, against the cell's arm ratings and vacuum cup
(`robot.loads`). A toolpath without a record was planned rigid; a sheet given to the check then
adds the load verdicts for that sheet (the program itself is not compensated and declares no
payload; the report says so). A given sheet that differs from the record is refused: the program
was made for the recorded one.

Exceeded loads are problems of kind `load`, one per crease and check, on the waypoints of the fold
moves of the states concerned, naming the crease and the remedy. The cell's vacuum pad must also
sit on the grip face (`fabkit.grip_footprint.pad_footprint`): a pad that does not fit, or sheet
under it that is not planar enough for its lips, is a `load` problem at the grip waypoint (subject
"pad footprint").
"""
from __future__ import annotations

from dataclasses import dataclass

from fabkit.errors import InputError
from sim.problems import Problem

__all__ = ["SheetCheck", "resolve_sheet", "fold_states_model", "slab_offset", "check_sheet_loads"]


@dataclass(frozen=True)
class SheetCheck:
    """The load verdicts of a check: `record` (CHECK.json `loads`), `problems` (kind `load`),
    `notes`; `ok` when no load is exceeded."""

    record: dict
    problems: tuple[Problem, ...]
    notes: tuple[str, ...]

    @property
    def ok(self) -> bool:
        return not self.problems


def _same_sheet(a, b) -> bool:
    from fabkit.materials import material_toml

    return a.summary() == b.summary() and material_toml(a.material) == material_toml(b.material)


def resolve_sheet(tp, sheet=None):
    """`(spec, recorded)`: the sheet the check uses - the toolpath's record (`recorded` True), else
    the `sheet` given (a `fabkit.sheet.SheetSpec`), else None - or `InputError` when a sheet is
    given that is not the recorded one."""
    if sheet is None and not (isinstance(tp.extra, dict) and tp.extra.get("sheet") is not None):
        return None, False  # a rigid program: nothing of the sheet models is loaded
    from robot.sheet_program import sheet_of_toolpath

    recorded = sheet_of_toolpath(tp)
    if recorded is not None:
        if sheet is not None and not _same_sheet(sheet, recorded):
            raise InputError(f"the toolpath was planned for {_describe(recorded)}, not {_describe(sheet)} (re-plan "
                             "with fabkit toolpath --material ... to fold another sheet)", source="--material")
        return recorded, True
    if sheet is None or sheet.rigid:
        return None, False
    return sheet, False


def _describe(spec) -> str:
    if spec.rigid:
        return "a rigid sheet (--material none)"
    return f"{spec.thickness * 1000:g} mm {spec.material.name}, {spec.prep.describe()}"


def fold_states_model(model, spec, recorded: bool, source: str):
    """The FOLD model whose states the program follows: the compensated states of a recorded sheet,
    else `model` itself."""
    if spec is None or not recorded:
        return model
    from robot.sheet_program import compensated_states

    comp = compensated_states(model, spec, source=source)
    return model if comp is None else comp.model


def slab_offset(tp, spec, thickness: float | None) -> float:
    """Where the panel pieces' slab sits [m, its centre along the front normals]: centred on the
    faces without a sheet; for a sheet, behind its front face, which lies `front_face_offset` in
    front of the design surface (the record's `design_surface`, else the top face)."""
    if spec is None or spec.rigid or not thickness:
        return 0.0
    from dataclasses import replace

    from fabkit.sheet import front_face_offset

    rec = tp.extra.get("sheet") if isinstance(tp.extra, dict) else None
    surface = rec.get("design_surface", "top") if isinstance(rec, dict) else "top"
    return front_face_offset(replace(spec, thickness=float(thickness)), surface) - thickness / 2


def _state_moves(tp) -> dict[int, tuple[int, int]]:
    """Per fold state s >= 1: (first, last) waypoint index of the moves that fold into it (from the
    one after state s - 1's grip pose to state s's)."""
    pose_of: dict[int, int] = {}
    for k, w in enumerate(tp.waypoints):
        if w.op in ("grip", "fold", "release") and int(w.state) not in pose_of:
            pose_of[int(w.state)] = k
    return {s: (pose_of[s - 1] + 1, k) for s, k in pose_of.items() if s >= 1 and s - 1 in pose_of}


def check_sheet_loads(tp, spec, design_model, cell, *, recorded: bool) -> SheetCheck:
    """The fold-load verdicts of `tp` folding `spec` (module docstring). `design_model`: the FOLD
    the toolpath was planned from (its crease rows and design states)."""
    from robot.sheet_program import toolpath_load_check
    from sim.toolpath_program import grip_face_of

    grip = grip_face_of(tp)
    if grip is None:
        raise InputError("the toolpath names no grip face: the fold loads cannot be checked", source="PATH.json")
    rep = toolpath_load_check(tp, spec, design_model, cell, grip)
    moves = _state_moves(tp)
    states: dict[int, list] = {}
    for v in rep.verdicts:
        states.setdefault(v.state, []).append({
            "crease": v.crease, "check": v.check, "demand": v.demand, "capacity": v.capacity, "unit": v.unit,
            "ratio": v.demand / v.capacity if v.capacity > 0 else None, "ok": v.ok, "remedy": v.remedy})
    moments = {(v.state, v.crease): v.demand for v in rep.verdicts if v.check == "wrist couple"}
    rows = []
    for s in sorted(states):
        for row in states[s]:
            row["moment_nm"] = moments.get((s, row["crease"]))
        first, last = moves.get(s, (None, None))
        rows.append({"state": s, "waypoints": None if first is None else [first, last],
                     "ok": all(r["ok"] for r in states[s]), "checks": states[s]})
    problems = []
    for crease, check, vs in rep.failure_runs():
        worst = max(vs, key=lambda v: v.demand)
        ss = [v.state for v in vs]
        first = moves.get(ss[0], (0, 0))[0]
        last = moves.get(ss[-1], (first, first))[1]
        problems.append(Problem(
            waypoint=first, kind="load", last_waypoint=last, subject=f"{crease}: {check}",
            value=worst.demand / worst.capacity if worst.capacity > 0 else None,
            detail=(f"{crease}, fold states {','.join(map(str, ss))}: {check} {worst.demand:.1f} {worst.unit} of "
                    f"{worst.capacity:.1f} {worst.unit} ({worst.demand / worst.capacity:.0%}); remedy: "
                    f"{worst.remedy}")))
    footprint = _pad_footprint(tp, design_model, cell, grip)
    if not footprint["ok"]:
        at = next((k for k, w in enumerate(tp.waypoints) if w.op == "grip"), 0)
        problems.append(Problem(waypoint=at, kind="load", last_waypoint=at, subject="pad footprint",
                                value=footprint["radius_mm"] / max(footprint["room_mm"], 1e-9),
                                detail=f"{footprint['problem']}; remedy: a smaller pad, or grip a wider face"))
    notes = []
    if not recorded:
        notes.append(f"fold loads checked for {_describe(spec)}, but the program was planned rigid: it is not "
                     "springback-compensated and declares no payload (plan with fabkit toolpath --material)")
    record = {**rep.summary(), "sheet": spec.summary(), "recorded": recorded, "states": rows,
              "pad_footprint": footprint}
    record.pop("problems", None)
    return SheetCheck(record=record, problems=tuple(problems), notes=tuple(notes))


def _pad_footprint(tp, design_model, cell, grip: int) -> dict:
    """The cell's pad on the grip face (`fabkit.grip_footprint.pad_footprint`), JSON-ready."""
    from fabkit.grip_footprint import FoldGeometry, pad_footprint
    from robot.loads import pad_of_cell

    pad = pad_of_cell(cell)
    fp = pad_footprint(FoldGeometry.of_fold(design_model), grip, pad.footprint_radius, cup_radius=pad.diameter / 2)
    return {"ok": fp.ok, "face": int(grip), "radius_mm": pad.footprint_radius * 1000, "room_mm": fp.inscribed_m * 1000,
            "planarity_mm": fp.planarity_m * 1000, "faces": list(fp.faces), "problem": fp.problem}

