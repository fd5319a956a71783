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


def grid_from_topology(mesh: PolyMesh) -> tuple[np.ndarray, bool]:
    """Structured `(nu, nv)` vertex-id grid of a quad mesh that is a topological rectangle.

    The `u` (across) direction is the shorter side. Returns `(index, is_lowpoly)` where
    `is_lowpoly` means the across direction has exactly 3 vertices (the §3.1 input). Raises
    InputError when the mesh is not a rectangular quad grid.
    """
    t = mesh.topology
    if not np.all(t.face_sizes == 4):
        raise InputError("the surface must be a quad grid (all faces quads)")
    if len(t.boundary_loops) != 1:
        raise InputError(f"the surface must be a single rectangular patch (it has {len(t.boundary_loops)} boundary loops)")
    loop = t.boundary_loops[0]
    faces_per_vertex = np.diff(t.vertex_faces[1])
    corners = [i for i, v in enumerate(loop) if faces_per_vertex[v] == 1]
    if len(corners) != 4:
        raise InputError(f"the surface must be a rectangular quad grid (found {len(corners)} corners, need 4)")
    # side A runs from corner 0 to corner 1; each next row lies across the quads beyond the last row
    loop = np.roll(loop, -corners[0])
    side_a = [int(v) for v in loop[: corners[1] - corners[0] + 1]]
    F = t.face_array
    edge_faces: dict[tuple[int, int], list[int]] = {}
    for f, q in enumerate(F.tolist()):
        for k in range(4):
            a, b = q[k], q[(k + 1) % 4]
            edge_faces.setdefault((min(a, b), max(a, b)), []).append(f)
    rows = [side_a]
    used_faces: set[int] = set()
    while len(rows) * len(side_a) < mesh.n_vertices:
        prev = rows[-1]
        nxt: list[int] = []
        for a, b in zip(prev[:-1], prev[1:]):
            cand = [f for f in edge_faces.get((min(a, b), max(a, b)), []) if f not in used_faces]
            if len(cand) != 1:
                raise InputError("the surface is not a rectangular quad grid (cannot follow its rows)")
            q = F[cand[0]].tolist()
            used_faces.add(cand[0])
            ia, ib = q.index(a), q.index(b)
            step = 1 if (ia + 1) % 4 == ib else -1  # direction a -> b around the quad
            c_a = q[(ia - step) % 4]  # neighbour of a that is not b
            c_b = q[(ib + step) % 4]
            if not nxt:
                nxt.append(c_a)
            elif nxt[-1] != c_a:
                raise InputError("the surface is not a rectangular quad grid (rows do not line up)")
            nxt.append(c_b)
        rows.append(nxt)
    index = np.array(rows, dtype=np.int64).T  # (len side_a, n rows)
    if index.size != mesh.n_vertices or len(np.unique(index)) != mesh.n_vertices:
        raise InputError("the surface is not a complete rectangular quad grid")
    if index.shape[0] > index.shape[1]:
        index = index.T
    return index, index.shape[0] == 3
