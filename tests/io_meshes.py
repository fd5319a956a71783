"""Small meshes with known structure shared by the file-format tests."""
from __future__ import annotations

import numpy as np

from fabkit.mesh import PolyMesh

#: flat pattern: a quad, a pentagon, two triangles and a quad, counter-clockwise seen from +z
MIXED_V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0], [0, 2, 0], [1, 2, 0],
                    [2, 2, 0], [3, 0.5, 0]], dtype=float) * 0.1
MIXED_F = [[0, 1, 4, 3], [1, 2, 9, 5, 4], [3, 4, 7], [3, 7, 6], [4, 5, 8, 7]]


def mixed_mesh(scale: float = 1.0, jitter: float = 0.0, seed: int = 7) -> PolyMesh:
    """Mixed tri/quad/pentagon panel with `strip`, `column`, `middle` face tags and a vertex tag."""
    rng = np.random.default_rng(seed)
    V = MIXED_V * scale
    if jitter:
        V = V + rng.normal(scale=jitter, size=V.shape) * [1, 1, 0]
    return PolyMesh(V, MIXED_F, face_data={
        "strip": np.array([0, 1, 0, 0, 1]),
        "column": np.array([0, 0, 1, 1, 1]),
        "middle": np.array([1, 1, 0, 0, 0]),
    }, vertex_data={"pinned": np.array([True] + [False] * 9), "weight": np.linspace(0.1, 1.0, 10) / 3})


def folded_coords(mesh: PolyMesh, angle: float) -> np.ndarray:
    """Rotate every vertex with x > 0.1 about the line x = 0.1 (a valley fold for angle > 0)."""
    V = np.array(mesh.vertices)
    hinge = 0.1
    right = V[:, 0] > hinge + 1e-12
    d = V[right, 0] - hinge
    V[right, 0] = hinge + d * np.cos(angle)
    V[right, 2] = d * np.sin(angle)
    return V


def grid(nx: int, ny: int, dx: float = 1.0) -> PolyMesh:
    """Flat nx-by-ny grid of unit quads, counter-clockwise, vertex (i, j) = j * (nx + 1) + i."""
    xs, ys = np.meshgrid(np.arange(nx + 1) * dx, np.arange(ny + 1) * dx)
    V = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    F = [[j * (nx + 1) + i, j * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i]
         for j in range(ny) for i in range(nx)]
    return PolyMesh(V, F)
