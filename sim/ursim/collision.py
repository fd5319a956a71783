"""Contacts of the simulated arm in the MuJoCo model of the cell (`sim.model.build_cell_model`).

The stand-in calls `CellCollision(cell)(q)` every controller period while the arm moves; a
penetrating contact between the arm or tool and the cell (obstacles, or the arm with itself)
triggers a protective stop, as a real controller stops when it detects a collision.
"""
from __future__ import annotations

import mujoco
import numpy as np

from sim.model import GROUP_ARM, GROUP_ENV, GROUP_TOOL, build_cell_model


class CellCollision:
    """Callable `q -> ("geomA × geomB", depth m)` of the deepest penetrating contact, or None."""

    def __init__(self, cell):
        self.model, self.names = build_cell_model(cell)
        self.data = mujoco.MjData(self.model)
        g = self.names.geom_group
        self.robot = (g == GROUP_ARM) | (g == GROUP_TOOL)
        self.env = g == GROUP_ENV

    def __call__(self, q) -> tuple[str, float] | None:
        m, d = self.model, self.data
        d.qpos[:6] = np.asarray(q, dtype=np.float64)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        n = d.ncon
        if not n:
            return None
        con = d.contact
        worst = None
        for g1, g2, dist in zip(con.geom1[:n], con.geom2[:n], con.dist[:n]):
            if dist >= 0:
                continue  # the environment margin reports near misses too: only penetration stops
            if (self.robot[g1] and (self.env[g2] or self.robot[g2])) or (self.robot[g2] and self.env[g1]):
                if worst is None or -dist > worst[1]:
                    worst = (f"{self.names.geom[g1]} × {self.names.geom[g2]}", float(-dist))
        return worst
