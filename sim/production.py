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

__all__ = ["program_panel", "carry_over"]


@functools.lru_cache(maxsize=4)
def _cell(cell_toml: str, cell_name: str):
    from robot.cell import parse_cell

    return parse_cell(tomllib.loads(cell_toml), cell_name)


def program_panel(fold_text: str, fold_name: str, cell_toml: str, cell_name: str, thickness: float) -> dict:
    """Plan and check one panel. Returns {"stage": "program"|"check"|None, "reason", "toolpath"
    (PATH.json dict or None), "check" (CHECK.json dict or None), "cycle_time_s", "grip_face"}; stage
    None means both passed."""
    from fabkit.frames import middle_row_frames
    from fabkit.io.fold import load_fold
    from robot.holds_record import clamped_faces_of
    from robot.panel_placement import placed_cell, placement_for
    from robot.toolpath import PlanningError, plan_panel
    from sim.check import run_toolpath_check

    cell = _cell(cell_toml, cell_name)
    out = {"stage": None, "reason": "", "toolpath": None, "check": None, "cycle_time_s": None, "grip_face": None}
    with tempfile.TemporaryDirectory(prefix="fabkit-program-") as tmp:  # read back exactly as a file
        path = Path(tmp) / Path(fold_name).name
        path.write_text(fold_text)
        model = load_fold(path)
        frames = middle_row_frames(model, source=fold_name)
        source = {"file": fold_name, "sha256": hashlib.sha256(fold_text.encode()).hexdigest(),
                  "states": int(frames.n_states)}
        try:  # planned as `fabkit toolpath` plans: the clamped face on the cell's clamp
            placement = placement_for(cell, model)
            res = plan_panel(placed_cell(cell, placement), frames, source=source,
                             clamped_faces=clamped_faces_of(model), placement=placement)
        except PlanningError as exc:
            return {**out, "stage": "program", "reason": str(exc)}
        from robot.jig_holds import with_jig_holds

        tp = with_jig_holds(res.toolpath, cell, model)   # the faces the cell's jigs hold
        out.update(toolpath=tp.to_json(), grip_face=int(res.grip_face), cycle_time_s=float(res.cycle_time))
        # the check `fabkit check` runs: arm, panel, holds, the panel's own collisions
        report = run_toolpath_check(tp, cell, fold=path, thickness=thickness).report
        # the report names the FOLD file it checked: the panel's own name, not this temporary copy
        check = json.loads(json.dumps(report.to_json()).replace(json.dumps(str(path))[1:-1], fold_name))
    out["check"] = check
    out["cycle_time_s"] = float(report.cycle_time_s)
    if not report.ok:
        first = report.problems[0]
        out.update(stage="check", reason=f"{len(report.problems)} problem(s), first: waypoint {first.waypoint} "
                                         f"{first.kind}: {first.detail}")
    return out


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
