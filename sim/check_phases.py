"""The check of a program in phases, per phase: what CHECK.json's `phases` says.

A one-arm program in phases (`robot.phased_planner`: PATH.json `phases`) is checked as one program:
every move, the transfers between phases included, goes through the same interpolation, collision,
reach and speed checks, and the holds are proven on every move that carries the panel with the
faces held on it (`sim.check_holds`). This module adds the per-phase view: for each phase its grip
face and side, fold states and waypoints, the problems inside its waypoints, its smallest
clearance, whether the holds were proven in every state it folds through, and whether the
`holds` record names the phase's grip face on its holding moves (a record that names another face
is a problem). The transfer after a phase is reported with its waypoints, problems and clearance.
Between phases the panel stays in the state the phase ended in: nothing folds it, and no springback
is modelled.
"""
from __future__ import annotations

import math

from fabkit.errors import InputError
from sim.problems import Problem

__all__ = ["phases_check"]


def _span(report, lo: int, hi: int) -> dict:
    inside = [p for p in report.problems if lo <= p.waypoint <= hi]
    clear = [c for c in report.along_path.get("clearance_m", [])[lo:hi + 1] if c is not None]
    return {"waypoints": [lo, hi], "problems": len(inside),
            "min_clearance_m": min(clear) if clear else None}


def phases_check(tp, report) -> tuple[dict | None, tuple[Problem, ...]]:
    """(CHECK.json `phases` record or None for a program of one phase, problems) of toolpath `tp`
    checked as `report` (a `sim.check.CheckReport` with its holds record)."""
    from robot.holds_record import HOLDING_OPS
    from robot.phased_planner import phases_of

    try:
        phases = phases_of(tp)
    except ValueError as exc:
        raise InputError(str(exc), source="PATH.json") from None
    if phases is None:
        return None, ()
    ops = [w.op for w in tp.waypoints]
    rows = (report.holds or {}).get("arms", {}) if report.holds else {}
    row = next(iter(rows.values()), None)
    states = (report.holds or {}).get("states", [])
    out, problems = [], []
    for k, ph in enumerate(phases):
        lo, hi = ph["waypoints"]
        held = [i for i in range(lo, hi + 1) if ops[i] in HOLDING_OPS]
        wrong = [i for i in held if row is not None and row[i] != ph["face"]]
        if wrong:
            problems.append(Problem(waypoint=wrong[0], kind="holds", subject=f"phase {k}", last_waypoint=wrong[-1],
                                    detail=f"phase {k} grips face {ph['face']}, the holds record names "
                                    f"{row[wrong[0]]} on the move into waypoint {wrong[0]}"))
        proofs = [s for s in states if lo <= s["waypoints"][0] and s["waypoints"][1] <= hi]
        entry = {**{key: ph[key] for key in ("face", "side", "states")}, **_span(report, lo, hi),
                 "grips": sum(op == "grip" for op in ops[lo:hi + 1]),
                 "releases": sum(op == "release" for op in ops[lo:hi + 1]),
                 "holds_proven": bool(proofs) and all(s["ok"] for s in proofs), "hold_states": len(proofs)}
        if k + 1 < len(phases):
            nxt = phases[k + 1]["waypoints"][0]
            entry["transfer"] = _span(report, hi + 1, nxt - 1)
            entry["transfer"]["moves"] = [tp.waypoints[i].move for i in range(hi + 1, nxt)]
        out.append(entry)
    ok = all(e["problems"] == 0 and e["holds_proven"] and e.get("transfer", {}).get("problems", 0) == 0
             for e in out) and not problems
    return {"ok": ok, "count": len(out), "phases": out}, tuple(problems)
