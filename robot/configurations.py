"""Arm configurations of a UR: branches (shoulder / elbow / wrist signs), the IK solution nearest a
reference (wrap-aware), and the singularity factors and limits the planner and checker share.
`robot.kinematics` re-exports every name.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot.ur_arm import URModel, get_model, wrap_angle

__all__ = ["shoulder_term", "branch_signs", "branch_text", "branch_label", "unwrap_near", "wrapped_distance",
           "nearest_index", "select_nearest", "SingularityLimits", "SINGULARITY_LIMITS", "SingularityFactors",
           "singularity_factors"]

_TWO_PI = 2 * np.pi


# ---- branches and nearest solutions ------------------------------------------------------------

def shoulder_term(model: URModel | str, q) -> np.ndarray:
    """a2 cos q2 + a3 cos(q2+q3) + d5 sin(q2+q3+q4) [m]: the wrist centre's reach from the base axis.

    Its sign is the shoulder branch; zero is the shoulder singularity.
    """
    model = get_model(model)
    Q = np.asarray(q, dtype=np.float64)
    q2, q3, q4 = Q[..., 1], Q[..., 2], Q[..., 3]
    return model.a[1] * np.cos(q2) + model.a[2] * np.cos(q2 + q3) + model.d[4] * np.sin(q2 + q3 + q4)


def branch_signs(model: URModel | str, q) -> np.ndarray:
    """Branch signature (shoulder, elbow, wrist) as +-1 ints: `(3,)` for `(6,)`, `(n, 3)` for `(n, 6)`.

    shoulder = sign of `shoulder_term`, elbow = sign(sin q3), wrist = sign(sin q5). The 8 IK
    solutions of a generic pose have 8 different signatures; a signature can only change by passing
    through the matching singularity.
    """
    Q = np.asarray(q, dtype=np.float64)
    s = np.stack([shoulder_term(model, Q), np.sin(Q[..., 2]), np.sin(Q[..., 4])], axis=-1)
    return np.where(s >= 0, 1, -1).astype(np.int64)


def branch_text(signs) -> str:
    """"shoulder+ elbow- wrist+" for a (shoulder, elbow, wrist) signature of +-1."""
    s, e, w = (("+" if int(v) > 0 else "-") for v in signs)
    return f"shoulder{s} elbow{e} wrist{w}"


def branch_label(model: URModel | str, q) -> str:
    """Readable branch of one configuration, e.g. "shoulder+ elbow- wrist+"."""
    return branch_text(branch_signs(model, np.asarray(q, dtype=np.float64).reshape(6)))


def unwrap_near(q, q_ref, model: URModel | str | None = None) -> np.ndarray:
    """`q` shifted joint by joint by multiples of 2pi to lie nearest `q_ref` inside the joint ranges.

    The ranges are the model's (both UR models: +-2pi, elbow +-pi); `(6,)` or `(n, 6)`.
    """
    m = get_model(model or "ur5e")
    q = np.asarray(q, dtype=np.float64)
    q_ref = np.asarray(q_ref, dtype=np.float64)
    out = q_ref + wrap_angle(q - q_ref)
    lo, hi = np.array(m.q_min), np.array(m.q_max)
    out = np.where(out > hi, out - _TWO_PI, out)
    out = np.where(out < lo, out + _TWO_PI, out)
    return out


def wrapped_distance(a, b) -> np.ndarray:
    """Largest joint difference between configurations, modulo 2pi (rad)."""
    return np.max(np.abs(wrap_angle(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64))), axis=-1)


def nearest_index(solutions, q_ref, *, model: URModel | str | None = None, branch=None) -> int:
    """Index of the solution closest to `q_ref` (wrap-aware); see `select_nearest`."""
    S = np.asarray(solutions, dtype=np.float64).reshape(-1, 6)
    if len(S) == 0:
        raise LookupError("no IK solution")
    U = unwrap_near(S, q_ref, model)
    moves = np.abs(U - np.asarray(q_ref, dtype=np.float64))
    cost = np.max(moves, axis=1) + 1e-3 * np.sum(moves, axis=1)
    if branch is not None:
        if model is None:
            raise ValueError("selecting by branch needs the model (the shoulder sign depends on its DH lengths)")
        ok = np.all(branch_signs(model, S) == np.asarray(branch), axis=1)
        if not np.any(ok):
            raise LookupError(f"no IK solution on branch {branch_text(branch)}")
        cost = np.where(ok, cost, np.inf)
    return int(np.argmin(cost))


def select_nearest(solutions, q_ref, *, model: URModel | str | None = None, branch=None) -> np.ndarray:
    """The solution closest to `q_ref`, unwrapped next to it (`(6,)`, inside the joint ranges).

    Wrap-aware: each joint may move by multiples of 2pi. Distance is the largest single-joint move
    (what limits a move's duration), ties broken by the sum of moves. With `branch` (a (shoulder,
    elbow, wrist) signature of +-1; needs `model` for the shoulder term) only solutions on that branch
    count. Raises `LookupError` if no solution qualifies.
    """
    S = np.asarray(solutions, dtype=np.float64).reshape(-1, 6)
    i = nearest_index(S, q_ref, model=model, branch=branch)
    return unwrap_near(S[i], q_ref, model)


# ---- singularities -----------------------------------------------------------------------------

@dataclass(frozen=True)
class SingularityLimits:
    """How close to a singularity a configuration may come: the one source for planner and checker.

    elbow: |sin q3| (0.05 ~ 2.9 deg from stretched/folded); wrist: |sin q5|; shoulder_m: the
    shoulder factor of det J (wrist centre to the base axis) in metres.
    """

    elbow: float = 0.05
    wrist: float = 0.05
    shoulder_m: float = 0.03


SINGULARITY_LIMITS = SingularityLimits()


@dataclass(frozen=True)
class SingularityFactors:
    """Factors of det J = a2 a3 * elbow * wrist * shoulder (reference §3.4).

    `elbow` = sin q3 and `wrist` = sin q5 (dimensionless), `shoulder` = the wrist centre's reach
    from the base axis [m]; each is near zero at its singularity. `det` is the Jacobian determinant.
    """

    elbow: np.ndarray
    wrist: np.ndarray
    shoulder: np.ndarray
    det: np.ndarray


def singularity_factors(model: URModel | str, q) -> SingularityFactors:
    """Closed-form singularity factors for `(6,)` or `(n, 6)` configurations."""
    model = get_model(model)
    Q = np.asarray(q, dtype=np.float64)
    elbow, wrist = np.sin(Q[..., 2]), np.sin(Q[..., 4])
    shoulder = shoulder_term(model, Q)
    det = model.a[1] * model.a[2] * elbow * wrist * shoulder
    return SingularityFactors(elbow=elbow, wrist=wrist, shoulder=shoulder, det=det)
