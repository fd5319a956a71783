"""The multi-panel input surface (paper §3.1): a low-poly quad grid, subdivided by Catmull–Clark.

One face-flow direction of the low-poly is shaped by exactly 3 vertices (the *across* direction,
u), so every subdivided iso-line across the surface is a cubic B-spline with three control points
— a planar curve (three points span a plane). Those iso-lines are the paper's planar arcs.

The low-poly carries its integer grid coordinates as float `vertex_data["grid"]`; Catmull–Clark
reproduces linear functions on a regular grid (also with its boundary rules), so after k levels
the coordinates times 2^k are integers again and give the subdivided vertices' grid positions.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabkit.errors import InputError
from fabkit.mesh import PolyMesh

__all__ = ["GridSurface", "canopy_lowpoly", "subdivide_grid", "grid_from_mesh"]


@dataclass(frozen=True)
class GridSurface:
    """A structured quad-grid surface: `points[i, j]` with i across (arcs run along i), j along."""

    points: np.ndarray  # (nu, nv, 3)
    mesh: PolyMesh      # the same surface as a polygon mesh (vertex ids: mesh order)
    index: np.ndarray   # (nu, nv) vertex id of each grid point in `mesh`

    @property
    def shape(self) -> tuple[int, int]:
        return self.points.shape[:2]


def canopy_lowpoly(length: float = 6.0, width: float = 2.4, height: float = 2.2, arch: float = 0.5,
                   wave: float = 0.35, waves: int = 2, stations: int = 9, sweep: float = 0.3) -> PolyMesh:
    """A wave-like canopy low-poly: 3 vertices across (u) x `stations` along (x), mirror-symmetric.

    The canopy spans x in [-length/2, length/2]; its ridge height follows a cosine wave
    (`waves` periods) and its width breathes with the same wave; the ridge vertex is swept along
    x by an odd function (`sweep`), so the cross-section arcs are not in x = const planes — they
    are planar only because each has three control vertices. Mirror-symmetric in the plane
    x = 0. Units: metres.
    """
    if stations < 3:
        raise InputError(f"stations must be >= 3, got {stations}")
    for name, v in (("length", length), ("width", width), ("height", height)):
        if not v > 0:
            raise InputError(f"{name} must be positive, got {v}")
    xs = np.linspace(-length / 2, length / 2, stations)
    phase = np.cos(2 * np.pi * waves * xs / length)
    half = 0.5 * width * (1.0 + 0.25 * phase)
    ridge = height + wave * phase
    V, G = [], []
    for j, x in enumerate(xs):
        dx = sweep * np.sin(2 * np.pi * x / length)
        for i, (xx, y, z) in enumerate(((x, -half[j], 0.35 * ridge[j]), (x + dx, 0.0, ridge[j] + arch),
                                        (x, half[j], 0.35 * ridge[j]))):
            V.append((xx, y, z))
            G.append((i, j))
    nu = 3
    F = [[j * nu + i, j * nu + i + 1, (j + 1) * nu + i + 1, (j + 1) * nu + i]
         for j in range(stations - 1) for i in range(nu - 1)]
    # faces CCW seen from below/inside the canopy would flip normals; orient them upwards (+z)
    mesh = PolyMesh(np.array(V), F, vertex_data={"grid": np.array(G, dtype=np.float64)})
    if mesh.face_normals[:, 2].mean() < 0:
        mesh = PolyMesh(np.array(V), [f[::-1] for f in F], vertex_data={"grid": np.array(G, dtype=np.float64)})
    return mesh


def grid_from_mesh(mesh: PolyMesh, levels: int) -> GridSurface:
    """Recover the structured grid of a subdivided low-poly from its `vertex_data["grid"]`."""
    if "grid" not in mesh.vertex_data:
        raise InputError("surface has no grid coordinates (vertex data 'grid')")
    g = np.asarray(mesh.vertex_data["grid"]) * (2 ** levels)
    gi = np.rint(g).astype(np.int64)
    if np.abs(g - gi).max() > 1e-6:
        raise InputError("surface is not a regular quad grid (grid coordinates are not dyadic)")
    nu, nv = gi[:, 0].max() + 1, gi[:, 1].max() + 1
    index = np.full((nu, nv), -1, dtype=np.int64)
    index[gi[:, 0], gi[:, 1]] = np.arange(mesh.n_vertices)
    if np.any(index < 0) or nu * nv != mesh.n_vertices:
        raise InputError("surface is not a complete quad grid")
    return GridSurface(points=mesh.vertices[index], mesh=mesh, index=index)


def subdivide_grid(lowpoly: PolyMesh, levels: int = 3) -> GridSurface:
    """Catmull–Clark `levels` times and return the structured high-resolution grid."""
    from fabkit.generate.subdivide import catmull_clark

    return grid_from_mesh(catmull_clark(lowpoly, levels), levels)
