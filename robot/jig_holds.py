"""Which face each jig of the cell holds, and on which moves: PATH.json's `holds.jigs`.

A jig (`[[jigs]]` in the cell, `robot.cell.Jig`) is a pad fixed in the cell. It holds the face
that lies on it: the face whose polygon carries the jig's footprint, in the footprint's plane,
with the panel where the program places it (PATH.json `placement`, else the cell's fixture). A jig
engages its face on every move during which the face lies on it in every fold state the move
passes through (a jig is switched on while the face rests on it and off before the face leaves),
so a face that a fold carries away from the pad is not held there. The rows have the shape of
the arms' rows: `holds.jigs = {jig name: [face or null per waypoint]}`, entry i the face the jig
holds on the move into waypoint i.

`sim.check_jigs` verifies the rows against the cell and the FOLD file, `sim.check_holds` counts
the jig-held faces among the held faces.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["JigContact", "face_motion", "jig_footprint_check", "jig_contacts", "jig_rows", "with_jig_holds",
           "JIG_TOL"]

#: The jig footprint may leave its face or its plane by this much [m] (a vacuum pad's lip compliance).
JIG_TOL = 5e-4


@dataclass(frozen=True)
class JigContact:
    """`face` (polygon id) lies on jig `name` in fold states `states` (sorted ints)."""

    name: str
    face: int
    states: tuple[int, ...]


def face_motion(fold_model, face: int, state: int) -> np.ndarray:
    """4x4 rigid motion of polygon `face` from the flat key frame to fold state `state` (panel frame):
    the least-squares fit of its vertices (Kabsch; a face is rigid in every state)."""
    from scipy.spatial.transform import Rotation

    from fabkit.frames import fold_positions
    from fabkit.hold_model_fold import fold_triangles

    tris, poly = fold_triangles(fold_model)
    verts = np.unique(tris[poly == face])
    if len(verts) == 0:
        raise ValueError(f"face {face} is not a face of the panel")
    A = np.asarray(fold_model.vertices_coords, np.float64)[verts]
    B = fold_positions(fold_model)[state][verts]
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    rot, _ = Rotation.align_vectors(B - cb, A - ca)
    T = np.eye(4)
    T[:3, :3] = rot.as_matrix()
    T[:3, 3] = cb - rot.as_matrix() @ ca
    return T


def jig_footprint_check(fold_model, fixture, jig, face: int, state: int, tol: float = JIG_TOL):
    """`fabkit.placement.ClampCheck` of `jig`'s footprint on polygon `face` in fold state `state`,
    the panel placed by `fixture` (panel frame -> world)."""
    from fabkit.placement import check_clamp_footprint
    from robot.panel_placement import clamped_face_ring

    ring = clamped_face_ring(fold_model, int(face))
    pts = np.column_stack([ring, np.zeros(len(ring))])
    moved = np.asarray(fixture, np.float64) @ face_motion(fold_model, int(face), int(state))
    return check_clamp_footprint(pts, np.arange(len(ring)), int(face), moved, jig.pose, jig.footprint, tol=tol)


def _candidate_faces(fold_model, fixture, jig, state: int) -> list[int]:
    """Faces whose plane in `state` passes within 1 cm of the footprint's centre and that reach it
    (their farthest corner from their centroid as far as the centre), nearest first."""
    from fabkit.frames import fold_positions
    from fabkit.hold_model_fold import fold_triangles

    tris, poly = fold_triangles(fold_model)
    P = fold_positions(fold_model)[state]
    centre = jig.pose @ np.append(np.asarray(jig.footprint, np.float64).mean(axis=0), [0.0, 1.0])
    local = (np.linalg.inv(np.asarray(fixture, np.float64)) @ centre)[:3]
    out = []
    for f in np.unique(poly):
        T = P[tris[poly == f]]
        n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]).sum(axis=0)
        if np.linalg.norm(n) == 0:
            continue
        n = n / np.linalg.norm(n)
        c = T.reshape(-1, 3).mean(axis=0)
        reach = float(np.linalg.norm(T.reshape(-1, 3) - c, axis=1).max())
        if abs((local - c) @ n) <= 0.01 and np.linalg.norm(local - c) <= reach:
            out.append((float(np.linalg.norm(local - c)), int(f)))
    return [f for _, f in sorted(out)]


def jig_contacts(fold_model, cell, fixture=None) -> tuple[JigContact, ...]:
    """For every jig of `cell`, the face lying on it (`jig_footprint_check` passes) and the fold
    states where it does; the face on the jig in the most states (ties: the lowest id). A jig no
    face lies on in any state is left out."""
    from fabkit.frames import fold_positions

    fx = cell.fixture if fixture is None else fixture
    n_states = len(fold_positions(fold_model))
    out = []
    for jig in cell.jigs:
        on: dict[int, list[int]] = {}
        for s in range(n_states):
            for f in _candidate_faces(fold_model, fx, jig, s):
                if jig_footprint_check(fold_model, fx, jig, f, s).ok:
                    on.setdefault(f, []).append(s)
                    break
        if on:
            face = min(on, key=lambda f: (-len(on[f]), f))
            out.append(JigContact(jig.name, int(face), tuple(on[face])))
    return tuple(out)


def move_state_ranges(states, ops) -> list[tuple[int, int]]:
    """(lowest, highest) integer fold state each move into waypoint i passes through, from the
    waypoints' `state` labels: a `fold` waypoint with the label of the one before it is a point the
    planner inserted between that state and the next (`sim.toolpath_program.fold_progress`)."""
    out = [(int(states[0]), int(states[0]))]
    for i in range(1, len(states)):
        lo, hi = sorted((int(states[i - 1]), int(states[i])))
        if states[i] == states[i - 1] and ops[i] == "fold":
            hi += 1
        out.append((lo, hi))
    return out


def jig_rows(contacts, states, ops) -> dict:
    """`holds.jigs` for waypoint `states` labels and `ops`: each jig holds its face on the moves whose
    fold states all have the face on the jig (module docstring)."""
    ranges = move_state_ranges(states, ops)
    rows = {}
    for c in contacts:
        on = set(c.states)
        rows[c.name] = [c.face if all(s in on for s in range(lo, hi + 1)) else None for lo, hi in ranges]
    return rows


def with_jig_holds(tp, cell, fold_model):
    """Toolpath `tp` with `holds.jigs` recorded for the jigs of `cell` (the panel where `tp`'s
    `placement` puts it) and the whole-document hash recomputed; `tp` itself when the cell has no
    jig, `tp` records no holds (planned before the planner wrote them) or no face lies on a jig."""
    from robot.panel_placement import placed_cell, placement_of
    from robot.toolpath import Toolpath

    if not getattr(cell, "jigs", ()) or not isinstance(tp.extra.get("holds"), dict):
        return tp
    placed = placed_cell(cell, placement_of(tp.extra))
    contacts = jig_contacts(fold_model, placed)
    if not contacts:
        return tp
    holds = dict(tp.extra["holds"])
    holds["jigs"] = jig_rows(contacts, [w.state for w in tp.waypoints], [w.op for w in tp.waypoints])
    return Toolpath(tp.robot, tp.cell, tp.tcp, tp.source, tp.waypoints, {**tp.extra, "holds": holds},
                    tp.cell_sha256)
