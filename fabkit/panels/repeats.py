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
import json
from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["SAME_PART_TOL", "PartClasses", "same_part_classes", "rigid_residual", "relabel_fold", "same_part_result"]

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


def relabel_fold(text: str, rep: str, name: str, deviation: float, tol: float) -> str:
    """The refold FOLD text of panel `rep` as panel `name`'s (the same part): title and panel name
    changed, `fabkit:fold_states_of` and `fabkit:same_part_deviation_m` / `_tol_m` added. The
    geometry is left byte for byte as it is, so a check of either file sees the same panel."""
    lines = text.split("\n")
    title = f' "file_title": {json.dumps(f"fabkit refold of panel {rep}")},'
    panel = f' "fabkit:panel": {json.dumps(rep)},'
    if lines.count(title) != 1 or lines.count(panel) != 1:
        raise ValueError(f"not a production refold FOLD of panel {rep}")
    lines[lines.index(title)] = f' "file_title": {json.dumps(f"fabkit refold of panel {name}")},'
    lines[lines.index(panel)] = "\n".join([
        f' "fabkit:panel": {json.dumps(name)},', f' "fabkit:fold_states_of": {json.dumps(rep)},',
        f' "fabkit:same_part_deviation_m": {json.dumps(float(deviation))},',
        f' "fabkit:same_part_tol_m": {json.dumps(float(tol))},'])
    return "\n".join(lines)


def same_part_result(r: dict, task: dict, deviation: float, tol: float, carry: Callable) -> dict:
    """Panel `task`'s result from the result `r` of a panel of the same part: its fold states,
    program and check, re-pointed at this panel's FOLD by `carry` (`sim.production.carry_over`)."""
    name = task["name"]
    out = {**r, "id": task["id"], "name": name, "same_as": r["name"], "same_part_deviation_m": float(deviation),
           "seconds": 0.0}
    if r["stage"] is not None:
        out["reason"] = f"{r['reason']} (the same part as {r['name']})"
    if r.get("fold") is None:
        return out
    out["fold"] = relabel_fold(r["fold"], r["name"], name, deviation, tol)
    note = (f"program and check of panel {r['name']}, the same part: this panel's flat pattern (panel frame) and "
            f"relaxed shape (up to a rigid motion) are within {deviation:.2g} m of it (tol {tol:g} m), and its "
            f"FOLD has {r['name']}'s fold states")
    prog = carry({k: r[k] for k in ("stage", "reason", "toolpath", "check", "cycle_time_s", "grip_face")},
                 out["fold"], f"{name}_refold.fold", note)
    out.update(toolpath=prog["toolpath"], check=prog["check"])
    return out
