"""What holds the panel at every waypoint: PATH.json's `holds` record.

`holds` = `{"clamped_faces": [face, ...], "arms": {arm: [face or null per waypoint]}}`. Faces are
the FOLD file's polygon ids (`faces_fabkit:polygon`, the ids `grip.face` uses). Entry i of an arm
is the face that arm holds while it moves to waypoint i and on arrival there: the gripper output
switches on after arriving at `grip` and off after arriving at `release`, so an arm holds its grip
face on the moves into `fold` and `release` waypoints and nothing on the others. The clamped faces
are held throughout. A cell with jigs adds `"jigs": {jig: [face or null per waypoint]}` (the same
shape as an arm's row: the face the jig holds on the move into waypoint i; `robot.jig_holds`). The
record is an extra key of the document, so the whole-document hash covers it; `sim.check_holds`
proves from it that the holds fix the panel in every state it moves through.
"""
from __future__ import annotations

__all__ = ["HOLDING_OPS", "holds_record", "holds_of", "clamped_faces_of"]

#: Ops whose incoming move carries the panel with the gripper on.
HOLDING_OPS = ("fold", "release")


def holds_record(ops, grip_face: int | None, clamped_faces=(), arm: str = "a") -> dict:
    """The `holds` record of a one-arm program with waypoint `ops` gripping `grip_face` (None or
    negative: the arm holds nothing) with `clamped_faces` clamped."""
    face = None if grip_face is None or int(grip_face) < 0 else int(grip_face)
    held = [face if op in HOLDING_OPS else None for op in ops]
    return {"clamped_faces": sorted({int(f) for f in clamped_faces}), "arms": {str(arm): held}}


def holds_of(extra: dict, n_waypoints: int) -> dict | None:
    """The validated `holds` record of a toolpath's extra keys, or None if it has none; `ValueError`
    naming the key for a malformed one."""
    h = extra.get("holds") if isinstance(extra, dict) else None
    if h is None:
        return None

    def face_ok(f):
        return isinstance(f, int) and not isinstance(f, bool) and f >= 0

    if not isinstance(h, dict) or not isinstance(h.get("clamped_faces"), list) or not isinstance(h.get("arms"), dict):
        raise ValueError("holds: expected {clamped_faces: [face ids], arms: {arm: [face or null per waypoint]}}")
    if not all(face_ok(f) for f in h["clamped_faces"]):
        raise ValueError("holds.clamped_faces: expected face ids (integers >= 0)")
    if not isinstance(h.get("jigs", {}), dict):
        raise ValueError("holds.jigs: expected {jig: [face or null per waypoint]}")
    for key in ("arms", "jigs"):
        for arm, row in h.get(key, {}).items():
            if not isinstance(row, list) or len(row) != n_waypoints:
                raise ValueError(f"holds.{key}.{arm}: expected one entry per waypoint ({n_waypoints})")
            if not all(f is None or face_ok(f) for f in row):
                raise ValueError(f"holds.{key}.{arm}: expected face ids or null")
    return h


def clamped_faces_of(fold_model, tol: float = 1e-9) -> tuple[int, ...]:
    """The clamped faces of a FOLD file: `file_fabkit:fixed_face` as `fabkit refold` writes it (the
    fold states are in its frame); for a file that names none, the faces (polygon ids) whose
    vertices stay within `tol` [m] of their first position in every state, the faces the states
    hold still."""
    import numpy as np

    from fabkit.frames import face_groups, fold_positions

    f = fold_model.file_data.get("fabkit:fixed_face")
    if isinstance(f, int) and not isinstance(f, bool) and f >= 0:
        return (int(f),)
    P = fold_positions(fold_model)
    still = np.linalg.norm(P - P[:1], axis=2).max(axis=0) <= tol
    groups = face_groups(fold_model.faces_vertices, fold_model.faces_data)
    return tuple(int(i) for i, v in zip(groups.ids, groups.vertices) if still[v].all())
