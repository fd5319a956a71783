"""Does the program hold the panel while it folds it? The holds part of the check.

From PATH.json's `holds` record (`robot.holds_record`: the clamped faces, and per arm and waypoint
the face it holds) and the FOLD file the program was planned from, every move that carries the
panel (its fold state changes) is a span of fold states with one set of held faces: the clamped
faces plus each arm's face. `fabkit.holds.holds_along` proves, at every state of the span and at
one point inside every step, that these faces fix the rigid panel (no crease row with a side held
by nothing, and no first-order free motion in a folded state). A span that fails is one problem
naming the crease left free (or the free motion) and the waypoints of the moves. Clamped faces
must not move in the fold states (the states are expressed in the clamp's frame): one that does is
a problem too.

What is modelled is `fabkit.holds`'s rigid-panel model (docs/holds.md): gravity, friction, the
sheet's elastic sag and how firmly a cup seals are not. States the panel is not moved through
(the flat panel before the grip, the folded panel after the release) are not tested: the panel
does not move there. A toolpath whose PATH.json has no `holds` record (planned before the planner
wrote one) gets the record derived from its grip face and the FOLD file's clamped face (noted).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabkit.errors import InputError
from sim.problems import Problem

__all__ = ["HoldsCheck", "check_holds", "clamp_problems", "CLAMP_MOTION_TOL"]

#: A clamped face may move this much [m] between fold states (well inside a jaw's compliance): refold
#: fixes one triangle of it, and
#: the other triangles of a quad that is not exactly planar turn about the diagonal by round-off.
CLAMP_MOTION_TOL = 1e-4


@dataclass(frozen=True)
class HoldsCheck:
    """`record` CHECK.json's `holds` value; `problems` (kind "holds"); `notes`."""

    ok: bool
    record: dict
    problems: tuple[Problem, ...]
    notes: tuple[str, ...] = ()


def _spans(states: np.ndarray, held: list[tuple[int, ...]]) -> list[tuple[int, int, float, float, tuple]]:
    """(first waypoint, last waypoint, lowest state, highest state, held faces) of every run of
    consecutive moves that carry the panel (state changes) with the same held faces."""
    out = []
    for i in range(1, len(states)):
        s0, s1 = float(states[i - 1]), float(states[i])
        if abs(s1 - s0) <= 1e-12:
            continue
        lo, hi = min(s0, s1), max(s0, s1)
        if out and out[-1][1] == i - 1 and out[-1][4] == held[i]:
            a, _, l0, h0, h = out[-1]
            out[-1] = (a, i, min(l0, lo), max(h0, hi), h)
        else:
            out.append((i, i, lo, hi, held[i]))
    return out


def _state_json(s: float, rep) -> dict:
    d = rep.to_json()
    d.pop("second_states", None)
    return {"state": float(s), **d}


def check_holds(tp, fold_model, states, *, source: str | None = None) -> HoldsCheck:
    """The holds check of toolpath `tp` (a `robot.toolpath.Toolpath`) against its FOLD model, with
    `states` the fractional fold state of every waypoint (`sim.interpolate.Program.states`)."""
    from fabkit.frames import fold_positions
    from fabkit.hold_model_fold import hold_model_from_fold
    from fabkit.holds import holds_along
    from robot.holds_record import clamped_faces_of, holds_of, holds_record
    from sim.toolpath_program import grip_face_of

    notes = []
    try:
        rec = holds_of(tp.extra, len(tp))
    except ValueError as exc:
        raise InputError(str(exc), source=source) from None
    if rec is None:
        rec = holds_record([w.op for w in tp.waypoints], grip_face_of(tp), clamped_faces_of(fold_model))
        notes.append("the toolpath records no holds: derived from its grip face and the FOLD file's clamped face")
    clamped = tuple(int(f) for f in rec["clamped_faces"])
    arms = {str(a): list(row) for a, row in rec["arms"].items()}
    jigs = {str(j): list(row) for j, row in rec.get("jigs", {}).items()}   # jig-held faces (robot.jig_holds)
    held = [tuple(sorted(set(clamped) | {row[i] for row in (*arms.values(), *jigs.values()) if row[i] is not None}))
            for i in range(len(tp))]
    out = {"ok": True, "clamped_faces": list(clamped), "arms": arms, **({"jigs": jigs} if jigs else {}),
           "recorded": "holds" in tp.extra, "states": []}
    problems: list[Problem] = []
    try:
        model, angles = hold_model_from_fold(fold_model, source=source)
    except InputError as exc:
        problems.append(Problem(waypoint=0, kind="holds", detail=f"the holds cannot be proven: {exc}",
                                last_waypoint=len(tp) - 1, subject="holds model"))
        out["ok"] = False
        return HoldsCheck(False, out, tuple(problems), tuple(notes))
    positions = fold_positions(fold_model)
    if len(positions) == len(angles) + 1:        # a flat key frame put first (fabkit.frames.fold_positions)
        angles = np.vstack([np.zeros_like(angles[:1]), angles])
    faces = set(int(f) for f in np.unique(model.tri_face))
    for f in sorted(set(clamped) | {x for row in (*arms.values(), *jigs.values()) for x in row if x is not None}):
        if f not in faces:
            raise InputError(f"holds: face {f} is not a face of the panel", source=source)
    for f in clamped:
        verts = np.unique(model.tris[model.tri_face == f])
        move = float(np.linalg.norm(positions[:, verts] - positions[:1, verts], axis=2).max())
        if move > CLAMP_MOTION_TOL:
            problems.append(Problem(waypoint=0, kind="holds", subject=f"clamp on face {f}", last_waypoint=len(tp) - 1,
                                    value=move, detail=f"the clamped face {f} moves {move * 1000:.3g} mm in the fold "
                                    "states: they are not in the clamp's frame"))
    for first, last, lo, hi, hold in _spans(np.asarray(states, np.float64), held):
        a, b = int(np.floor(lo + 1e-9)), int(np.ceil(hi - 1e-9))
        if not hold:
            problems.append(Problem(waypoint=first, kind="holds", subject="nothing held", last_waypoint=last,
                                    detail=f"fold states {a}-{b}: the panel moves and nothing holds it"))
            continue
        reports = holds_along(model, angles[a:b + 1], hold, between=1)
        bad: dict = {}
        for s, rep in reports:
            out["states"].append({"waypoints": [first, last], **_state_json(a + s, rep)})
            if rep.ok:
                continue
            subjects = [f"crease {r}" for r in rep.unheld_creases] + (["free motion"] if len(rep.problems) >
                                                                     len(rep.unheld_creases) else [])
            for subject, msg in zip(subjects, rep.problems):
                if subject not in bad:
                    bad[subject] = [a + s, a + s, msg, rep.sigma_zero if subject == "free motion" else None]
                bad[subject][1] = a + s
        for subject, (s0, s1, msg, value) in bad.items():
            where = f"fold state {s0:g}" if s0 == s1 else f"fold states {s0:g}-{s1:g}"
            problems.append(Problem(waypoint=first, kind="holds", subject=subject, last_waypoint=last, value=value,
                                    detail=f"{where}, held faces {list(hold)}: {msg}"))
    out["ok"] = not problems
    return HoldsCheck(not problems, out, tuple(problems), tuple(notes))


def clamp_problems(fold_model, cell, clamped_faces, n_waypoints: int) -> tuple[Problem, ...]:
    """Does the cell's clamp footprint lie on the clamped faces, with the panel where `cell.fixture`
    puts it? One problem (kind "holds", subject "clamp") when it leaves them or their plane; none
    for a cell without a clamp (nothing to compare)."""
    from robot.panel_placement import footprint_check

    if getattr(cell, "clamp", None) is None or not clamped_faces:
        return ()
    res = footprint_check(fold_model, cell, list(clamped_faces))
    return tuple(Problem(waypoint=0, kind="holds", subject="clamp", last_waypoint=n_waypoints - 1,
                         value=res.outside_m, detail=f"{msg}: the clamp does not hold the face the fold states fix")
                 for msg in res.problems)
