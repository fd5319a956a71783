"""Pictures of a toolpath check: one waypoint as PNG (an offending pair in red) or the whole program
as MP4, drawn from the configurations the check went through (`sim.check.ToolpathCheck`).

`fabkit check --render` and `fabkit.pipeline.render` both draw through here. Offscreen OpenGL
(EGL or OSMesa) must be selectable (`sim.render.select_gl_backend`) before mujoco is imported.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fabkit.errors import InputError

__all__ = ["render_waypoint", "render_movie", "default_waypoint"]


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
    from sim.model import build_cell_model
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
    m, _ = build_cell_model(cell, run.panel, all_arms=dense.q.shape[1] > 6)  # a two-arm check: both arms
    w, h = size
    frame = next(iter(render_frames(m, cell, dense.q[j:j + 1], panel=run.panel, states=dense.state[j:j + 1],
                                    width=w, height=h, highlight=highlight)))
    write_png(path, frame)
    return {"path": str(path), "waypoint": k, "config": j, "highlight": list(highlight),
            "inside_move": not bool(dense.at_waypoint[j])}


def render_movie(run, cell, path: str | Path, size: tuple[int, int] = (640, 480), max_frames: int = 240,
                 advance=None) -> dict:
    """Write the whole checked program as an MP4 at 30 fps of program time, sped up to at most
    `max_frames` frames; `advance()` is called once per frame written. -> frames and speed-up."""
    from sim.model import build_cell_model
    from sim.render import movie_indices, render_frames, write_mp4

    if not 2 <= max_frames <= 10000:
        raise InputError(f"must be in 2..10000, got {max_frames}", source="--frames")
    dense = run.dense
    m, _ = build_cell_model(cell, run.panel, all_arms=dense.q.shape[1] > 6)  # a two-arm check: both arms
    idx, speedup = movie_indices(dense.dt, max_frames=max_frames)
    w, h = size
    frames = render_frames(m, cell, dense.q[idx], panel=run.panel, states=dense.state[idx], width=w, height=h)

    def counted():
        for frame in frames:
            yield frame
            if advance is not None:
                advance()

    n = write_mp4(path, counted())
    return {"path": str(path), "frames": n, "speedup": speedup}
