"""Small meshes with known developments for the unfold and cut-file tests."""
from __future__ import annotations

import numpy as np

from fabkit.mesh import PolyMesh


def grid_faces(nu: int, nv: int) -> np.ndarray:
    """Quads of an nu x nv vertex grid (vertex i * nv + j), counter-clockwise for +u right, +v up."""
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
    a = (i * nv + j).ravel()
    return np.stack([a, a + nv, a + nv + 1, a + 1], axis=1)


def flat_grid(nu=6, nv=5, du=0.1, dv=0.08) -> tuple[PolyMesh, np.ndarray]:
    """A flat quad grid in z = 0 and its coordinates (its own exact development)."""
    U, Vv = np.meshgrid(np.arange(nu) * du, np.arange(nv) * dv, indexing="ij")
    uv = np.stack([U.ravel(), Vv.ravel()], axis=1)
    return PolyMesh(np.column_stack([uv, np.zeros(len(uv))]), grid_faces(nu, nv)), uv


def cylinder_strip(nu=20, nv=8, radius=0.4, arc=2.0, height=0.5, bump=0.0) -> tuple[PolyMesh, np.ndarray]:
    """Quads on a cylinder (axis +y), bending towards +z; exact development: cumulative chords x heights.

    bump > 0 scales x by 1 + bump sin(pi y / height): no longer developable.
    """
    phi = np.linspace(-arc / 2, arc / 2, nu)
    y = np.linspace(0.0, height, nv)
    P, Y = np.meshgrid(phi, y, indexing="ij")
    X = radius * np.sin(P) * (1 + bump * np.sin(np.pi * Y / height))
    Z = radius * (1 - np.cos(P))
    V = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
    chord = 2 * radius * np.sin((arc / (nu - 1)) / 2)
    U2, V2 = np.meshgrid(np.arange(nu) * chord, y, indexing="ij")
    return PolyMesh(V, grid_faces(nu, nv)), np.stack([U2.ravel(), V2.ravel()], axis=1)


def cone_strip(n_gen=16, n_ring=6, half_angle=0.5, sweep=2.5, s0=0.3, s1=1.0) -> tuple[PolyMesh, np.ndarray]:
    """Planar quads between generators of a cone (apex at the origin, axis +z, opening downwards).

    Exact discrete development: vertex at distance s along generator j goes to s (cos Φ_j, sin Φ_j),
    Φ_j the sum of the 3D angles between consecutive generators.
    """
    theta = np.linspace(0, sweep, n_gen)
    d = np.stack([np.sin(half_angle) * np.cos(theta), np.sin(half_angle) * np.sin(theta),
                  -np.cos(half_angle) * np.ones_like(theta)], axis=1)
    s = np.linspace(s0, s1, n_ring)
    V = (d[:, None, :] * s[None, :, None]).reshape(-1, 3)
    gamma = np.arccos(np.clip(np.einsum("ij,ij->i", d[:-1], d[1:]), -1, 1))
    Phi = np.concatenate([[0.0], np.cumsum(gamma)])
    uv = (s[None, :, None] * np.stack([np.cos(Phi), np.sin(Phi)], axis=1)[:, None, :]).reshape(-1, 2)
    # faces: generator j (u) x ring i (v); orient so the front side faces away from the axis... choose
    # counter-clockwise in the development (positive shoelace area)
    faces = grid_faces(n_gen, n_ring)
    tri = uv[faces]
    area = 0.5 * np.sum(tri[:, :, 0] * np.roll(tri[:, :, 1], -1, axis=1) - tri[:, :, 1] * np.roll(tri[:, :, 0], -1, axis=1), axis=1)
    if np.all(area < 0):
        faces = faces[:, ::-1]
    return PolyMesh(V, faces), uv


def folded_grid(fold: float, nu=8, nv=5, du=0.1, dv=0.08) -> tuple[PolyMesh, np.ndarray]:
    """A flat grid folded rigidly about the line u = (nu // 2) * du by `fold` radians (valley +).

    Faces carry face_data "strip" (0 left of the crease, 1 right). Exact development: the flat grid.
    """
    mesh, uv = flat_grid(nu, nv, du, dv)
    u0 = (nu // 2) * du
    V = mesh.vertices.copy()
    right = V[:, 0] > u0 + 1e-12
    x = V[right, 0] - u0
    # valley: the front sides (+z) turn towards each other, i.e. the right part rotates up (+z)
    V[right, 0] = u0 + x * np.cos(fold)
    V[right, 2] = x * np.sin(fold)
    cu = mesh.face_centroids[:, 0]
    strip = (cu > u0).astype(np.int64)
    return PolyMesh(V, mesh.faces_list(), face_data={"strip": strip}), uv


def sphere_cap(n=16, radius=1.0, extent=0.6) -> PolyMesh:
    """Quad grid on a sphere cap around +z (not developable: angle defect ≈ area / R²)."""
    t = np.linspace(-extent, extent, n)
    X, Y = np.meshgrid(t, t, indexing="ij")
    Z = np.sqrt(radius ** 2 - X ** 2 - Y ** 2)
    return PolyMesh(np.stack([X, Y, Z], axis=-1).reshape(-1, 3), grid_faces(n, n))


def rigid_motion(V: np.ndarray, seed: int = 3) -> np.ndarray:
    """V under a random rotation and translation (seeded)."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    return Rotation.random(random_state=rng).apply(np.array(V)) + rng.normal(size=3)


def align_error(a: np.ndarray, b: np.ndarray) -> float:
    """Max distance between 2D point sets a and b after the best rotation + translation of b onto a
    (no mirror)."""
    from scipy.spatial.transform import Rotation

    A = np.column_stack([a - a.mean(0), np.zeros(len(a))])
    B = np.column_stack([b - b.mean(0), np.zeros(len(b))])
    R, _ = Rotation.align_vectors(A, B)
    return float(np.max(np.linalg.norm(R.apply(B) - A, axis=1)))
