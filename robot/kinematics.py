"""UR5e / UR10e kinematics: DH models, forward kinematics, verified inverse kinematics, branches.

Conventions (reference `ur-robots.md` §1): standard DH with the published parameters; DH frame 0 is
the UR controller "base" frame, DH frame 6 is the flange (= tool0, z out of the flange); the TCP
pose is `flange @ tcp`. Joint angles in radians, lengths in metres. Arrays in, arrays out: `fk`
accepts `(6,)` or `(n, 6)` joint vectors.

Inverse kinematics goes through `ur_analytic_ik` (fast closed form, C++) wrapped so that:

- every returned solution is verified by our own numpy FK (position <= `IK_TOL_POS` m, rotation
  <= `IK_TOL_ROT` rad), and solutions that miss by a little are polished by Gauss-Newton steps;
- its known degenerate case (wrist 2 at +-90 deg with wrist 3 at 0/180 deg: the generating
  configuration is dropped by its internal FK filter) is recovered: whenever fewer than 8
  solutions come back we solve again for the target yawed by +-`DEGENERATE_YAW` about the flange z
  axis (joint 6's axis, so the yaw moves q6 alone, exactly) and undo the yaw on q6;
- its C++ stdout warnings are contained by redirecting file descriptor 1 to /dev/null around the
  call (`quiet_stdout`);
- branch selection is ours (`select_nearest`, `branch_signs`); `inverse_kinematics_closest` of the
  library is never used (it mixes two metrics, reference §2.3).
"""
from __future__ import annotations

import contextlib
import ctypes
import os
import sys
import threading
from dataclasses import dataclass
from typing import Iterator

import numpy as np

__all__ = [
    "URModel", "MODELS", "get_model", "fk", "fk_tcp", "fk_frames", "jacobian", "ik", "ik_raw",
    "pose_error", "select_nearest", "nearest_index", "branch_text", "shoulder_term", "unwrap_near", "wrapped_distance",
    "wrap_angle", "branch_signs", "branch_label",
    "SingularityFactors", "singularity_factors", "quiet_stdout", "IK_TOL_POS", "IK_TOL_ROT",
]

#: Every IK solution reproduces its target to these tolerances (metres, radians).
IK_TOL_POS = 1e-9
IK_TOL_ROT = 1e-9
#: Yaw (rad) about the flange z axis used to step off the solver's degenerate poses.
DEGENERATE_YAW = 1e-3
#: Two solutions closer than this (max wrapped joint difference, rad) are the same solution.
DUPLICATE_TOL = 1e-7

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

    def _ik_module(self):
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


def get_model(name: str | URModel) -> URModel:
    """The model called `name` ("ur5e" or "ur10e"); a `URModel` is returned as is."""
    if isinstance(name, URModel):
        return name
    try:
        return MODELS[str(name).lower()]
    except KeyError:
        raise ValueError(f"unknown robot model {name!r}; known: {', '.join(MODELS)}") from None


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


# ---- stdout containment ------------------------------------------------------------------------

# ur_analytic_ik prints "Warning: Detected and filtered incorrect IK solution" from C++ to stdout;
# the only way to keep it off the user's terminal (or a JSON stream on stdout) is to point file
# descriptor 1 elsewhere during the call. fd 1 is process-wide, so one lock guards the swap.
_STDOUT_LOCK = threading.RLock()
_STDOUT_STATE = {"depth": 0, "devnull": None}
_LIBC_FFLUSH = None


def _fflush_c() -> None:
    global _LIBC_FFLUSH
    if _LIBC_FFLUSH is None:
        try:
            _LIBC_FFLUSH = ctypes.CDLL(None).fflush
        except (OSError, AttributeError):  # pragma: no cover - non-POSIX
            _LIBC_FFLUSH = lambda _: 0  # noqa: E731
    _LIBC_FFLUSH(None)


@contextlib.contextmanager
def quiet_stdout() -> Iterator[None]:
    """Send everything written to file descriptor 1 inside the block to /dev/null.

    Cheap (a dup, two dup2 and an fflush, ~3 us) and re-entrant; C stdio buffers are flushed before
    fd 1 is restored so nothing written inside leaks out later. Python's own `sys.stdout` is flushed
    first so earlier prints are not lost.
    """
    with _STDOUT_LOCK:
        if _STDOUT_STATE["depth"] > 0:
            _STDOUT_STATE["depth"] += 1
            try:
                yield
            finally:
                _STDOUT_STATE["depth"] -= 1
            return
        try:
            sys.stdout.flush()
        except (AttributeError, ValueError, OSError):
            pass
        try:
            saved = os.dup(1)
        except OSError:  # fd 1 closed: nothing to protect
            saved = None
        if saved is not None:
            if _STDOUT_STATE["devnull"] is None:
                _STDOUT_STATE["devnull"] = os.open(os.devnull, os.O_WRONLY)
            os.dup2(_STDOUT_STATE["devnull"], 1)
        _STDOUT_STATE["depth"] = 1
        try:
            yield
        finally:
            _STDOUT_STATE["depth"] = 0
            if saved is not None:
                _fflush_c()
                os.dup2(saved, 1)
                os.close(saved)


# ---- inverse kinematics ------------------------------------------------------------------------

def wrap_angle(q: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (q + np.pi) % _TWO_PI - np.pi


_wrap = wrap_angle


def ik_raw(model: URModel | str, T_flange: np.ndarray) -> np.ndarray:
    """The library's solutions for a flange pose, unverified: `(k, 6)` (stdout contained)."""
    with quiet_stdout():
        return _solve(get_model(model), T_flange)


def _solve(model: URModel, T_flange: np.ndarray) -> np.ndarray:
    sols = model._ik_module().inverse_kinematics(np.ascontiguousarray(T_flange, dtype=np.float64))
    return np.array(sols, dtype=np.float64).reshape(-1, 6)


def _rigid_inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform."""
    out = np.eye(4)
    R = T[:3, :3]
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ T[:3, 3]
    return out


def _yaw(T: np.ndarray, eps: float) -> np.ndarray:
    c, s = np.cos(eps), np.sin(eps)
    Rz = np.array([[c, -s, 0.0, 0.0], [s, c, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    return T @ Rz


def _polish(model: URModel, q: np.ndarray, T: np.ndarray, steps: int = 4) -> np.ndarray:
    """Gauss-Newton steps on the flange pose (for candidates that miss the tolerance by a little)."""
    from scipy.spatial.transform import Rotation

    q = q.copy()
    for _ in range(steps):
        F = fk(model, q)
        dp = T[:3, 3] - F[:3, 3]
        dw = Rotation.from_matrix(T[:3, :3] @ F[:3, :3].T).as_rotvec()
        if np.linalg.norm(dp) < 1e-14 and np.linalg.norm(dw) < 1e-14:
            break
        step, *_ = np.linalg.lstsq(jacobian(model, q), np.concatenate([dp, dw]), rcond=None)
        q = q + step
    return q


def _dedupe(Q: np.ndarray, err: np.ndarray) -> np.ndarray:
    """Keep one of each set of solutions closer than DUPLICATE_TOL (the most accurate one)."""
    order = np.argsort(err, kind="stable")
    Q = Q[order]
    same = np.max(np.abs(_wrap(Q[:, None, :] - Q[None, :, :])), axis=2) <= DUPLICATE_TOL
    keep = np.ones(len(Q), dtype=bool)
    for i in range(len(Q)):
        if keep[i]:
            keep[i + 1:] &= ~same[i, i + 1:]
    Q = Q[keep]
    return Q[np.lexsort(Q.T[::-1])]


def ik(model: URModel | str, T, tcp=None) -> np.ndarray:
    """Every joint solution `(k, 6)` (k <= 8, angles in [-pi, pi)) whose FK reproduces pose `T`.

    `T` is the TCP pose in the robot base frame (4x4) and `tcp` the TCP in the flange frame
    (None = the flange itself). Each solution is verified by FK to `IK_TOL_POS` m and `IK_TOL_ROT`
    rad; the library's degenerate poses are recovered (module docstring). Returns an empty
    `(0, 6)` array for an unreachable pose — never an unverified solution.
    """
    model = get_model(model)
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"ik needs a finite 4x4 pose, got shape {T.shape}")
    T_flange = T if tcp is None else T @ _rigid_inverse(np.asarray(tcp, dtype=np.float64))
    with quiet_stdout():
        cands = [_solve(model, T_flange)]
        if len(cands[0]) < 8:
            for eps in (DEGENERATE_YAW, -DEGENERATE_YAW):
                Q = _solve(model, _yaw(T_flange, eps))
                if len(Q):
                    Q[:, 5] -= eps
                    cands.append(Q)
    Q = _wrap(np.concatenate(cands))
    if len(Q) == 0:
        return Q
    dp, dr = pose_error(fk(model, Q), T_flange[None])
    bad = (dp > IK_TOL_POS) | (dr > IK_TOL_ROT)
    for i in np.flatnonzero(bad & (dp < 1e-4) & (dr < 1e-4)):
        Q[i] = _wrap(_polish(model, Q[i], T_flange))
        p, r = pose_error(fk(model, Q[i]), T_flange)
        dp[i], dr[i] = p, r
    ok = (dp <= IK_TOL_POS) & (dr <= IK_TOL_ROT)
    if len(cands) == 1:  # one library call: its solutions are already distinct
        return Q[ok]
    return _dedupe(Q[ok], (dp + dr)[ok])


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
    out = q_ref + _wrap(q - q_ref)
    lo, hi = np.array(m.q_min), np.array(m.q_max)
    out = np.where(out > hi, out - _TWO_PI, out)
    out = np.where(out < lo, out + _TWO_PI, out)
    return out


def wrapped_distance(a, b) -> np.ndarray:
    """Largest joint difference between configurations, modulo 2pi (rad)."""
    return np.max(np.abs(_wrap(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64))), axis=-1)


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
