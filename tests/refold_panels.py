"""Exact FLAT/TARGET pairs for the refold tests (and bench): folds with known answers."""
from __future__ import annotations

import numpy as np

from fabkit.generate import MirrorPlane, reflect_panel
from fabkit.generate.reflect import grid_faces
from fabkit.mesh import PolyMesh

DEG = np.pi / 180.0


def flat_of(panel: PolyMesh) -> PolyMesh:
    """The exact development of a generated panel (vertex_data uv) as a z = 0 mesh with its tags."""
    uv = np.asarray(panel.vertex_data["uv"])
    return PolyMesh(np.column_stack([uv, np.zeros(len(uv))]), panel.faces_list(), face_data=panel.face_data)


def reflect_pair(n_creases: int = 1, columns: int = 12, rows=3) -> tuple[PolyMesh, PolyMesh]:
    """(FLAT, TARGET) of a reflect panel with one (60 deg valley) or two (+60/-60) curved creases."""
    if n_creases == 1:
        planes = [MirrorPlane(0.3, 60 * DEG)]
    else:
        planes = [MirrorPlane(0.15, 60 * DEG), MirrorPlane(0.35, -60 * DEG)]
    panel = reflect_panel(planes=planes, columns=columns, rows=rows)
    return flat_of(panel), panel


def straight_crease_pair(angle: float, nx: int = 4, ny: int = 3, size: float = 1.0):
    """A flat nx x ny quad grid folded by `angle` (valley +) about the straight crease x = 0.

    The half x > 0 rotates about the y axis; face strips: 0 for x < 0, 1 for x > 0 (nx even).
    Known answer: every hinge on the crease has fold angle `angle`, all others 0.
    """
    xs = np.linspace(-size / 2, size / 2, nx + 1)
    ys = np.linspace(0.0, size * ny / nx, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    faces = grid_faces(nx, ny + 1)
    fcol = np.repeat(np.arange(nx), ny)
    strip = (fcol >= nx // 2).astype(np.int64)
    middle = np.zeros(len(faces), np.int64)
    mid_row = ny // 2
    middle[(np.arange(len(faces)) % ny == mid_row) & ((fcol == nx // 2 - 1) | (fcol == nx // 2))] = 1
    column = (np.arange(len(faces)) % ny).astype(np.int64)  # along the crease
    fd = {"strip": strip, "column": column, "middle": middle}
    flat = PolyMesh(V, faces, face_data=fd)
    T = V.copy()
    right = T[:, 0] > 1e-12
    # valley: the +x half turns up towards the front (+z): rotate about -y by angle
    c, s = np.cos(angle), np.sin(angle)
    x = T[right, 0]
    T[right, 0], T[right, 2] = c * x, s * x
    return flat, PolyMesh(T, faces, face_data=fd)


def letter_fold_pair(angle: float, nx: int = 6, ny: int = 2, size: float = 1.0):
    """A flat strip with two straight creases at x = -1/6 and 1/6 (of `size`), both valley `angle`.

    Beyond about 160 deg the two flaps, folded over the middle panel from both sides, cross each
    other: a known interpenetration.
    """
    xs = np.linspace(-size / 2, size / 2, nx + 1)
    ys = np.linspace(0.0, size * ny / nx, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    faces = grid_faces(nx, ny + 1)
    fcol = np.repeat(np.arange(nx), ny)
    strip = np.digitize(fcol, [nx // 3, 2 * nx // 3]).astype(np.int64)
    column = (np.arange(len(faces)) % ny).astype(np.int64)
    middle = (column == ny // 2).astype(np.int64) * np.isin(fcol, [nx // 3 - 1, nx // 3, 2 * nx // 3 - 1,
                                                                    2 * nx // 3]).astype(np.int64)
    fd = {"strip": strip, "column": column, "middle": middle}
    a, b = xs[nx // 3], xs[2 * nx // 3]
    T = V.copy()
    c, s = np.cos(angle), np.sin(angle)
    left, right = T[:, 0] < a - 1e-12, T[:, 0] > b + 1e-12
    dl, dr = a - V[left, 0], V[right, 0] - b
    T[left, 0], T[left, 2] = a - c * dl, s * dl
    T[right, 0], T[right, 2] = b + c * dr, s * dr
    return PolyMesh(V, faces, face_data=fd), PolyMesh(T, faces, face_data=fd)
