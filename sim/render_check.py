"""Pictures of a toolpath check: one waypoint as PNG (an offending pair in red) or the whole program
as MP4, drawn from the configurations the check went through (`sim.check.ToolpathCheck`).

Every arm of the cell is drawn (the arms the program does not drive stand at their `home`). The
held faces are drawn in their hold's colour, from the check's `holds` record (`sim.hold_colours`:
the clamp blue, each arm its own colour, each jig purple, the jig's body too), with a legend
naming the face each hold has in that frame; a grip, release or regrip is named in a banner (on
the PNG of that waypoint, and in the MP4 for the frames after it, which always include the frame
of the change). A face is coloured only while its hold holds it: the cup on a face before the
vacuum is on is not a hold.

`fabkit check --render` and `fabkit.pipeline.render` both draw through here. Offscreen OpenGL
(EGL or OSMesa) must be selectable (`sim.render.select_gl_backend`) before mujoco is imported.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fabkit.errors import InputError

__all__ = ["render_waypoint", "render_movie", "default_waypoint", "face_points", "project_scene", "picture_model"]

#: MP4 frames a grip-change banner stays up.
BANNER_FRAMES = 12


def _holds(run) -> dict | None:
    return getattr(run.report, "holds", None)


def face_points(panel, face_id: int, state: float, shrink: float = 0.6) -> np.ndarray:
    """World points (k + 1, 3) on a panel face at a fractional fold state: its centroid, then its
    corners pulled toward the centroid to `shrink` of the way (inside the face)."""
    from scipy.spatial.transform import Rotation

    f = list(panel.face_ids or range(len(panel.pieces))).index(int(face_id))
    pos, quat = panel.poses_at(float(state))
    R = Rotation.from_quat(np.asarray(quat[f])[[1, 2, 3, 0]]).as_matrix()
    local = np.asarray(panel.pieces.local_polygons[f], np.float64)
    pts = np.vstack([np.zeros((1, 3)), shrink * (local - local.mean(axis=0)) + local.mean(axis=0)])
    return pts @ R.T + pos[f]


def _colour_map(record: dict | None, cell, waypoint: int) -> dict:
    """{geom name: rgba} of the faces held at `waypoint`, and of the bodies of the jigs holding."""
    from fabkit.held_faces import held_faces
    from sim.hold_colours import colour_of

    out = {}
    for h in held_faces(record, waypoint):
        out[f"face_{h.face}"] = colour_of(record, h)
        if h.role == "jig" and hasattr(cell, "jig") and cell.jig(h.name) is not None and cell.jig(h.name).obstacle:
            out[cell.jig(h.name).obstacle] = colour_of(record, h)[:3] + (0.8,)
    return out


def project_scene(scene):
    """A copy of the two eye cameras of a MuJoCo scene (what `sim.render.project_points` reads; the
    scene itself is overwritten by the next frame)."""
    from types import SimpleNamespace

    keys = ("pos", "forward", "up", "frustum_center", "frustum_bottom", "frustum_top", "frustum_near")
    cams = [SimpleNamespace(**{k: np.array(getattr(scene.camera[i], k)) for k in keys}) for i in (0, 1)]
    return SimpleNamespace(camera=cams)


def picture_model(cell, panel):
    """The cell model the pictures draw: with every arm of the cell, and the panel."""
    from sim.model import build_cell_model

    m, _ = build_cell_model(cell, panel, all_arms=bool(getattr(cell, "extra_arms", ())))
    return m


def default_waypoint(run) -> int:
    """The waypoint a PNG shows by default: the first problem, else the middle of the fold (the
    panel half folded)."""
    report, prog = run.report, run.program
    folding = [i for i, op in enumerate(prog.ops) if op in ("fold", "release")]
    return report.problems[0].waypoint if report.problems else folding[len(folding) // 2] if folding else 0


def render_waypoint(run, cell, path: str | Path, size: tuple[int, int] = (640, 480),
                    waypoint: int | None = None) -> dict:
    """Write waypoint `waypoint` (default `default_waypoint`) of the checked program as a PNG; a
    problem at that waypoint draws its pair red and, by default, shows the first offending
    configuration (which may lie on the move into the waypoint). -> what was drawn."""
    from sim.render import render_frames, write_png

    report, prog, dense = run.report, run.program, run.dense
    k = default_waypoint(run) if waypoint is None else int(waypoint)
    if not 0 <= k < len(prog):
        raise InputError(f"waypoint {k} is outside 0..{len(prog) - 1}", source="--waypoint")
    hits = np.flatnonzero(dense.at_waypoint & (dense.waypoint == k))
    j = int(hits[0]) if len(hits) else None
    highlight = ()
    for p in report.problems:
        if p.waypoint == k:
            if p.pair:
                highlight = p.pair
            if waypoint is None and p.config is not None:
                j = int(p.config)
            break
    if j is None:
        raise InputError(f"waypoint {k} has no joint solution to draw", source="--waypoint")
    from fabkit.held_faces import grip_changes
    from sim.hold_colours import draw_legend
    from sim.render import project_points

    record = _holds(run)
    m = picture_model(cell, run.panel)
    w, h = size
    changes = [c.text for c in grip_changes(record) if c.waypoint == k]
    banner = "; ".join(changes) or f"waypoint {k} ({prog.ops[k]}), fold state {float(dense.state[j]):.2f}"
    scenes = []
    frame = next(iter(render_frames(m, cell, dense.q[j:j + 1], panel=run.panel, states=dense.state[j:j + 1],
                                    width=w, height=h, highlight=highlight,
                                    face_colours=lambda _: _colour_map(record, cell, k),
                                    on_scene=lambda _, scene: scenes.append(project_scene(scene)),
                                    overlay=lambda fr, _: draw_legend(fr, record, k, banner))))
    write_png(path, frame)
    from fabkit.held_faces import held_faces

    held = []
    for hold in held_faces(record, k) if run.panel is not None else []:
        px = project_points(scenes[0], face_points(run.panel, hold.face, float(dense.state[j])), w, h)
        held.append({"hold": hold.label, "face": hold.face, "pixels": px.round(1).tolist()})
    return {"path": str(path), "waypoint": k, "config": j, "highlight": list(highlight),
            "inside_move": not bool(dense.at_waypoint[j]), "held": held, "banner": banner}


def render_movie(run, cell, path: str | Path, size: tuple[int, int] = (640, 480), max_frames: int = 240,
                 advance=None) -> dict:
    """Write the whole checked program as an MP4 at 30 fps of program time, sped up to at most
    `max_frames` frames; `advance()` is called once per frame written. -> frames and speed-up."""
    from sim.render import movie_indices, render_frames, write_mp4

    if not 2 <= max_frames <= 10000:
        raise InputError(f"must be in 2..10000, got {max_frames}", source="--frames")
    from fabkit.held_faces import grip_changes
    from sim.hold_colours import draw_legend

    dense, record = run.dense, _holds(run)
    m = picture_model(cell, run.panel)
    changes = grip_changes(record)
    idx, speedup = movie_indices(dense.dt, max_frames=max(2, max_frames - len(changes)))
    # the frame of every grip change is shown: the first configuration of its waypoint
    at = {c: np.flatnonzero(dense.at_waypoint & (dense.waypoint == c.waypoint)) for c in changes}
    idx = np.unique(np.concatenate([idx, [int(a[0]) for a in at.values() if len(a)]]).astype(np.int64))
    banner_of = {}
    for c, a in at.items():
        if len(a):
            first = int(np.searchsorted(idx, a[0]))
            for f in range(first, min(first + BANNER_FRAMES, len(idx))):
                banner_of.setdefault(f, []).append(c.text)
    wps = dense.waypoint[idx]
    w, h = size
    frames = render_frames(m, cell, dense.q[idx], panel=run.panel, states=dense.state[idx], width=w, height=h,
                           face_colours=lambda f: _colour_map(record, cell, int(wps[f])),
                           overlay=lambda fr, f: draw_legend(fr, record, int(wps[f]), "; ".join(banner_of.get(f, []))))

    def counted():
        for frame in frames:
            yield frame
            if advance is not None:
                advance()

    n = write_mp4(path, counted())
    return {"path": str(path), "frames": n, "speedup": speedup, "grip_changes": [c.text for c in changes]}
