"""Small exactly developable planar-quad meshes with known answers, for the relax tests."""
from __future__ import annotations

import numpy as np

from fabkit.generate import MirrorPlane, grid_faces
from fabkit.mesh import PolyMesh


def cylinder_grid(columns: int = 8, levels: int = 5, radius: float = 1.0, arc: float = 1.5,
                  height: float = 1.0) -> PolyMesh:
    """Quads on a cylinder, ruled along the generators: planar rectangles, angle sums exactly 2π."""
    phi = np.linspace(-arc / 2, arc / 2, columns + 1)
    y = np.linspace(0.0, height, levels)
    P, Y = np.meshgrid(phi, y, indexing="ij")
    V = np.stack([radius * np.sin(P), Y, radius * (1 - np.cos(P))], axis=-1).reshape(-1, 3)
    return PolyMesh(V, grid_faces(columns, levels))


def cone_grid(columns: int = 8, levels: int = 5, r0: float = 0.5, r1: float = 1.5, half_angle: float = 0.6,
              arc: float = 1.5) -> PolyMesh:
    """Quads on a cone between radii r0..r1 along the rulings (apex excluded): planar, developable."""
    phi = np.linspace(-arc / 2, arc / 2, columns + 1)
    s = np.linspace(r0, r1, levels)
    P, S = np.meshgrid(phi, s, indexing="ij")
    ruling = np.stack([np.sin(half_angle) * np.cos(P), np.sin(half_angle) * np.sin(P),
                       np.full_like(P, np.cos(half_angle))], axis=-1)
    V = (S[..., None] * ruling).reshape(-1, 3)
    return PolyMesh(V, grid_faces(columns, levels))


def folded_grid(columns: int = 6, levels: int = 6, fold: float = 0.8) -> PolyMesh:
    """A flat unit grid folded by `fold` rad along the straight line x = 0.5 (a straight crease)."""
    x = np.linspace(0.0, 1.0, columns + 1)
    y = np.linspace(0.0, 1.0, levels)
    X, Y = np.meshgrid(x, y, indexing="ij")
    V = np.stack([X, Y, np.zeros_like(X)], axis=-1).reshape(-1, 3)
    right = V[:, 0] > 0.5
    d = V[right, 0] - 0.5
    V[right, 0] = 0.5 + d * np.cos(fold)
    V[right, 2] = d * np.sin(fold)
    return PolyMesh(V, grid_faces(columns, levels))


def perturbed(mesh: PolyMesh, sigma_rel: float, seed: int = 0) -> tuple[PolyMesh, float]:
    """The mesh with Gaussian noise of σ = sigma_rel × mean edge length on every coordinate; returns σ."""
    sigma = sigma_rel * float(mesh.edge_lengths.mean())
    rng = np.random.default_rng(seed)
    return mesh.with_vertices(mesh.vertices + rng.normal(scale=sigma, size=mesh.vertices.shape)), sigma


def crease_edges(mesh: PolyMesh) -> np.ndarray:
    """Interior edges whose two faces lie in different strips (face_data 'strip')."""
    s = mesh.face_data["strip"]
    inner = mesh.topology.interior_edges
    ef = mesh.edge_faces[inner]
    return inner[s[ef[:, 0]] != s[ef[:, 1]]]


#: reflect_panel parameter sets shared by the relax tests: one crease, two creases, a skewed crease
REFLECT_PANELS = {
    "one-crease": dict(columns=12, rows=3),
    "two-creases": dict(columns=16, rows=3, planes=[MirrorPlane(0.2, np.radians(60)),
                                                     MirrorPlane(0.4, np.radians(-50), 0.1)]),
    "skewed": dict(columns=16, rows=4, radius=0.4, arc=1.2, planes=[MirrorPlane(0.3, np.radians(80), 0.3)]),
}
