"""A PATH.json toolpath as the checker's arrays, and the panel of the FOLD file it was planned from.

`program_from_toolpath` refuses a toolpath planned for another robot model or TCP (checking it
would check the wrong machine). `load_source_panel` finds the FOLD file the toolpath's `source`
names (or the one given), verifies its sha256 against the one recorded at planning, refuses
non-finite or absurd coordinates, and builds the panel the check poses with the fold states.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fabkit.errors import InputError
from robot.cell import file_sha256, pose_to_matrix
from robot.motion import payload_accel_bounds
from robot.toolpath import fold_file_of
from robot.ur_motion import PayloadError
from sim.interpolate import Program
from sim.panel import DEFAULT_THICKNESS, PanelModel, check_fold_coordinates, panel_from_fold

__all__ = ["program_from_toolpath", "fold_progress", "fold_file_of", "grip_face_of", "load_source_fold", "source_panel",
           "load_source_panel"]


def program_from_toolpath(tp, cell, sha256: str | None = None) -> Program:
    """Arrays of a `robot.toolpath.Toolpath` for `cell`; `InputError` if it was planned for another
    robot model or another TCP (checking it here would check the wrong machine). `sha256`: the
    toolpath's hash when the caller computed it already."""
    if tp.robot != cell.model.name:
        raise InputError(f"toolpath is for a {tp.robot}, the cell {cell.name!r} has a {cell.model.name}",
                         source=cell.source)
    tcp = pose_to_matrix(tp.tcp)
    if not np.allclose(tcp, cell.tool.tcp, atol=1e-9):
        raise InputError(f"toolpath TCP {list(np.round(tp.tcp, 6))} differs from the cell's tool TCP "
                         "(planned for another tool)", source=cell.source)
    W = tp.waypoints
    poses = np.array([pose_to_matrix(w.pose) for w in W])
    grip = tp.extra.get("grip", {}) if isinstance(tp.extra, dict) else {}
    if not (isinstance(grip, dict) and all(isinstance(grip.get(k, 0.0), (int, float)) and not isinstance(
            grip.get(k, 0.0), bool) and 0 <= grip.get(k, 0.0) < 60 for k in ("grip_dwell_s", "release_dwell_s"))):
        raise InputError("grip: expected an object with grip_dwell_s and release_dwell_s in seconds (0..60)")
    dwell = np.array([float(grip.get("grip_dwell_s", 0.0)) if w.op == "grip" else
                      float(grip.get("release_dwell_s", 0.0)) if w.op == "release" else 0.0 for w in W])
    try:
        bound = payload_accel_bounds(tuple(w.op for w in W), tp.extra.get("payload"), tp.robot)
    except (PayloadError, KeyError, TypeError, ValueError) as exc:
        raise InputError(f"payload: {exc}") from None
    states = fold_progress(np.array([w.state for w in W], dtype=np.float64), tuple(w.op for w in W),
                           poses[:, :3, 3])
    return Program(poses=poses, q=np.array([w.q for w in W], dtype=np.float64).reshape(-1, 6),
                   moves=tuple(w.move for w in W), v=np.array([w.v for w in W], dtype=np.float64),
                   a=np.array([w.a for w in W], dtype=np.float64), states=states, tcp=tcp,
                   ops=tuple(w.op for w in W), sha256=sha256 if sha256 is not None else tp.sha256,
                   r=np.array([w.r for w in W], dtype=np.float64), dwell=dwell, accel_bound=bound)


def fold_progress(states: np.ndarray, ops, positions: np.ndarray) -> np.ndarray:
    """Fractional fold states for the waypoints that subdivide a fold move.

    The planner labels the points it inserts between fold states s and s+1 with the state being
    left (s). The tool is on the straight line between the two states' grip poses there, so the
    panel is posed at s + (TCP travel so far / travel of the whole move) to stay with the tool.
    """
    out = np.asarray(states, dtype=np.float64).copy()
    n = len(out)
    i = 0
    while i < n:
        j = i
        while j + 1 < n and states[j + 1] == states[i] and ops[j + 1] == "fold":
            j += 1
        nxt = j + 1
        if j > i and nxt < n and ops[nxt] in ("fold", "release") and states[nxt] == states[i] + 1:
            seg = np.linalg.norm(np.diff(positions[i:nxt + 1], axis=0), axis=1)
            total = seg.sum()
            if total > 0:
                out[i + 1:nxt] = states[i] + np.cumsum(seg)[:-1] / total
        i = j + 1
    return out


def grip_face_of(tp):
    """The grip face id (polygon id) a toolpath names in `source` or its `grip` block, or None."""
    for block in (tp.source if isinstance(tp.source, dict) else {}, tp.extra.get("grip", {}) or {}):
        face = block.get("grip_face", block.get("face")) if isinstance(block, dict) else None
        if isinstance(face, int) and not isinstance(face, bool) and face >= 0:
            return face
    return None


def load_source_fold(tp, fold: str | Path | None = None, *, base_dir: str | Path | None = None):
    """The FOLD model the toolpath was planned from: `(model, path, sha256)`, `(None, None, None)`
    when the toolpath names none and `fold` is None. `fold` overrides the file the source names;
    either way its sha256 must equal the one the toolpath recorded (`source.sha256`) when it
    recorded one. `InputError` for a missing or changed file and non-finite or absurd coordinates."""
    from fabkit.io.fold import load_fold

    path = Path(fold) if fold is not None else fold_file_of(tp, base_dir)
    if path is None:
        return None, None, None
    if not path.exists():
        raise InputError("FOLD file named by the toolpath's source not found (pass --fold or --no-panel)"
                         if fold is None else "FOLD file not found", source=str(path))
    got = file_sha256(path)
    want = tp.fold_sha256
    if want is not None and got != want:
        raise InputError(f"FOLD file has sha256 {got[:12]}…, the toolpath was planned from {want[:12]}… "
                         "(the fold states changed since planning)", source=str(path))
    model = load_fold(path)
    check_fold_coordinates(model, source=str(path))
    return model, path, got


def source_panel(tp, cell, model, path, thickness: float | None = None, offset: float = 0.0) -> PanelModel:
    """The panel the check poses: `model`'s faces in its fold states (the design states, or the
    springback-compensated ones a sheet program follows), `thickness` [m] thick, its slab centred
    `offset` [m] along the faces' front normals. `InputError` for a grip face not in the panel or
    too few states."""
    from dataclasses import replace

    from robot.phased_planner import phases_of

    try:
        phases = phases_of(tp)
    except ValueError as exc:
        raise InputError(str(exc), source="PATH.json") from None
    try:
        panel = panel_from_fold(model, cell.fixture, grip_face_id=None if phases else grip_face_of(tp),
                                thickness=thickness or DEFAULT_THICKNESS, source=str(path), offset=offset)
    except ValueError as exc:
        raise InputError(str(exc), source=str(path)) from None
    if phases:   # phases grip different faces: the tool's contact is excluded with the phase's face
        ids, grip = list(panel.face_ids), [-1] * len(tp.waypoints)
        for ph in phases:
            if ph["face"] not in ids:
                raise InputError(f"grip face {ph['face']} is not a face of the panel", source=str(path))
            for i in range(ph["waypoints"][0], ph["waypoints"][1] + 1):
                grip[i] = ids.index(ph["face"])
        panel = replace(panel, grip_by_waypoint=tuple(grip))
    top = max((w.state for w in tp.waypoints), default=0)
    if top > panel.n_states - 1:
        raise InputError(f"the toolpath uses fold state {top} but the file has {panel.n_states} states",
                         source=str(path))
    return panel


def load_source_panel(tp, cell, fold: str | Path | None = None, *, base_dir: str | Path | None = None,
                      thickness: float | None = None) -> tuple[PanelModel | None, Path | None, str | None]:
    """The panel of the toolpath's FOLD file (`load_source_fold`, `source_panel`): `(panel, path,
    sha256)`, `(None, None, None)` when the toolpath names none and `fold` is None."""
    model, path, got = load_source_fold(tp, fold, base_dir=base_dir)
    if model is None:
        return None, None, None
    return source_panel(tp, cell, model, path, thickness), path, got
