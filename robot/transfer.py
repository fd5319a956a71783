"""The transfer between two phases of a one-arm program: off the panel, over it, home, over the next grip.

After a phase's retract the arm lifts straight up (world +z) by `lift`, moves to the cell's home
configuration, moves to the point `lift` above the next phase's approach pose and goes down onto
the approach: every leg is a joint move (`movej`) between configurations of one branch (a lifted
point the waypoint's branch does not reach is left out: that leg goes straight). The lifted
points keep the tool's orientation of the approach/retract they stand over, so the legs beside the
panel are short vertical joint moves, and the long swing to and from home happens above the
panel. Whether the legs clear the panel in its current fold state, the fixture and the table is
for the check (`fabkit check` checks these moves like every other); this module only solves them.
"""
from __future__ import annotations

import numpy as np

from robot import kinematics as K
from robot.cell import matrix_to_pose, pose_to_matrix
from robot.toolpath import Waypoint

__all__ = ["TRANSFER_LIFTS", "lifted_waypoint", "TransferError"]

#: Lifts [m] over the retract / approach pose a transfer tries, highest first (the first both legs reach).
TRANSFER_LIFTS = (0.25, 0.15, 0.08)


class TransferError(ValueError):
    """A lifted point no configuration of the waypoint's branch reaches (or only near a singularity)."""


def lifted_waypoint(cell, wp: Waypoint, lift: float, *, v: float, a: float) -> Waypoint:
    """`wp` (an approach or retract waypoint) raised by `lift` [m] along the world's up direction,
    solved on the branch of `wp.q` nearest to it, as a stopping `movej` with joint speed `v` and
    acceleration `a` (same op and fold state as `wp`). Raises `TransferError`."""
    model, tcp = cell.model, cell.tool.tcp
    T = pose_to_matrix(wp.pose)
    up = cell.world_to_base[:3, :3] @ np.array([0.0, 0.0, 1.0])
    T[:3, 3] += float(lift) * up
    q_ref = np.asarray(wp.q, dtype=np.float64)
    S = K.ik(model, T, tcp)
    if len(S) == 0:
        raise TransferError(f"no joint solution reaches {lift:g} m above the {wp.op} pose")
    try:
        q = K.select_nearest(S, q_ref, model=model, branch=K.branch_signs(model, q_ref))
    except LookupError:
        raise TransferError(f"the point {lift:g} m above the {wp.op} pose needs another configuration") from None
    f = K.singularity_factors(model, q)
    lim = K.SINGULARITY_LIMITS
    if abs(f.wrist) < lim.wrist or abs(f.elbow) < lim.elbow or abs(f.shoulder) < lim.shoulder_m:
        raise TransferError(f"the point {lift:g} m above the {wp.op} pose is near a singularity")
    return Waypoint(pose=matrix_to_pose(T), q=q, move="movej", v=v, a=a, r=0.0, state=wp.state, op=wp.op)
