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
    # only pairs of parts of different arms: arm k's parts have contype bit k and collide with
    # every other arm's bit (obstacles, panel and each arm's own parts are not paired here)
    bits = np.where(owner >= 0, 1 << np.clip(owner, 0, 30), 0)
    every = int(np.bitwise_or.reduce(bits[owner >= 0])) if np.any(owner >= 0) else 0
    saved = m.geom_contype.copy(), m.geom_conaffinity.copy()
    m.geom_contype[:] = bits
    m.geom_conaffinity[:] = np.where(owner >= 0, every & ~bits, 0)
    out = []
    rows = np.concatenate(Q, axis=1)
    try:
        for k in range(M):
            d.qpos[:] = rows[k]
            mujoco.mj_kinematics(m, d)
            mujoco.mj_collision(m, d)
            if d.ncon == 0:
                continue
            geoms, dist = d.contact.geom[:d.ncon], d.contact.dist[:d.ncon]
            for (g0, g1), dd in zip(geoms, dist):
                a, b = owner[g0], owner[g1]
                if a >= 0 and b >= 0 and a != b and dd < clearance:
                    ga, gb = (g0, g1) if a < b else (g1, g0)
                    out.append(ArmContact(k, (names.geom[ga], names.geom[gb]), float(dd)))
    finally:
        m.geom_contype[:], m.geom_conaffinity[:] = saved
    return out
