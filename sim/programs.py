"""Synthetic robot programs over a cell's fixture, for exercising and benchmarking the checker.

`sweep_program` lays a smooth Lissajous sweep of tool-down (slightly tilting) TCP poses above the
fixture and solves them with `robot.kinematics` (nearest solution to the previous waypoint, the
first nearest the cell's home): a realistic dense `movel` program with known-good geometry.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from robot import kinematics as kin
from sim.interpolate import Program

__all__ = ["sweep_program", "program_from_poses", "toolpath_from_program"]


def program_from_poses(cell, poses_world: np.ndarray, *, move: str = "movel", v: float = 0.1, a: float = 1.2,
                       states=None, q_start=None) -> Program:
    """A program through TCP poses given in the world frame, joints by IK on the start's branch
    (nearest solution to the previous waypoint; the first from the cell's home or `q_start`).

    Waypoints without an IK solution get NaN joints (the check reports them as unreachable).
    """
    model = cell.model
    to_base = cell.world_to_base
    P = to_base[None] @ np.asarray(poses_world, dtype=np.float64)
    Q = np.full((len(P), 6), np.nan)
    prev = np.asarray(cell.robot.home if q_start is None else q_start, dtype=np.float64)
    branch = kin.branch_signs(model, prev)  # stay on the start's branch (shoulder, elbow, wrist)
    for i, T in enumerate(P):
        S = kin.ik(model, T, cell.tool.tcp)
        if len(S):
            try:
                prev = Q[i] = kin.select_nearest(S, prev, model=model, branch=branch)
            except LookupError:
                prev = Q[i] = kin.select_nearest(S, prev, model=model)
    n = len(P)
    states = np.zeros(n) if states is None else np.asarray(states, dtype=np.float64)
    return Program(poses=P, q=Q, moves=(move,) * n, v=np.full(n, v), a=np.full(n, a), states=states,
                   tcp=np.asarray(cell.tool.tcp), ops=("sweep",) * n)


def sweep_program(cell, n: int = 2000, *, height: float = 0.15, half_span=(0.12, 0.15), tilt_deg: float = 12.0,
                  loops: float = 1.0, v: float = 0.1, a: float = 1.2, centre=None) -> Program:
    """`n` waypoints sweeping `height` m above the fixture plane over +-half_span (m), tool down.

    `centre`: (x, y) of the sweep in the panel (fixture) frame; default (0.25, 0.25), the middle of
    a 0.5 m panel laid out from the origin as `fabkit unfold` does (where the cells put their work).
    """
    t = np.linspace(0.0, 1.0, n) * loops
    fixture = np.asarray(cell.fixture)
    if centre is None:
        centre = (0.25, 0.25)
    local = np.column_stack([centre[0] + half_span[0] * np.sin(2 * np.pi * 3 * t),
                             centre[1] + half_span[1] * np.sin(2 * np.pi * 2 * t), np.full(n, height)])
    tilt = np.radians(tilt_deg)
    rot = (Rotation.from_euler("x", np.pi)
           * Rotation.from_rotvec(np.column_stack([tilt * np.sin(2 * np.pi * 5 * t), tilt * np.cos(2 * np.pi * 4 * t),
                                                   0.5 * np.sin(2 * np.pi * t)])))
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = fixture[:3, :3] @ rot.as_matrix()
    T[:, :3, 3] = local @ fixture[:3, :3].T + fixture[:3, 3]
    return program_from_poses(cell, T, v=v, a=a)


def toolpath_from_program(prog: Program, cell, *, source=None, op: str = "fold"):
    """A `robot.toolpath.Toolpath` (PATH.json) carrying a program's waypoints, for the CLI."""
    from robot.cell import matrix_to_pose
    from robot.toolpath import Toolpath

    r = np.zeros(len(prog)) if prog.r is None else prog.r
    ops = prog.ops if prog.ops and all(o != "sweep" for o in prog.ops) else (op,) * len(prog)
    waypoints = [{"pose": matrix_to_pose(prog.poses[i]).tolist(), "q": prog.q[i].tolist(), "move": prog.moves[i],
                  "v": float(prog.v[i]), "a": float(prog.a[i]), "r": float(r[i]), "state": int(prog.states[i]),
                  "op": ops[i]} for i in range(len(prog))]
    return Toolpath(robot=cell.model.name, cell=cell.name, tcp=tuple(matrix_to_pose(cell.tool.tcp)),
                    source=dict(source or {"generator": "sim.programs"}), waypoints=tuple(waypoints),
                    cell_sha256=cell.sha256)
