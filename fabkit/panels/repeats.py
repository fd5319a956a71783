"""Panels that are the same part: equal refold inputs in the panel frame, up to a rigid motion.

An installation repeats its panels (the pleated vault: 494 panels, 98 different ones). What the
refold, the planner and the check read of a panel is its flat pattern in the panel frame (the
clamped face at the fixture's origin, see `fabkit.panels.production`), its faces and tags, and the
relaxed panel only through rigid-motion invariants (fold angles from dihedral angles, the target
distance after aligning the clamped face, crease detection). So two panels whose

- faces, tags and later-stage options are identical,
- flat patterns in the panel frame agree to `tol` at every vertex, and
- relaxed panels agree to `tol` at every vertex after the best *proper* rigid motion (a mirror
  image is a different part: the robot cannot fold it with the same program)

get the same fold states to within about `tol` in the panel frame, where the robot sees them. A
production run computes one of them (the representative) and gives the others its fold states,
program and check (`fabkit.panels.production`); the deviation of every panel from its
representative is recorded.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

__all__ = ["SAME_PART_TOL", "PartClasses", "same_part_classes", "rigid_residual"]

#: Max vertex deviation [m] of two panels (flat pattern in the panel frame; relaxed panel after
#: the best rigid motion) that are treated as the same part: 0.1 um, 300 times finer than a UR
#: arm's repeatability (0.03 mm) and far below every tolerance of the check. Measured on the
#: pleated vault: repeated panels agree to 1e-14 m, different ones differ by 4.6 mm or more.
SAME_PART_TOL = 1e-7


@dataclass(frozen=True)
class PartClasses:
    """`rep[i]`: the representative of panel i (itself for a representative); `deviation[i]`: its
    max vertex deviation [m] from the representative (0 for a representative)."""

    rep: dict
    deviation: dict
    tol: float

    @property
    def representatives(self) -> list:
        return sorted(k for k, r in self.rep.items() if k == r)

    def members(self, rep) -> list:
        return sorted(k for k, r in self.rep.items() if r == rep and k != rep)


def rigid_residual(a: np.ndarray, b: np.ndarray) -> float:
    """Max vertex distance [m] between point sets `a` and `b` (same order) after the best proper
    rigid motion of `b` onto `a` (Kabsch, rotation with det +1)."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    A, B = a - ca, b - cb
    U, _, Vt = np.linalg.svd(B.T @ A)
    d = np.sign(np.linalg.det(U @ Vt))
    R = U @ np.diag([1.0, 1.0, d]) @ Vt
    return float(np.linalg.norm(B @ R - A, axis=1).max())


def _signature(part: dict) -> str:
    h = hashlib.sha256()
    for key in sorted(part["exact"]):
        v = part["exact"][key]
        a = np.ascontiguousarray(v) if isinstance(v, np.ndarray) else np.asarray(str(v))
        h.update(f"{key}{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def same_part_classes(parts: dict, tol: float = SAME_PART_TOL) -> PartClasses:
    """Group panels into parts. `parts[i]` = {"exact": {name: array or value} compared for equality,
    "flat": (n, 2|3) flat pattern in the panel frame, "target": (n, 3) relaxed panel}; the first
    panel (by key order) of each part is its representative."""
    rep, dev = {}, {}
    buckets: dict[str, tuple[list, list]] = {}  # signature -> (representatives, their flat patterns)
    for i in sorted(parts):
        p = parts[i]
        flat, target = np.asarray(p["flat"], float), np.asarray(p["target"], float)
        key = f"{_signature(p)}{flat.shape}{target.shape}"
        reps, flats = buckets.setdefault(key, ([], []))
        found = None
        if reps:
            d_flat = np.linalg.norm(np.asarray(flats) - flat, axis=2).max(axis=1)  # every representative at once
            for k in np.flatnonzero(d_flat <= tol):
                d = max(float(d_flat[k]), rigid_residual(np.asarray(parts[reps[k]]["target"], float), target))
                if d <= tol:
                    found = (reps[k], d)
                    break
        if found is None:
            reps.append(i)
            flats.append(flat)
            rep[i], dev[i] = i, 0.0
        else:
            rep[i], dev[i] = found
    return PartClasses(rep=rep, deviation=dev, tol=tol)
