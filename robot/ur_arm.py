"""UR arm models and forward kinematics: the published DH parameters of the UR5e and UR10e, joint
ranges and speed limits, flange and TCP poses, the geometric Jacobian, pose errors.

Conventions (reference `ur-robots.md` §1): standard DH; DH frame 0 is the UR controller "base"
frame, DH frame 6 is the flange (= tool0, z out of the flange); the TCP pose is `flange @ tcp`.
Joint angles in radians, lengths in metres; `(6,)` or `(n, 6)` joint vectors. `robot.kinematics`
re-exports every name.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["URModel", "MODELS", "HOME_Q", "get_model", "fk", "fk_tcp", "fk_frames", "jacobian", "pose_error", "wrap_angle"]

_HALF_PI = np.pi / 2


@dataclass(frozen=True, eq=False)
class URModel:
    """A UR arm: standard DH parameters (m, rad), joint ranges (rad) and joint speed limits (rad/s).

    `d`, `a`, `alpha` are the six DH rows; `q_min`/`q_max` the joint ranges used for unwrapping
    (elbow +-pi as in the ROS description, the others +-2pi); `joint_speed_max` the catalogue speeds.
    """

    name: str
    d: tuple[float, ...]
    a: tuple[float, ...]
    alpha: tuple[float, ...]
    q_min: tuple[float, ...]
    q_max: tuple[float, ...]
    joint_speed_max: tuple[float, ...]

    def __post_init__(self) -> None:
        # derived constant arrays for the vectorised FK (exact cos/sin of the 0, +-pi/2 twists so
        # FK carries no 6e-17 noise)
        ca = np.array([0.0 if abs(al) == _HALF_PI else np.cos(al) for al in self.alpha])
        sa = np.array([np.sign(al) if abs(al) == _HALF_PI else np.sin(al) for al in self.alpha])
        for name, value in (("_ca", ca), ("_sa", sa), ("_a", np.array(self.a)), ("_d", np.array(self.d))):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    def ik_module(self):
        """The `ur_analytic_ik` solver of this model (imported on first use)."""
        import ur_analytic_ik

        return getattr(ur_analytic_ik, self.name)


_TWO_PI = 2 * np.pi
_ALPHA = (_HALF_PI, 0.0, 0.0, _HALF_PI, -_HALF_PI, 0.0)
_RANGE_MIN = (-_TWO_PI, -_TWO_PI, -np.pi, -_TWO_PI, -_TWO_PI, -_TWO_PI)
_RANGE_MAX = (_TWO_PI, _TWO_PI, np.pi, _TWO_PI, _TWO_PI, _TWO_PI)
_DEG = np.pi / 180

#: Published DH parameters (UR "Parameters for calculations of kinematics and dynamics").
MODELS: dict[str, URModel] = {
    "ur5e": URModel("ur5e", d=(0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996),
                    a=(0.0, -0.425, -0.3922, 0.0, 0.0, 0.0), alpha=_ALPHA, q_min=_RANGE_MIN, q_max=_RANGE_MAX,
                    joint_speed_max=(180 * _DEG,) * 6),
    "ur10e": URModel("ur10e", d=(0.1807, 0.0, 0.0, 0.17415, 0.11985, 0.11655),
                     a=(0.0, -0.6127, -0.57155, 0.0, 0.0, 0.0), alpha=_ALPHA, q_min=_RANGE_MIN, q_max=_RANGE_MAX,
                     joint_speed_max=(120 * _DEG, 120 * _DEG) + (180 * _DEG,) * 4),
}


#: q = [0, -90, 90, -90, -90, 0] deg, UR's home configuration (tool pointing down).
HOME_Q = (0.0, -_HALF_PI, _HALF_PI, -_HALF_PI, -_HALF_PI, 0.0)


def get_model(name: str | URModel) -> URModel:
    """The model called `name` ("ur5e" or "ur10e"); a `URModel` is returned as is."""
    if isinstance(name, URModel):
        return name
    try:
        return MODELS[str(name).lower()]
    except KeyError:
        raise ValueError(f"unknown robot model {name!r}; known: {', '.join(MODELS)}") from None



def wrap_angle(q: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (q + np.pi) % _TWO_PI - np.pi


# ---- forward kinematics ------------------------------------------------------------------------

def _dh_all(model: URModel, Q: np.ndarray) -> np.ndarray:
    """The six standard DH transforms Rz(q) Tz(d) Tx(a) Rx(alpha) for `(n, 6)` angles -> (n, 6, 4, 4)."""
    ct, st = np.cos(Q), np.sin(Q)
    ca, sa, a, d = model._ca, model._sa, model._a, model._d
    T = np.zeros(Q.shape + (4, 4))
    T[..., 0, 0] = ct
    T[..., 0, 1] = -st * ca
    T[..., 0, 2] = st * sa
    T[..., 0, 3] = a * ct
    T[..., 1, 0] = st
    T[..., 1, 1] = ct * ca
    T[..., 1, 2] = -ct * sa
    T[..., 1, 3] = a * st
    T[..., 2, 1] = sa
    T[..., 2, 2] = ca
    T[..., 2, 3] = d
    T[..., 3, 3] = 1.0
    return T


def fk_frames(model: URModel | str, q) -> np.ndarray:
    """Frames 0..6 of the DH chain in the base frame: `(n, 7, 4, 4)` for q `(n, 6)` (or `(7,4,4)`)."""
    model = get_model(model)
    q = np.asarray(q, dtype=np.float64)
    single = q.ndim == 1
    Q = q.reshape(-1, 6)
    n = Q.shape[0]
    frames = np.empty((n, 7, 4, 4))
    frames[:, 0] = np.eye(4)
    A = _dh_all(model, Q)
    for i in range(6):
        frames[:, i + 1] = frames[:, i] @ A[:, i]
    return frames[0] if single else frames


def fk(model: URModel | str, q) -> np.ndarray:
    """Flange (tool0) pose in the robot base frame: `(4, 4)` for q `(6,)`, `(n, 4, 4)` for `(n, 6)`."""
    model = get_model(model)
    q = np.asarray(q, dtype=np.float64)
    single = q.ndim == 1
    Q = q.reshape(-1, 6)
    A = _dh_all(model, Q)
    T = A[:, 0] @ A[:, 1] @ A[:, 2] @ A[:, 3] @ A[:, 4] @ A[:, 5]
    return T[0] if single else T


def fk_tcp(model: URModel | str, q, tcp=None) -> np.ndarray:
    """TCP pose in the robot base frame: `fk(q) @ tcp` (tcp = 4x4 TCP in the flange frame)."""
    T = fk(model, q)
    return T if tcp is None else T @ np.asarray(tcp, dtype=np.float64)


def jacobian(model: URModel | str, q) -> np.ndarray:
    """Geometric Jacobian of the flange in the base frame, rows (v [m/s], w [rad/s]): `(6, 6)`."""
    F = fk_frames(model, np.asarray(q, dtype=np.float64).reshape(6))
    p_end = F[6, :3, 3]
    J = np.empty((6, 6))
    for i in range(6):
        z, p = F[i, :3, 2], F[i, :3, 3]
        J[:3, i] = np.cross(z, p_end - p)
        J[3:, i] = z
    return J


def pose_error(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position error (m) and rotation angle error (rad) between pose stacks `A`, `B` (..., 4, 4)."""
    D = np.asarray(A)[..., :3, :] - np.asarray(B)[..., :3, :]
    D = D * D
    dp = np.sqrt(D[..., 3].sum(axis=-1))
    # ||Ra - Rb||_F = 2 sqrt(2) sin(theta / 2) for a rotation by theta between them
    dr = np.sqrt(D[..., :3].sum(axis=(-2, -1)))
    rot = 2.0 * np.arcsin(np.minimum(dr * (0.5 / np.sqrt(2.0)), 1.0))
    return dp, rot


