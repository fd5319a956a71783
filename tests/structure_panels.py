"""Plain-OBJ panels as a user brings them, for the structure and pipeline tests: reflection-method
panels with their tags stripped, shuffled, triangulated or noisy, and a faceted cylinder strip."""
from __future__ import annotations

import numpy as np

from fabkit.generate import MirrorPlane, reflect_panel
from fabkit.mesh import PolyMesh

DEG = np.pi / 180.0


def reflect_tagged(n_creases: int = 1, fold: float = 60.0, columns: int = 12, rows: int = 3,
                   skew: float = 0.0) -> PolyMesh:
    """A reflect panel with its tags (the known answer); fold [deg] valley + on crease 0."""
    if n_creases == 1:
        planes = [MirrorPlane(0.3, fold * DEG, skew)]
    else:
        planes = [MirrorPlane(0.2, fold * DEG, skew), MirrorPlane(0.42, -fold * DEG)]
    return reflect_panel(planes=planes, columns=columns, rows=rows)


def plain(mesh: PolyMesh, vertices=None) -> PolyMesh:
    """The same faces and coordinates with no tags at all (what another program writes)."""
    return PolyMesh(mesh.vertices if vertices is None else vertices, mesh.faces_list())


def true_creases(tagged: PolyMesh) -> np.ndarray:
    st = np.asarray(tagged.face_data["strip"])
    t = tagged.topology
    ef = np.maximum(t.edge_faces, 0)
    return ~t.boundary_edge_mask & (st[ef[:, 0]] != st[ef[:, 1]])


def noisy(mesh: PolyMesh, rel: float = 0.01, seed: int = 0) -> PolyMesh:
    """Gaussian vertex noise with σ = rel x the mean edge length."""
    rng = np.random.default_rng(seed)
    return mesh.with_vertices(mesh.vertices + rng.normal(0.0, rel * mesh.edge_lengths.mean(), mesh.vertices.shape))


def shuffled(mesh: PolyMesh, seed: int = 0):
    """(mesh with vertices and faces permuted and each face's corners rotated, new_of_old vertex map,
    old_of_new face map)."""
    rng = np.random.default_rng(seed)
    n = mesh.n_vertices
    new_of_old = rng.permutation(n)
    V = np.empty_like(mesh.vertices)
    V[new_of_old] = mesh.vertices
    order = rng.permutation(mesh.n_faces)
    faces = []
    for f in order:
        poly = [int(new_of_old[v]) for v in mesh.face(int(f))]
        k = int(rng.integers(len(poly)))
        faces.append(poly[k:] + poly[:k])
    fd = {k: np.asarray(v)[order] for k, v in mesh.face_data.items()}
    return PolyMesh(V, faces, face_data=fd), new_of_old, order


def triangulated(mesh: PolyMesh) -> PolyMesh:
    """Every quad split along its 0-2 diagonal (as an exporter that triangulates does)."""
    tris = []
    for f in mesh.faces_list():
        tris += [[f[0], f[1], f[2]], [f[0], f[2], f[3]]] if len(f) == 4 else [f]
    return PolyMesh(mesh.vertices, tris)


def cylinder_strip(columns: int = 12, arc_deg: float = 60.0, rows: int = 4, radius: float = 0.5,
                   width: float = 0.6, jitter: float = 0.0, seed: int = 0) -> PolyMesh:
    """A faceted cylinder strip with no crease: rulings bend by arc/columns each; `jitter` varies
    the generator spacing (relative), so rulings bend by unequal amounts."""
    rng = np.random.default_rng(seed)
    step = np.full(columns, arc_deg / columns) * (1.0 + jitter * rng.uniform(-1, 1, columns))
    phi = np.radians(np.concatenate([[0.0], np.cumsum(step)]) - arc_deg / 2)
    ys = np.linspace(0.0, width, rows + 1)
    V = np.array([[radius * np.sin(p), y, radius * (1 - np.cos(p))] for p in phi for y in ys])
    from fabkit.generate.reflect import grid_faces

    return PolyMesh(V, grid_faces(columns, rows + 1))
