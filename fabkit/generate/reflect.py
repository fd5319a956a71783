"""An exactly developable curved-crease panel by the reflection method (Mitani & Igarashi 2011).

Construction (all lengths in metres, angles in radians):

1. A strip of a circular cylinder of radius `radius` with its axis along +y. Generator i sits at
   angle ``phi_i = -arc/2 + i * arc / columns`` (i = 0..columns) at
   ``x = R sin(phi), z = R (1 - cos(phi))``; the strip touches the plane z = 0 along the middle
   generator and bends towards +z. Heights along every generator run from y = 0 to y = `width`.
2. Each `MirrorPlane` is the plane ``y = offset + tan(skew) * x + cot(f / 2) * z``. It meets
   every generator in one point: the crease vertex of that generator. A plane with skew = 0 meets
   the middle generator at height `offset` and there folds the sheet by exactly `fold` (valley
   positive, FOLD convention, measured on the finished panel).
3. Each generator is cut at its crease heights; every piece between two creases (a *strip*) gets
   `rows` equal segments. Consecutive generators bound one column of quads, so every quad lies
   between two parallel lines and is planar to round-off; every interior vertex has angle sum 2π
   to round-off (the mesh lies on the prism inscribed in the cylinder, which is developable).
4. Planes are applied from the last to the first: everything beyond plane j (its crease vertices
   excluded) is mirrored across it. A reflection is an isometry that fixes the plane, so crease
   vertices stay put, faces stay planar and angle sums stay 2π. A later reflection mirrors the
   creases beyond it and so swaps their mountain/valley sense; plane j is therefore built with
   ``f = (-1)**j * fold`` so that the *finished* crease j folds by `fold`.

`vertex_data["uv"]` is the exact planar development of the discrete mesh: the unrolled
pre-reflection strip, with u the cumulative *chord* length between generators (the discrete mesh
lies on the inscribed prism; u -> R*phi as columns grow) and v the height along the generator.
Faces are counter-clockwise in (u, v), i.e. seen from the front (+z) side of the development.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from fabkit.errors import InputError
from fabkit.mesh import PolyMesh

__all__ = ["MirrorPlane", "reflect_panel", "grid_faces"]


@dataclass(frozen=True)
class MirrorPlane:
    """A mirror plane ``y = offset + tan(skew) x + cot(f/2) z`` (see module docstring).

    offset: height [m] where the plane meets the middle generator (x = z = 0).
    fold: signed fold angle [rad] of the finished crease at the middle generator when skew = 0
          (valley +, mountain -), 0 < |fold| < π.
    skew: slope angle [rad] of the crease in the development at the middle generator, |skew| < π/2.
    """

    offset: float
    fold: float
    skew: float = 0.0


def grid_faces(n_columns: int, n_levels: int) -> np.ndarray:
    """Quads of a column-major grid: vertex ``i * n_levels + j`` for generator i, level j.

    Face ``i * (n_levels - 1) + j`` is ``(i,j), (i+1,j), (i+1,j+1), (i,j+1)``: counter-clockwise when
    i grows along +u and j along +v.
    """
    i, j = np.meshgrid(np.arange(n_columns), np.arange(n_levels - 1), indexing="ij")
    a = (i * n_levels + j).ravel()
    return np.stack([a, a + n_levels, a + n_levels + 1, a + 1], axis=1).astype(np.int64)


def _check(cond: bool, message: str) -> None:
    if not cond:
        raise InputError(message, source="reflect_panel")


def reflect_panel(radius: float = 0.5, arc: float = np.pi / 3, width: float = 0.6,
                  planes: Sequence[MirrorPlane] | None = None, columns: int = 24,
                  rows: int | Sequence[int] = 4) -> PolyMesh:
    """Curved-crease panel from a cylinder strip mirrored across one or more planes.

    radius [m] > 0; arc [rad] in (0, 2π): angle the strip spans around the axis; width [m] > 0:
    length of the generators; planes: mirror planes ordered by offset (default: one valley crease
    of 60° at mid-width); columns >= 1: quads along the crease; rows: quads across each strip (one
    int for all strips or one per strip). Raises `InputError` for impossible values, including
    creases that leave the panel or cross each other.

    Tags: face_data "strip" (0..k), "column" (0..columns-1), "middle" (one face per strip in column
    columns // 2, the one in the middle row of its strip); vertex_data "uv" (n, 2).
    """
    radius, arc, width = float(radius), float(arc), float(width)
    _check(np.isfinite(radius) and radius > 0, f"radius must be a positive length, got {radius}")
    _check(np.isfinite(arc) and 0 < arc < 2 * np.pi, f"arc must be in (0, 2π) radians, got {arc}")
    _check(np.isfinite(width) and width > 0, f"width must be a positive length, got {width}")
    _check(int(columns) == columns and columns >= 1, f"columns must be a positive integer, got {columns}")
    columns = int(columns)
    if planes is None:
        planes = [MirrorPlane(offset=width / 2, fold=np.radians(60.0))]
    planes = list(planes)
    k = len(planes)
    rows_list = [rows] * (k + 1) if np.isscalar(rows) else list(rows)
    _check(len(rows_list) == k + 1, f"rows needs one entry per strip ({k + 1}), got {len(rows_list)}")
    for r in rows_list:
        _check(int(r) == r and r >= 1, f"rows must be positive integers, got {r}")
    rows_list = [int(r) for r in rows_list]
    for j, p in enumerate(planes):
        _check(np.isfinite(p.fold) and 0 < abs(p.fold) < np.pi,
               f"plane {j}: fold must satisfy 0 < |fold| < π radians, got {p.fold}")
        _check(np.isfinite(p.skew) and abs(p.skew) < np.pi / 2,
               f"plane {j}: skew must satisfy |skew| < π/2 radians, got {p.skew}")
        _check(np.isfinite(p.offset), f"plane {j}: offset must be finite, got {p.offset}")

    # generators on the cylinder and their exact development coordinate (cumulative chord)
    phi = -arc / 2 + arc * np.arange(columns + 1) / columns
    gx, gz = radius * np.sin(phi), radius * (1.0 - np.cos(phi))
    chord = 2.0 * radius * np.sin(arc / columns / 2.0)
    u = chord * (np.arange(columns + 1) - columns / 2.0)

    # build plane j with the sign that makes the finished crease fold by plane.fold
    normals, offsets = [], []
    heights = [np.zeros(columns + 1)]
    for j, p in enumerate(planes):
        f = p.fold if j % 2 == 0 else -p.fold
        a, b = np.tan(p.skew), 1.0 / np.tan(f / 2.0)
        heights.append(p.offset + a * gx + b * gz)
        normals.append(np.array([-a, 1.0, -b]))  # plane: n . (x, y, z) = offset
        offsets.append(p.offset)
    heights.append(np.full(columns + 1, width))
    H = np.array(heights)  # (k + 2, columns + 1): crease heights per generator, boundaries first/last
    gaps = np.diff(H, axis=0)
    min_gap = 1e-6 * width
    for s in range(k + 1):
        if gaps[s].min() <= min_gap:
            i = int(np.argmin(gaps[s]))
            what = ("the lower edge" if s == 0 else f"crease {s - 1}")
            other = ("the upper edge" if s == k else f"crease {s}")
            raise InputError(f"{what} and {other} meet or cross at generator {i} (heights {H[s, i]:.6g} m and "
                             f"{H[s + 1, i]:.6g} m); change the plane offsets, folds or the width",
                             source="reflect_panel")

    # heights of every level along every generator: strip s has rows_list[s] segments
    t_parts, strip_of_level = [], []
    for s in range(k + 1):
        t = np.arange(rows_list[s] + (1 if s == k else 0)) / rows_list[s]
        t_parts.append((s, t))
        strip_of_level += [s] * len(t)
    levels = []
    for s, t in t_parts:
        levels.append(H[s][:, None] + t[None, :] * (H[s + 1] - H[s])[:, None])
    Y = np.concatenate(levels, axis=1)  # (columns + 1, n_levels)
    n_levels = Y.shape[1]
    strip_of_level = np.array(strip_of_level)
    crease_level = np.cumsum(rows_list)[:-1]  # level index of crease j

    X = np.repeat(gx, n_levels)
    Z = np.repeat(gz, n_levels)
    V = np.stack([X, Y.ravel(), Z], axis=1)
    uv = np.stack([np.repeat(u, n_levels), Y.ravel()], axis=1)
    level = np.tile(np.arange(n_levels), columns + 1)
    for j in range(k - 1, -1, -1):
        beyond = level > crease_level[j]
        n = normals[j]
        nn = n @ n
        d = (V[beyond] @ n - offsets[j]) / nn
        V[beyond] -= 2.0 * d[:, None] * n[None, :]

    faces = grid_faces(columns, n_levels)
    f_col = np.repeat(np.arange(columns), n_levels - 1)
    f_level = np.tile(np.arange(n_levels - 1), columns)
    f_strip = strip_of_level[f_level]
    middle = np.zeros(len(faces), dtype=np.int64)
    mid_col = columns // 2
    start = np.concatenate([[0], np.cumsum(rows_list)[:-1]])
    for s in range(k + 1):
        middle[mid_col * (n_levels - 1) + start[s] + rows_list[s] // 2] = 1
    return PolyMesh(V, faces, face_data={"strip": f_strip.astype(np.int64), "column": f_col.astype(np.int64),
                                         "middle": middle}, vertex_data={"uv": uv})
