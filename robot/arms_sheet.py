"""A sheet program for a cell with two arms: what the sheet model adds to each arm's program.

In (the same models as one arm, `robot.sheet_program`, per arm):

- **springback**: the program follows the springback-compensated fold states
  (`robot.sheet_program.compensated_states`): every crease is overbent by its own compensation,
  whichever arm folds it, so a crease gets the same programmed angle as in a one-arm program of
  the same FOLD file. The `sheet` record (angles per state, material, tool mass) is shared by the
  arms;
- **payload per arm**: the panel's mass is split among what holds it (`holder_shares`): each strip
  of the panel (the parts between crease rows) goes to the holder nearest along the strips - the
  clamp's strip to the clamp, the strips from an arm's grip strip outward to that arm - and a
  strip as near to two holders is split equally between them. Each arm declares its tool plus its
  share (`robot.loads.payload_record`, CoG in its flange frame at the grip); the clamp's share is
  carried by the clamp. The shares sum to the panel's mass. Without strip tags the panel cannot be
  split: each arm then declares the whole panel (the one-arm bound) and the record says so;
- **fold loads per arm**: each crease is folded by the arm whose grip is nearest beyond it from the
  clamp (`robot.loads.toolpath_loads` with the other arms' grips): on the middle-clamped tri-fold
  each arm folds the crease row between the clamp and its wing. Its fold moment, its lever to that
  arm's grip and the arm's payload are checked against that arm's wrist, rated payload and cup
  (pull and tilt of the pad), as for one arm. `ArmsLoadReport` holds one `LoadReport` per arm.

Out: the share of a wing's weight the crease carries as a hinge, and the lever effect of gripping
nearer the crease than the wing's centre of mass (the declared share is the wing's mass); forces
one arm exerts on the other through the panel when their fold moves are not exactly simultaneous
(the planner makes them equal in the motion model; `robot.two_arm_planner`); springback between
the two wings (each crease is compensated on its own, as for one arm); regrips (never planned for
a sheet).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["HolderShare", "holder_shares", "ArmsLoadReport", "arms_sheet_records", "other_grips"]

CLAMP = "clamp"


@dataclass(frozen=True)
class HolderShare:
    """The part of the panel's mass one holder carries: `mass` [kg], `cog` [m] (panel frame, flat),
    `strips` {strip: fraction of it}."""

    mass: float
    cog: np.ndarray
    strips: dict


def _strip_of_face(model, face: int) -> int:
    from fabkit.frames import face_groups

    groups = face_groups(model.faces_vertices, model.faces_data)
    return int(groups.strip[groups.index_of(int(face))])


def holder_shares(model, spec, grips: dict, fixed_face: int | None = None) -> dict | None:
    """{holder: HolderShare} of the design FOLD `model` (its flat key frame) for the arms' `grips`
    {arm: face} and the clamped face (`fixed_face`, default the file's `fabkit:fixed_face`), the
    clamp as holder `"clamp"` (module docstring). None without strip tags or a clamped face."""
    from fabkit.sheet import panel_mass

    if fixed_face is None:
        fixed_face = model.file_data.get("fabkit:fixed_face")
    if fixed_face is None or "strip" not in model.faces_data:
        return None
    holders = {CLAMP: _strip_of_face(model, int(fixed_face)),
               **{arm: _strip_of_face(model, int(f)) for arm, f in grips.items()}}
    strip = np.asarray(model.faces_data["strip"], dtype=np.int64)
    weights = {h: np.zeros(len(strip)) for h in holders}
    fractions: dict = {h: {} for h in holders}
    for s in np.unique(strip):
        dist = {h: abs(int(s) - hs) for h, hs in holders.items()}
        near = [h for h in holders if dist[h] == min(dist.values())]
        for h in near:
            weights[h][strip == s] = 1.0 / len(near)
            fractions[h][int(s)] = 1.0 / len(near)
    flat = model.mesh()
    tris, tri_face = flat.triangulate()
    V = np.asarray(flat.vertices, np.float64)
    whole = panel_mass(spec, V, tris)
    a, b, c = V[tris[:, 0]], V[tris[:, 1]], V[tris[:, 2]]
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    centres = (a + b + c) / 3
    out = {}
    for h in holders:
        w = weights[h][tri_face] * areas
        area = float(w.sum())
        cog = (centres * w[:, None]).sum(0) / area if area > 0 else whole.cog
        out[h] = HolderShare(mass=whole.mass * area / whole.area if whole.area > 0 else 0.0, cog=cog,
                             strips=fractions[h])
    return out


@dataclass(frozen=True)
class ArmsLoadReport:
    """The fold-load verdicts of every arm: `arms` ((name, `robot.loads.LoadReport`), ...); the
    same interface as one arm's report, each line naming its arm."""

    arms: tuple

    @property
    def ok(self) -> bool:
        return all(r.ok for _, r in self.arms)

    @property
    def failures(self) -> list:
        return [v for _, r in self.arms for v in r.failures]

    def failure_lines(self) -> list[str]:
        return [f"arm {n}: {line}" for n, r in self.arms for line in r.failure_lines()]

    def summary(self) -> dict:
        """One arm's summary shape (`verdicts` and `problems` of all arms, each crease named
        "arm <name>: <crease>") plus `arms` {name: that arm's summary}."""
        per = {n: r.summary() for n, r in self.arms}
        verdicts = [{**v, "crease": f"arm {n}: {v['crease']}", "arm": n} for n, s in per.items()
                    for v in s["verdicts"]]
        return {"ok": self.ok, "arm": "+".join(s["arm"] for s in per.values()),
                "payload_kg": {n: s["payload_kg"] for n, s in per.items()}, "verdicts": verdicts,
                "problems": [f"arm {n}: {p}" for n, s in per.items() for p in s["problems"]], "arms": per}


def other_grips(tp, grip_face: int) -> tuple[int, ...]:
    """The faces the other arms of a two-arm program hold (its `source.grip_faces`), seen from the
    arm that grips `grip_face`; () for a one-arm program."""
    faces = (tp.source or {}).get("grip_faces") if isinstance(tp.source, dict) else None
    if not isinstance(faces, dict):
        return ()
    return tuple(int(f) for f in faces.values() if int(f) != int(grip_face))


def arms_sheet_records(atp, spec, design_model, compensated, cell, grips: dict, tool_mass: float | None = None,
                       design_surface: str = "top"):
    """`(ArmsToolpath with the sheet records, ArmsLoadReport)` of a two-arm program `atp` planned on
    the compensated states (module docstring): the shared `sheet` record, each arm's `payload`
    and its cycle time under that payload; `cell` the cell file's cell (the program's placement is
    applied here)."""
    from dataclasses import replace

    from fabkit.sheet import panel_mass
    from robot.arm_cells import arm_cell
    from robot.arms_toolpath import ArmsToolpath
    from robot.loads import payload_record, toolpath_loads
    from robot.motion import toolpath_cycle_time
    from robot.panel_placement import placed_cell, placement_of
    from robot.sheet_program import DEFAULT_TOOL_MASS, grip_side_of, sheet_record
    from robot.two_arm_planner import lockstep_timing
    from robot.ur_motion import PayloadError

    mass = DEFAULT_TOOL_MASS if tool_mass is None else float(tool_mass)
    placed = placed_cell(cell, placement_of(atp.extra))
    shares = holder_shares(design_model, spec, grips)
    flat = design_model.mesh()
    whole = panel_mass(spec, flat.vertices, flat.triangulate()[0])
    arms, reports, split = [], [], {}
    for name, tp in atp.arms:
        share = shares[name] if shares is not None else HolderShare(whole.mass, whole.cog, {})
        split[name] = {"panel_kg": share.mass, "strips": {str(k): v for k, v in share.strips.items()}}
        payload = payload_record(arm_cell(placed, name), tp.waypoints, share.mass, share.cog, mass)
        payload["note"] = ("held = tool + this arm's share of the panel (robot.arms_sheet.holder_shares: the strips "
                           "nearest its grip); tool CoG half-way to the TCP" if shares is not None else
                           "held = tool + the whole panel (no strip tags to split it by); tool CoG half-way to the TCP")
        arm_tp = replace(tp, extra={**tp.extra, "payload": payload})
        try:  # the declared payload lowers the joint acceleration bound (robot.ur_motion)
            arm_tp = replace(arm_tp, extra={**arm_tp.extra, "cycle_time_s": toolpath_cycle_time(arm_tp).total})
        except PayloadError:  # over the arm's rating: the check refuses the toolpath and says so
            pass
        arms.append((name, arm_tp))
        reports.append((name, toolpath_loads(spec, design_model, compensated.creases, grips[name],
                                             arm_cell(placed, name), mass + share.mass, side=grip_side_of(tp),
                                             other_grips=tuple(f for n, f in grips.items() if n != name))))
    loads = ArmsLoadReport(arms=tuple(reports))
    if shares is not None:
        split[CLAMP] = {"panel_kg": shares[CLAMP].mass, "strips": {str(k): v for k, v in shares[CLAMP].strips.items()}}
    sheet = {**sheet_record(spec, compensated, tool_mass, design_surface, loads.summary()),
             "panel_kg": whole.mass, "panel_split": split if shares is not None else None}
    out = ArmsToolpath.build(atp.cell, atp.cell_sha256, atp.source, arms, atp.sync, {**atp.extra, "sheet": sheet})
    try:  # the lockstep program's duration under the declared payloads
        total = lockstep_timing(out)["total_s"]
    except PayloadError:  # over an arm's rating: the check refuses the toolpath and says so
        return out, loads
    return ArmsToolpath.build(atp.cell, atp.cell_sha256, atp.source, arms, atp.sync,
                              {**atp.extra, "sheet": sheet, "cycle_time_s": total}), loads
