"""Small exact fold sequences for the face-frame and toolpath tests: a tagged grid folded along
straight creases (known answers: every strip is a rigid rotation about its crease line)."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from fabkit.fold import FoldFrame, FoldModel
from fabkit.mesh import PolyMesh


def grid_panel(n_strips=3, n_columns=5, strip_width=0.2, length=0.5):
    """Flat grid: columns along x (the crease direction), strips stacked along y, bounding box at the
    origin (as `fabkit unfold` places flat patterns).

    Vertex (i, j) = i * (n_strips + 1) + j at x = i * length / n_columns, y = j * strip_width.
    Face (i, j) is strip j, column i; the middle column is tagged middle.
    """
    xs = np.linspace(0.0, length, n_columns + 1)
    ys = np.arange(n_strips + 1) * strip_width
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    m = n_strips + 1
    faces, strip, column = [], [], []
    for i in range(n_columns):
        for j in range(n_strips):
            a = i * m + j
            faces.append([a, a + m, a + m + 1, a + 1])
            strip.append(j)
            column.append(i)
    strip, column = np.array(strip), np.array(column)
    middle = (column == n_columns // 2).astype(np.int64)
    return PolyMesh(V, faces, face_data={"strip": strip, "column": column, "middle": middle})


def fold_positions(mesh, crease_angles, clamp_strip, strip_width):
    """Vertex positions with crease j (between strips j-1 and j) folded by crease_angles[j-1]
    (valley +: the far side turns toward +z), strip `clamp_strip` fixed."""
    V = np.array(mesh.vertices)
    n_strips = len(crease_angles) + 1
    ys = np.arange(n_strips + 1) * strip_width
    j_of = np.rint((V[:, 1] - ys[0]) / strip_width).astype(int)  # vertex level
    out = V.copy()
    # strips above the clamp: apply creases clamp+1..n outward; a vertex at level L > clamp is moved
    # by every crease c with clamp < c < L+... (crease c sits at level c)
    for side in (+1, -1):
        creases = range(clamp_strip + 1, n_strips) if side > 0 else range(clamp_strip, 0, -1)
        for c in creases:
            sel = j_of > c if side > 0 else j_of < c
            if not np.any(sel):
                continue
            angle = crease_angles[c - 1]
            # rotate about the crease line (current position of level-c vertices), axis along x
            pivot = out[j_of == c][0]
            axis = np.array([1.0, 0.0, 0.0]) * (1 if side > 0 else -1)
            R = Rotation.from_rotvec(axis * angle).as_matrix()
            out[sel] = (out[sel] - pivot) @ R.T + pivot
    return out


def folded_grid_model(n_strips=3, n_columns=5, strip_width=0.2, length=0.5, angles=None, clamp_strip=1,
                      n_states=11, triangulate=False):
    """A FoldModel of the grid folded from flat to `angles` (radians per crease) in n_states states
    (state 0 flat); optionally triangulated with a `polygon` map like `fabkit refold` writes."""
    mesh = grid_panel(n_strips, n_columns, strip_width, length)
    if angles is None:
        angles = [np.radians(60.0)] * (n_strips - 1)
    frames = [FoldFrame(fold_positions(mesh, [a * t for a in angles], clamp_strip, strip_width))
              for t in np.linspace(0.0, 1.0, n_states)]
    if not triangulate:
        return FoldModel.from_mesh(mesh, frames=frames)
    tris, tri_face = mesh.triangulate()
    data = {name: np.asarray(mesh.face_data[name])[tri_face] for name in ("strip", "column", "middle")}
    data["polygon"] = np.asarray(tri_face)
    tmesh = PolyMesh(mesh.vertices, tris, face_data=data)
    return FoldModel.from_mesh(tmesh, frames=frames)
