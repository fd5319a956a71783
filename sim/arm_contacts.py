"""Arm against arm in a cell with several arms: which parts of two arms (and their tools) touch.

Uses the cell model with every arm (`sim.model.build_cell_model(..., all_arms=True)`): MuJoCo pairs
the capsules of different arms and their tools like any two moving bodies. A contact counts when
its distance is below `clearance` (0: only touching or interpenetrating parts); the depth is
MuJoCo's penetration (m). Configurations are given per arm, in lockstep (row k of every arm's
joints is one moment of the program).
"""
from __future__ import annotations

from dataclasses import dataclass

import sim.gl_backend  # noqa: F401  (MUJOCO_GL before mujoco loads)
import mujoco
import numpy as np

from sim.model import build_cell_model

__all__ = ["ArmContact", "arm_arm_contacts"]


@dataclass(frozen=True)
class ArmContact:
    """Configuration index `config`, the two geoms (arm a's first), `distance_m` (negative: deep)."""

    config: int
    pair: tuple[str, str]
    distance_m: float


def _owner(names, m) -> np.ndarray:
    """Arm index of every geom: 0 the first arm and its tool, 1.. the extra arms, -1 anything else."""
    body_of = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in m.geom_bodyid]
    owner = np.full(m.ngeom, -1)
    for g, b in enumerate(body_of):
        if b in names.arm_bodies or b == names.tool_body:
            owner[g] = 0
        for k, e in enumerate(names.extra_arms, start=1):
            if b in e["bodies"] or b == e["tool_body"]:
                owner[g] = k
    return owner


def arm_arm_contacts(cell, joints: dict, clearance: float = 0.0, built=None) -> list[ArmContact]:
    """Contacts between parts of different arms. `joints`: arm name ("a", then the `[[arms]]`
    names) -> (M, 6) joint angles [rad]; every arm of the cell must be given. `built`: a model from
    `build_cell_model(cell, all_arms=True)` to reuse (its arm geoms' margins are raised to
    `clearance`)."""
    m, names = built if built is not None else build_cell_model(cell, all_arms=True)
    order = [n for n, _ in cell.arms]
    missing = [n for n in order if n not in joints]
    if missing:
        raise ValueError(f"no joints for arm {missing[0]!r} (arms: {', '.join(order)})")
    Q = [np.atleast_2d(np.asarray(joints[n], np.float64)) for n in order]
    M = len(Q[0])
    if any(q.shape != (M, 6) for q in Q):
        raise ValueError("every arm needs the same number of (6,) joint rows")
    owner = _owner(names, m)
    d = mujoco.MjData(m)
    m.geom_margin[owner >= 0] = np.maximum(m.geom_margin[owner >= 0], clearance)
    out = []
    for k in range(M):
        d.qpos[:] = np.concatenate([q[k] for q in Q])
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        for c in d.contact[:d.ncon]:
            a, b = owner[c.geom[0]], owner[c.geom[1]]
            if a >= 0 and b >= 0 and a != b and c.dist < clearance:
                ga, gb = (c.geom[0], c.geom[1]) if a < b else (c.geom[1], c.geom[0])
                out.append(ArmContact(k, (names.geom[ga], names.geom[gb]), float(c.dist)))
    return out
