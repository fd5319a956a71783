"""Do the jigs hold what the program says they hold? The jig part of the check.

PATH.json's `holds.jigs` (`robot.jig_holds`) names, per jig of the cell and per waypoint, the face
the jig holds on the move into that waypoint. For every run of moves in which a jig holds a face,
every fold state those moves pass through must have the jig's footprint on that face, in its
plane (`robot.jig_holds.jig_footprint_check`, within `JIG_TOL`), with the panel where the check
places it, and the face must not move between those states (`CLAMP_MOTION_TOL`): the jig is fixed
in the cell. A jig the cell does not have is a problem too. `sim.check_holds` counts the jig-held
faces among the held faces; `sim.check_panel_collisions` exempts the held face (only that face)
against the jig's body while it lies on it; the arms against the jig's body are the arm check's
(it is one of the cell's obstacles).
"""
from __future__ import annotations

import numpy as np

from sim.problems import Problem

__all__ = ["jig_spans", "check_jigs", "extend_holds"]


def jig_spans(row, states) -> list[tuple[int, int, int, int, int]]:
    """(first waypoint, last waypoint, face, lowest state, highest state) of every run of moves in
    which a jig row holds one face; `states` the fractional fold state of every waypoint."""
    st = np.asarray(states, np.float64)
    out = []
    for i in range(1, len(row)):
        f = row[i]
        if f is None:
            continue
        lo = int(np.floor(min(st[i - 1], st[i]) + 1e-9))
        hi = int(np.ceil(max(st[i - 1], st[i]) - 1e-9))
        if out and out[-1][1] == i - 1 and out[-1][2] == f:
            a, _, _, l0, h0 = out[-1]
            out[-1] = (a, i, f, min(l0, lo), max(h0, hi))
        else:
            out.append((i, i, int(f), lo, hi))
    return out


def check_jigs(jig_rows: dict, fold_model, cell, states) -> tuple[dict, tuple[Problem, ...]]:
    """(CHECK.json `holds.jig_checks`, problems of kind "holds") for PATH.json's jig rows."""
    from fabkit.frames import fold_positions
    from fabkit.hold_model_fold import fold_triangles
    from robot.jig_holds import jig_footprint_check
    from sim.check_holds import CLAMP_MOTION_TOL

    record, problems = {}, []
    n = len(states)
    tris, poly = fold_triangles(fold_model)
    P = fold_positions(fold_model)
    for name, row in jig_rows.items():
        jig = cell.jig(name) if hasattr(cell, "jig") else None
        spans = jig_spans(row, states)
        if jig is None:
            problems.append(Problem(waypoint=spans[0][0] if spans else 0, kind="holds", subject=f"jig {name}",
                                    last_waypoint=n - 1, detail=f"the program holds a face with jig {name!r}, "
                                    "which the cell does not have"))
            record[name] = {"ok": False, "spans": []}
            continue
        out = []
        for first, last, face, lo, hi in spans:
            worst_out = worst_plane = 0.0
            bad = []
            for s in range(lo, hi + 1):
                res = jig_footprint_check(fold_model, cell.fixture, jig, face, s)
                worst_out, worst_plane = max(worst_out, res.outside_m), max(worst_plane, res.off_plane_m)
                if not res.ok:
                    bad.append(s)
            verts = np.unique(tris[poly == face])
            move = float(np.linalg.norm(P[lo:hi + 1, verts] - P[lo, verts], axis=2).max())
            ok = not bad and move <= CLAMP_MOTION_TOL
            where = f"fold states {lo}-{hi}" if lo != hi else f"fold state {lo}"
            if bad:
                problems.append(Problem(
                    waypoint=first, kind="holds", subject=f"jig {name}", last_waypoint=last,
                    value=max(worst_out, worst_plane),
                    detail=f"{where}: the footprint of jig {name} leaves face {face} (up to {worst_out * 1000:.1f} mm "
                           f"outside, {worst_plane * 1000:.1f} mm off its plane, in fold states {bad}): the jig does "
                           "not hold the face the program says it holds"))
            elif move > CLAMP_MOTION_TOL:
                problems.append(Problem(
                    waypoint=first, kind="holds", subject=f"jig {name}", last_waypoint=last, value=move,
                    detail=f"{where}: face {face}, held by jig {name}, moves {move * 1000:.3g} mm: a jig is fixed in "
                           "the cell"))
            out.append({"waypoints": [first, last], "face": face, "states": [lo, hi], "ok": ok,
                        "footprint_outside_m": worst_out, "footprint_off_plane_m": worst_plane, "face_motion_m": move})
        record[name] = {"ok": all(s["ok"] for s in out), "obstacle": jig.obstacle, "spans": out}
    return record, tuple(problems)


def extend_holds(holds, fold_model, cell, states):
    """`(holds, jig_holds, problems)`: the `sim.check_holds.HoldsCheck` with the jig checks
    (`jig_checks`, its `ok` false when one fails) and what folds each crease (`creases`,
    `sim.check_crease_holds`) added to its record; `jig_holds` {jig obstacle: [(face, (lowest,
    highest) fold state)]} for `sim.check_panel_collisions`; `problems` the jig problems."""
    from dataclasses import replace

    from sim.check_crease_holds import crease_records

    record, problems = check_jigs(holds.record.get("jigs", {}), fold_model, cell, states)
    rec = dict(holds.record)
    if record:
        rec.update(jig_checks=record, ok=rec["ok"] and not problems)
    if rec.get("states"):
        rec["creases"] = crease_records(fold_model, rec, states)
    jig_holds = {cell.jig(n).obstacle: [(x["face"], tuple(x["states"])) for x in r["spans"]]
                 for n, r in record.items() if cell.jig(n) is not None and cell.jig(n).obstacle}
    return replace(holds, record=rec), jig_holds, problems
