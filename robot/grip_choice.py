"""Which grip faces and approach distances the planner tries, in which order.

`grip_order`: the middle-row faces that move, largest motion first (the far end of the row, refold
clamping the first strip); `approach_variants`: other approach/retract distances for a face that
does not plan or pass at the given one. `robot.planner.plan_panel` tries them in this order, and
with the checker (`sim.grip_search`) takes the first whose program passes the check.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from fabkit.errors import InputError

__all__ = ["grip_order", "approach_variants"]


def approach_variants(options):
    """Other approach/retract distances to try when a face does not plan or pass at the given one
    (a retract line through a near-singularity, the tool retracting into the folded panel)."""
    d = options.approach_distance
    return tuple(replace(options, approach_distance=x) for x in (0.6 * d, 1.6 * d))


def grip_order(frames, grip_face: int | None = None) -> list[int]:
    """The grip faces `plan_panel` tries, in order: `grip_face` alone when given (`InputError` if it
    is not a middle-row face), else the middle-row faces that move, largest motion first (more
    leverage far from the clamp; the far end of the row first), ties by the face frames' turn."""
    faces = [int(f) for f in frames.faces]
    if grip_face is not None:
        if int(grip_face) not in faces:
            raise InputError(f"face {grip_face} is not a middle-row face (middle row: {faces})", source="--grip-face")
        return [int(grip_face)]
    C = frames.frames[:, :, :3, 3]
    Z = frames.frames[:, :, :3, 2]
    turn = np.arccos(np.clip(np.einsum("ski,ki->sk", Z, Z[0]), -1.0, 1.0)).max(axis=0)
    motion = np.linalg.norm(C - C[0], axis=-1).max(axis=0) + 1e-6 * turn
    moving = [faces[k] for k in np.argsort(-motion, kind="stable") if motion[k] > 1e-9]
    return moving or faces
