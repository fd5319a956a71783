"""Closed polyhedra (Fig. 3 step a) and a flat grid, as `PolyMesh` with outward counter-clockwise faces.

Every solid is centred on the origin. Faces are counter-clockwise seen from outside, so
`mesh.face_normals` point outwards and the signed volume is positive.
"""
from __future__ import annotations

import numpy as np

from fabkit.errors import InputError
from fabkit.generate.reflect import grid_faces
from fabkit.mesh import PolyMesh

__all__ = ["cube", "box", "prism", "tetrahedron", "octahedron", "grid", "signed_volume"]


def _positive(name: str, value: float) -> float:
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise InputError(f"{name} must be a positive length, got {value}", source="generate")
    return value


def box(size_x: float = 1.0, size_y: float = 1.0, size_z: float = 1.0) -> PolyMesh:
    """Axis-aligned box with the given edge lengths [m]; 8 vertices, 6 quads."""
    sx, sy, sz = (_positive(n, v) / 2 for n, v in (("size_x", size_x), ("size_y", size_y), ("size_z", size_z)))
    # vertex index = 4*(z>0) + 2*(y>0) + (x>0)
    V = np.array([[x, y, z] for z in (-sz, sz) for y in (-sy, sy) for x in (-sx, sx)])
    faces = [[0, 2, 3, 1],  # -z
             [4, 5, 7, 6],  # +z
             [0, 1, 5, 4],  # -y
             [2, 6, 7, 3],  # +y
             [0, 4, 6, 2],  # -x
             [1, 3, 7, 5]]  # +x
    return PolyMesh(V, faces)


def cube(size: float = 1.0) -> PolyMesh:
    """Cube with edge length `size` [m]."""
    return box(size, size, size)


def prism(sides: int = 6, radius: float = 0.5, height: float = 1.0) -> PolyMesh:
    """Right prism over a regular `sides`-gon (circumradius `radius` [m]) along z; 2 n-gons + `sides` quads."""
    if int(sides) != sides or sides < 3:
        raise InputError(f"sides must be an integer >= 3, got {sides}", source="generate")
    n = int(sides)
    radius, height = _positive("radius", radius), _positive("height", height)
    a = 2 * np.pi * np.arange(n) / n
    ring = np.stack([radius * np.cos(a), radius * np.sin(a)], axis=1)
    V = np.vstack([np.column_stack([ring, np.full(n, -height / 2)]), np.column_stack([ring, np.full(n, height / 2)])])
    i = np.arange(n)
    sides_q = np.stack([i, (i + 1) % n, n + (i + 1) % n, n + i], axis=1)
    faces = [list(range(n - 1, -1, -1)), list(range(n, 2 * n))] + sides_q.tolist()
    return PolyMesh(V, faces)


def tetrahedron(size: float = 1.0) -> PolyMesh:
    """Regular tetrahedron with edge length `size` [m] (alternate corners of a cube)."""
    s = _positive("size", size) / (2 * np.sqrt(2))
    V = s * np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    return PolyMesh(V, [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])


def octahedron(size: float = 1.0) -> PolyMesh:
    """Regular octahedron with edge length `size` [m]."""
    r = _positive("size", size) / np.sqrt(2)
    V = r * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return PolyMesh(V, faces)


def grid(nx: int = 10, ny: int = 10, size_x: float = 1.0, size_y: float = 1.0) -> PolyMesh:
    """Flat `nx` x `ny` quad grid in z = 0, centred on the origin, faces counter-clockwise from +z.

    Vertex ``i * (ny + 1) + j`` is column i (along x), row j (along y); vertex_data "uv" = (x, y).
    """
    for name, v in (("nx", nx), ("ny", ny)):
        if int(v) != v or v < 1:
            raise InputError(f"{name} must be a positive integer, got {v}", source="generate")
    nx, ny = int(nx), int(ny)
    sx, sy = _positive("size_x", size_x), _positive("size_y", size_y)
    x = np.linspace(-sx / 2, sx / 2, nx + 1)
    y = np.linspace(-sy / 2, sy / 2, ny + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    V = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    return PolyMesh(V, grid_faces(nx, ny + 1), vertex_data={"uv": V[:, :2].copy()})


def signed_volume(mesh: PolyMesh) -> float:
    """Enclosed volume of a closed mesh [m^3]: positive when faces are counter-clockwise from outside."""
    tris, _ = mesh.triangulate()
    a, b, c = (mesh.vertices[tris[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
