"""UR5e / UR10e kinematics: verified inverse kinematics, and the one import place of the models and
forward kinematics (`robot.ur_arm`) and of branches and singularities (`robot.configurations`).

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
from typing import Iterator

import numpy as np

from robot.configurations import (SINGULARITY_LIMITS, SingularityFactors, SingularityLimits, branch_label,
                                  branch_signs, branch_text, nearest_index, select_nearest, shoulder_term,
                                  singularity_factors, unwrap_near, wrapped_distance)
from robot.ur_arm import MODELS, URModel, fk, fk_frames, fk_tcp, get_model, jacobian, pose_error, wrap_angle

__all__ = [
    "URModel", "MODELS", "get_model", "fk", "fk_tcp", "fk_frames", "jacobian", "ik", "ik_raw",
    "pose_error", "select_nearest", "nearest_index", "branch_text", "shoulder_term", "unwrap_near", "wrapped_distance",
    "wrap_angle", "branch_signs", "branch_label", "SingularityLimits", "SINGULARITY_LIMITS",
    "SingularityFactors", "singularity_factors", "quiet_stdout", "IK_TOL_POS", "IK_TOL_ROT",
]

#: Every IK solution reproduces its target to these tolerances (metres, radians).
IK_TOL_POS = 1e-9
IK_TOL_ROT = 1e-9
#: Yaw (rad) about the flange z axis used to step off the solver's degenerate poses.
DEGENERATE_YAW = 1e-3
#: Two solutions closer than this (max wrapped joint difference, rad) are the same solution.
DUPLICATE_TOL = 1e-7

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

def ik_raw(model: URModel | str, T_flange: np.ndarray) -> np.ndarray:
    """The library's solutions for a flange pose, unverified: `(k, 6)` (stdout contained)."""
    with quiet_stdout():
        return _solve(get_model(model), T_flange)


def _solve(model: URModel, T_flange: np.ndarray) -> np.ndarray:
    sols = model.ik_module().inverse_kinematics(np.ascontiguousarray(T_flange, dtype=np.float64))
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
    same = np.max(np.abs(wrap_angle(Q[:, None, :] - Q[None, :, :])), axis=2) <= DUPLICATE_TOL
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
    Q = wrap_angle(np.concatenate(cands))
    if len(Q) == 0:
        return Q
    dp, dr = pose_error(fk(model, Q), T_flange[None])
    bad = (dp > IK_TOL_POS) | (dr > IK_TOL_ROT)
    for i in np.flatnonzero(bad & (dp < 1e-4) & (dr < 1e-4)):
        Q[i] = wrap_angle(_polish(model, Q[i], T_flange))
        p, r = pose_error(fk(model, Q[i]), T_flange)
        dp[i], dr[i] = p, r
    ok = (dp <= IK_TOL_POS) & (dr <= IK_TOL_ROT)
    if len(cands) == 1:  # one library call: its solutions are already distinct
        return Q[ok]
    return _dedupe(Q[ok], (dp + dr)[ok])
