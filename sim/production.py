"""One panel's robot program for a production run: plan the fold toolpath, then check it in MuJoCo.

`program_panel` is the one place a production run (`fabkit.panels.production`) reaches the robot
and the simulator: it takes the panel's FOLD text (the refolded states) and the cell description
as text (so a worker on another machine needs no shared files) and returns plain data — the
PATH.json and CHECK.json documents and a verdict. The toolpath is checked exactly as planned (the
check reads the toolpath's own waypoints and the same fold states).
"""
from __future__ import annotations

import copy
import dataclasses
import functools
import hashlib
import json
import tempfile
import tomllib
from pathlib import Path

__all__ = ["program_panel", "carry_over", "clamp_refusal", "cup_refusal", "cup_refusal_before_refold"]


@functools.lru_cache(maxsize=4)
def _cell(cell_toml: str, cell_name: str):
    """The cell of `cell_toml` (the file's text, read as UTF-8 without newline translation), with
    the sha256 of the file's bytes as `robot.cell.load_cell` gives it, so `fabkit send` and
    `fabkit check` of the files written accept them against the cell file."""
    from robot.cell import parse_cell

    cell = parse_cell(tomllib.loads(cell_toml), cell_name)
    return dataclasses.replace(cell, sha256=hashlib.sha256(cell_toml.encode("utf-8")).hexdigest())


def program_panel(fold_text: str, fold_name: str, cell_toml: str, cell_name: str, thickness: float, *,
                  grip_face: int | None = None, sheet=None, tool_mass: float | None = None) -> dict:
    """Plan and check one panel, as `fabkit toolpath` and `fabkit check` do. Returns {"stage":
    "program"|"check"|None, "reason", "toolpath" (PATH.json dict or None), "check" (CHECK.json dict
    or None), "cycle_time_s", "grip_face", "loads"}; stage None means both passed.

    `grip_face`: the face the arm grips (None: the planner's choice through the check, as
    `fabkit toolpath`). `sheet` (`fabkit.sheet.SheetSpec`, not rigid): the program follows the
    springback-compensated states and carries the sheet and payload records
    (`robot.sheet_program`, as `fabkit toolpath --material`), and the check rebuilds the sheet
    from them and checks the fold loads (as `fabkit check`); `thickness` is then the sheet's."""
    from fabkit.errors import InputError, ToleranceError
    from fabkit.toolpath_stage import PlanSettings, plan_fold_file
    from sim.check import run_toolpath_check

    out = {"stage": None, "reason": "", "toolpath": None, "check": None, "cycle_time_s": None, "grip_face": None,
           "loads": None, "unclampable": None}
    sheet_fields = {} if sheet is None else {
        "material": sheet.material, "thickness": sheet.thickness, "crease": sheet.prep.kind,
        "ligament": sheet.prep.ligament, "bend_radius": sheet.inside_radius, "tool_mass": tool_mass}
    # the front side only: a production run tries its set-ups (fabkit.panels.production_refold) instead
    settings = PlanSettings(grip_face=grip_face, grip_side="front", **sheet_fields)
    with tempfile.TemporaryDirectory(prefix="fabkit-program-") as tmp:  # read back exactly as files
        path = Path(tmp) / Path(fold_name).name
        path.write_text(fold_text)
        cell_file = Path(tmp) / Path(cell_name).name
        cell_file.write_bytes(cell_toml.encode("utf-8"))
        from fabkit.io.fold import load_fold

        model = load_fold(path)  # read once for both refusals (the planner and the check read the file)
        unclampable = clamp_refusal(model, _cell(cell_toml, cell_name))
        if unclampable:  # the check would fail on it whatever the program: not planned
            return {**out, "stage": "check", "reason": f"waypoint 0 holds: {unclampable} (the clamp check, run "
                    "before planning: no program was planned or checked)", "unclampable": unclampable}
        no_cup = None if sheet is not None else cup_refusal(model, _cell(cell_toml, cell_name), grip_face,
                                                            source=str(path))
        if no_cup:  # every face the planner could grip is refused by the check's cup rule: not planned
            return {**out, "stage": "check", "reason": f"holds: {no_cup} (the cup check, run before planning: "
                    "no program was planned or checked)"}
        try:  # planned by the plan stage `fabkit toolpath` runs
            program = plan_fold_file(path, cell_file, settings)
        except (InputError, ToleranceError) as exc:  # springback the sheet cannot reach, a crease too tight
            return {**out, "stage": "program", "reason": str(exc).replace(str(path), fold_name)}
        if program.loads is not None:
            out["loads"] = program.loads.summary()
        if not program.ok:
            return {**out, "stage": "program", "reason": program.problems[0].replace(str(path), fold_name)}
        tp, res, cell = program.toolpath, program.plan, _cell(cell_toml, cell_name)
        out.update(toolpath=tp.to_json(), grip_face=int(res.grip_face), cycle_time_s=float(res.cycle_time))
        # the check `fabkit check` runs: arm, panel, holds, the panel's own collisions, the sheet's loads
        pieces = None if sheet is not None else thickness  # with a sheet: the sheet's thickness
        report = run_toolpath_check(tp, cell, fold=path, thickness=pieces).report
        # the report names the FOLD file it checked: the panel's own name, not this temporary copy
        check = json.loads(json.dumps(report.to_json()).replace(json.dumps(str(path))[1:-1], fold_name))
    out["check"] = check
    out["cycle_time_s"] = float(report.cycle_time_s)
    if not report.ok:
        first = report.problems[0]
        out.update(stage="check", reason=f"{len(report.problems)} problem(s), first: waypoint {first.waypoint} "
                                         f"{first.kind}: {first.detail}")
    return out


def _fold_model(fold):
    """`fold` as a `FoldModel`: a FOLD file's path is read, a model is taken as it is."""
    from fabkit.io.fold import load_fold

    return load_fold(fold) if isinstance(fold, (str, Path)) else fold


def clamp_refusal(fold, cell) -> str | None:
    """The check's clamp footprint problem of the FOLD file's panel in `cell` (`fold`: the file's
    path or its `FoldModel`), or None: the clamp's footprint leaves the clamped face where the
    planner places the panel (`robot.panel_placement`).
    It is a problem of the check (`sim.check_holds.clamp_problems`, computed as the check computes
    it, from the same placement) that no program escapes, so a set-up it refuses is refused before
    its plan and check are paid for."""
    from robot.holds_record import clamped_faces_of
    from robot.panel_placement import placed_cell, placement_for
    from sim.check_holds import clamp_problems

    model = _fold_model(fold)
    clamped = clamped_faces_of(model)
    placed = placed_cell(cell, placement_for(cell, model))
    problems = clamp_problems(model, placed, clamped, 1)
    return problems[0].detail if problems else None


def cup_refusal(fold, cell, grip_face: int | None = None, source: str | None = None) -> str | None:
    """Why no face the planner may grip carries the cell's cup, or None (`fold`: the FOLD file's
    path or its `FoldModel`, `source` its name in errors): every middle-row face it
    tries (`robot.grip_choice.grip_order`, or `grip_face`) fails the cup rule the check applies
    (`sim.check_cup`, through `robot.plan_cell.cup_footprint_of`), so any one-grip program of this
    set-up is refused and the plan and check are not paid for."""
    from fabkit.frames import planning_frames
    from robot.grip_choice import grip_order
    from robot.plan_cell import cup_footprint_of

    model = _fold_model(fold)
    footprint = cup_footprint_of(cell, model)
    if footprint is None:
        return None
    source = source if source is not None else str(fold) if isinstance(fold, (str, Path)) else None
    faces = grip_order(planning_frames(model, grip_face, source=source), grip_face)
    misfits = [(f, footprint(f)) for f in faces]
    if any(problem is None for _, problem in misfits):
        return None
    f, problem = misfits[0]
    return _no_cup(cell.tool.cup_radius, len(faces), f, problem)


def _no_cup(cup_radius: float, tried: int, face: int, problem: str, where: str = "middle-row face") -> str:
    return f"no {where} carries the {2000 * cup_radius:.0f} mm cup ({tried} tried); grip face {face}: {problem}"


def cup_refusal_before_refold(geometry, faces, cell_toml: str, cell_name: str, *, deviation_m: float,
                              sheet=None, middle_row: bool = True) -> str | None:
    """`program_panel`'s refusal of a set-up whose cup no refold can seat, or None, from the set-up's
    flat pattern and target (`fabkit.cup_before_refold`, two-state `geometry`) before its refold:
    every one of `faces` (the faces the planner may grip; `middle_row` False: a larger set, every
    face of the panel) is refused by the check's cup rule on any refold whose last state is within
    `deviation_m` [m] of the target. None with a `sheet` (its pad is checked with the fold loads,
    as `program_panel` does) or a cell without a cup."""
    from fabkit.cup_before_refold import cup_refused_before_refold

    cell = _cell(cell_toml, cell_name)
    radius = getattr(cell.tool, "cup_radius", None)
    if sheet is not None or radius is None:
        return None
    misfits = cup_refused_before_refold(geometry, faces, radius, deviation_m=deviation_m)
    if misfits is None:
        return None
    first = misfits[0]
    no_cup = _no_cup(radius, len(faces), int(faces[0]), first.problem,
                     "middle-row face" if middle_row else "face of the panel")
    return f"holds: {no_cup} (the cup check, run before the refold: nothing was refolded, planned or checked)"


def carry_over(result: dict, fold_text: str, fold_name: str, note: str) -> dict:
    """`program_panel`'s `result` for another panel whose FOLD (`fold_text`) has the same fold
    states (`fabkit.panels.production.relabel_fold`): the same waypoints, with the toolpath's
    source re-pointed at this FOLD (name and sha256; the toolpath hash follows) and the check's
    toolpath hash with it, `note` added to the check's notes. The check reads only the toolpath
    and the fold states, so it is the check of these files as they are."""
    from robot.toolpath import Toolpath

    out = copy.deepcopy(result)
    if result["toolpath"] is None:
        return out
    tp = Toolpath.from_json(result["toolpath"])
    src = {**tp.source, "file": Path(fold_name).name, "sha256": hashlib.sha256(fold_text.encode()).hexdigest()}
    moved = dataclasses.replace(tp, source=src)
    out["toolpath"] = moved.to_json()
    if out["check"] is not None:
        if out["check"].get("toolpath_sha256") != tp.sha256:
            raise ValueError("the check does not belong to the toolpath it is carried over with")
        out["check"]["toolpath_sha256"] = moved.sha256
        out["check"]["notes"] = list(out["check"].get("notes", [])) + [note]
    return out
