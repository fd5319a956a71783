"""The cup on the grip faces, as a check: every face an arm grips must carry the arm's cup.

The cup's disc (the cell's `tool.cup_radius`) about the grip face's centre, where the planner puts
the TCP, must lie on the sheet up to the creases and the outline and stay planar to the lip
compliance in every fold state (`fabkit.grip_footprint.cup_fit`). A grip on a sliver, across a
crease or over the outline is a `holds` problem from the first waypoint that arm grips the face.
A sheet program's pad is checked with its fold loads instead (`sim.check_loads`). What is not
modelled here: the seal itself and the holding force against the panel's weight and the fold loads
of a rigid program.
"""
from __future__ import annotations

from sim.problems import Problem

__all__ = ["cup_problems"]


def cup_problems(fold_model, holds: dict, cup_radius_of) -> tuple[dict | None, list[Problem]]:
    """(CHECK.json `holds.cup_footprint` record, problems) for a holds record
    (`robot.holds_record`: `arms` {arm: [face or None per waypoint]}); `cup_radius_of(arm)` is that
    arm's cup radius [m] (None: the arm has no cup declared, nothing is checked for it). The record
    holds one entry per arm with a cup (`{arm: record}`) when arms' cups differ, else one record."""
    from fabkit.grip_footprint import cup_fit, cup_footprint_record

    arms = {str(a): list(row) for a, row in holds.get("arms", {}).items()}
    radii = {a: cup_radius_of(a) for a in arms}
    records, problems, fits = {}, [], {}
    for arm, row in arms.items():
        if radii[arm] is None:
            continue
        if radii[arm] not in fits:   # arms with the same cup share its measurements
            fits[radii[arm]] = cup_fit(fold_model, radii[arm])
        rec = cup_footprint_record(fold_model, {"arms": {arm: row}}, radii[arm], fit=fits[radii[arm]])
        if rec is None:
            continue
        records[arm] = rec
        for face in (f for f in rec["faces"] if not f["ok"]):
            held = [i for i, g in enumerate(row) if g is not None and int(g) == face["face"]]
            who = f"arm {arm}: " if len(arms) > 1 else ""
            problems.append(Problem(waypoint=held[0], kind="holds", subject=f"cup × face_{face['face']}",
                                    last_waypoint=held[-1], value=face["room_mm"] / 1000,
                                    detail=f"{who}grip face {face['face']}: {face['problem']}: the cup cannot "
                                           "hold it (choose another grip face, a smaller cup or a pad)"))
    if not records:
        return None, []
    if len(records) == 1 or len({(r["cup_mm"], r["lip_compliance_mm"]) for r in records.values()}) == 1:
        first = next(iter(records.values()))
        faces = {f["face"]: f for r in records.values() for f in r["faces"]}
        return {**first, "faces": [faces[k] for k in sorted(faces)]}, problems
    return records, problems
