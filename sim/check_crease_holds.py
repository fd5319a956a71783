"""What folds each crease, per run of moves: CHECK.json's `holds.creases`.

For every run of consecutive moves that carry the panel (its fold state changes) with one set of
holds (the clamped faces, each arm's face, each jig's face: PATH.json `holds`), one record: the
waypoints, the fold states, the holds, and per crease row the fold angle at the run's first and
last state and the holds on each side of its cut (`fabkit.crease_holds`). The verdict (a side held
by nothing) is the holds check's (`sim.check_holds`); this record says who holds what, for people
and report.html.
"""
from __future__ import annotations

import numpy as np

__all__ = ["hold_labels", "crease_records"]


def hold_labels(record: dict, i: int) -> tuple[tuple[str, int], ...]:
    """(label, face) of every hold on the move into waypoint i: "clamp", "arm a", "jig NAME"."""
    out = [("clamp", int(f)) for f in record.get("clamped_faces", [])]
    for key, role in (("arms", "arm"), ("jigs", "jig")):
        for name, row in record.get(key, {}).items():
            if row[i] is not None:
                out.append((f"{role} {name}", int(row[i])))
    return tuple(out)


def crease_records(fold_model, record: dict, states) -> list[dict]:
    """The `holds.creases` records (module docstring) of a holds `record` (CHECK.json `holds`) over
    waypoint fold `states` (fractional)."""
    from fabkit.crease_holds import crease_holds, crease_sides
    from fabkit.frames import fold_positions
    from fabkit.hold_model_fold import hold_model_from_fold

    model, angles = hold_model_from_fold(fold_model)
    if len(fold_positions(fold_model)) == len(angles) + 1:   # a flat key frame put first
        angles = np.vstack([np.zeros_like(angles[:1]), angles])
    sides = crease_sides(model)
    st = np.asarray(states, np.float64)
    runs: list[list] = []
    for i in range(1, len(st)):
        if abs(st[i] - st[i - 1]) <= 1e-12:
            continue
        holds = hold_labels(record, i)
        lo, hi = min(st[i - 1], st[i]), max(st[i - 1], st[i])
        if runs and runs[-1][1] == i - 1 and runs[-1][4] == holds:
            runs[-1][1], runs[-1][2], runs[-1][3] = i, min(runs[-1][2], lo), max(runs[-1][3], hi)
        else:
            runs.append([i, i, lo, hi, holds])
    out = []
    for first, last, lo, hi, holds in runs:
        a = min(int(np.floor(lo + 1e-9)), len(angles) - 1)
        b = min(int(np.ceil(hi - 1e-9)), len(angles) - 1)
        creases = []
        for c in crease_holds(model, holds, sides):
            hinges = model.rows[c.crease]
            worst = hinges[np.argmax(np.abs(angles[a:b + 1][:, hinges]).max(axis=0))]
            creases.append({**c.to_json(), "angle_deg": [float(np.degrees(angles[a, worst])),
                                                          float(np.degrees(angles[b, worst]))]})
        out.append({"waypoints": [first, last], "states": [float(lo), float(hi)],
                    "holds": [f"{label} face {f}" for label, f in holds], "creases": creases})
    return out
