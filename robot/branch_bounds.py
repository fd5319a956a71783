"""Bounds that let the planner skip IK branches that cannot win, and the IK remembered per plan.

`robot.planner.plan_toolpath` starts a candidate branch at every IK solution of the approach pose
and propagates it through the fold (module docstring there). Two bounds, both from the IK of the
chain's own target poses (approach, grip, every fold state, retract), decide which branches need
propagating without changing what is planned:

- `reach_bound`: the first target pose no solution on the branch reaches. Propagation fails there
  or before, so the branch cannot plan; it is propagated only if it could be the failure that got
  farthest (the one a refusal names).
- `travel_bound`: a lower bound of the branch's joint travel (the planner's cost). A branch whose
  bound exceeds the best cost found cannot be chosen.
"""
from __future__ import annotations

import numpy as np

from robot import kinematics as K

__all__ = ["IKMemo", "reach_bound", "travel_bound", "first_try_is_the_target"]


class IKMemo:
    """`K.ik(model, T, tcp)` remembered by the pose's bytes for one plan: the subdivisions of a fold
    move keep the poses of the coarser division (k/n == 2k/2n exactly), and the reach bound
    (`reach_bound`) solves the chain's own poses before they are propagated."""

    def __init__(self, model, tcp):
        self.model, self.tcp, self.known = model, tcp, {}

    def __call__(self, T: np.ndarray) -> np.ndarray:
        T = np.ascontiguousarray(T, dtype=np.float64)
        key = T.tobytes()
        S = self.known.get(key)
        if S is None:
            S = K.ik(self.model, T, self.tcp)
            S.setflags(write=False)
            self.known[key] = S
        return S


def first_try_is_the_target(tgt, opt) -> bool:
    """True when the planner's propagation solves the target pose itself first (not an
    interpolated one): every move but a fold move given more than one piece (`fold_pieces`)."""
    return tgt.op not in ("fold", "release") or dict(opt.fold_pieces).get(tgt.state, 1) == 1


def reach_bound(model, chain, branch, opt, solve) -> int:
    """An upper bound on the chain index where the planner's propagation fails on `branch`: the
    first target whose own pose no solution on the branch reaches (propagation fails there or
    before), or len(chain) when every target pose is reachable on it (no bound: it may plan)."""
    for i in range(1, len(chain)):
        if not first_try_is_the_target(chain[i], opt):
            continue
        S = solve(chain[i].T)
        if len(S) == 0 or not np.any(np.all(K.branch_signs(model, S) == np.asarray(branch), axis=1)):
            return i
    return len(chain)


def travel_bound(model, chain, q0: np.ndarray, q_home: np.ndarray, branch, solve) -> float:
    """A lower bound of the joint travel `robot.planner.plan_toolpath` costs the branch (before its
    pi per changed sign): from home to q0, then between consecutive target poses at least the wrapped difference of the
    branch's solutions there (the path passes through them, each joint modulo 2pi). 0 when a target
    has more or fewer than one solution on the branch (no bound)."""
    total = float(np.abs(q0 - q_home).sum())
    prev = q0
    for tgt in chain[1:]:
        S = solve(tgt.T)
        on = S[np.all(K.branch_signs(model, S) == np.asarray(branch), axis=1)] if len(S) else S
        if len(on) != 1:
            return 0.0
        total += float(np.abs(K.wrap_angle(on[0] - prev)).sum())
        prev = on[0]
    return total
