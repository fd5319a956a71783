"""Vectorised measures every stage uses: corner angles, angle defect, planarity, dihedral angles.

Free functions over a `PolyMesh` (or its arrays); radians and metres. Tolerances used by the
tests live in `fabkit.tolerances`.
"""
from __future__ import annotations

import numpy as np

from fabkit.mesh import PolyMesh, cross3

TWO_PI = 2.0 * np.pi

__all__ = [
    "corner_angles", "angle_sums", "angle_defect", "interior_angle_defect", "best_fit_planes",
    "plane_distances", "face_planarity", "edge_lengths", "dihedral_angles", "summary",
]


def corner_angles(mesh: PolyMesh, vertices: np.ndarray | None = None) -> np.ndarray:
    """Interior angle of the polygon at every corner, in [0, 2π).

    The magnitude is the 3D angle between the two corner edges; a corner whose cross product points
    against the face normal (a reflex corner of a non-convex face) gets 2π minus it.
    """
    V = mesh.vertices if vertices is None else vertices
    t = mesh.topology
    here = V[t.face_indices]
    u = V[t.face_indices[t.corner_next]] - here
    w = V[t.face_indices[t.corner_prev]] - here
    c = cross3(u, w)
    sin = np.linalg.norm(c, axis=1)
    cos = np.einsum("ij,ij->i", u, w)
    theta = np.arctan2(sin, cos)
    if vertices is None:
        normal = mesh.face_normal_sums[t.corner_face]
    else:
        normal = np.add.reduceat(c, t.face_offsets[:-1], axis=0)[t.corner_face]
    reflex = np.einsum("ij,ij->i", c, normal) < 0
    return np.where(reflex, TWO_PI - theta, theta)


def angle_sums(mesh: PolyMesh, vertices: np.ndarray | None = None) -> np.ndarray:
    """Sum of corner angles at every vertex."""
    return np.bincount(mesh.face_indices, weights=corner_angles(mesh, vertices), minlength=mesh.n_vertices)


def angle_defect(mesh: PolyMesh, vertices: np.ndarray | None = None) -> np.ndarray:
    """2π − Σθ at every vertex (meaningful at interior vertices; NaN on boundary and unused ones)."""
    d = TWO_PI - angle_sums(mesh, vertices)
    d[~mesh.interior_vertex_mask] = np.nan
    return d


def interior_angle_defect(mesh: PolyMesh, vertices: np.ndarray | None = None) -> np.ndarray:
    """2π − Σθ at the interior vertices only, in vertex order (the discrete Gaussian curvature)."""
    return (TWO_PI - angle_sums(mesh, vertices))[mesh.interior_vertex_mask]


def best_fit_planes(mesh: PolyMesh, method: str = "cross") -> tuple[np.ndarray, np.ndarray]:
    """Per face `(unit normal, origin)`.

    method="cross": normal = sum of corner cross products, origin = centroid (paper §2.4).
    method="covariance": normal = eigenvector of the smallest eigenvalue of the vertex covariance
    (Poranne et al. 2013), oriented like the cross-product normal.
    """
    origin = mesh.face_centroids
    n_cross = mesh.face_normals
    if method == "cross":
        return n_cross, origin
    if method != "covariance":
        raise ValueError(f"unknown plane method {method!r} (cross or covariance)")
    t = mesh.topology
    d = mesh.vertices[t.face_indices] - origin[t.corner_face]
    outer = d[:, :, None] * d[:, None, :]
    cov = np.add.reduceat(outer, t.face_offsets[:-1], axis=0)
    _, vecs = np.linalg.eigh(cov)
    n = vecs[:, :, 0]
    n *= np.where(np.einsum("ij,ij->i", n, n_cross) < 0, -1.0, 1.0)[:, None]
    return n, origin


def plane_distances(mesh: PolyMesh, method: str = "cross") -> np.ndarray:
    """Signed distance of every corner's vertex to its face's best-fit plane (per corner)."""
    n, origin = best_fit_planes(mesh, method)
    t = mesh.topology
    return np.einsum("ij,ij->i", mesh.vertices[t.face_indices] - origin[t.corner_face], n[t.corner_face])


def face_planarity(mesh: PolyMesh, method: str = "cross") -> np.ndarray:
    """Max distance of a face's vertices to its best-fit plane / mean edge length of the face.

    Triangles are exactly 0.
    """
    t = mesh.topology
    d = np.abs(plane_distances(mesh, method))
    dmax = np.maximum.reduceat(d, t.face_offsets[:-1])
    V = mesh.vertices
    elen = np.linalg.norm(V[t.face_indices[t.corner_next]] - V[t.face_indices], axis=1)
    mean_edge = np.add.reduceat(elen, t.face_offsets[:-1]) / t.face_sizes
    p = dmax / mean_edge
    p[t.face_sizes == 3] = 0.0
    return p


def edge_lengths(mesh: PolyMesh) -> np.ndarray:
    return np.array(mesh.edge_lengths)


def dihedral_angles(mesh: PolyMesh, normals: np.ndarray | None = None) -> np.ndarray:
    """Signed fold angle per edge (FOLD convention: valley positive, mountain negative; radians).

    The angle between the normals of the two faces, about the edge direction; 0 on boundary edges.
    Valley: the faces' front sides turn towards each other.
    """
    t = mesh.topology
    n = mesh.face_normals if normals is None else normals
    E = mesh.edges
    out = np.zeros(len(E))
    inner = t.interior_edges
    if len(inner) == 0:
        return out
    fl, fr = t.edge_faces[inner, 0], t.edge_faces[inner, 1]
    e = mesh.vertices[E[inner, 1]] - mesh.vertices[E[inner, 0]]  # lo -> hi: the left face runs along it
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    nl, nr = n[fl], n[fr]
    s = np.einsum("ij,ij->i", cross3(nr, nl), e)
    c = np.einsum("ij,ij->i", nl, nr)
    out[inner] = np.arctan2(s, c)
    return out


def summary(mesh: PolyMesh) -> dict:
    """The headline numbers of a mesh (max/mean |defect|, max/mean planarity, edge stats)."""
    k = np.abs(interior_angle_defect(mesh))
    p = face_planarity(mesh)
    L = mesh.edge_lengths
    return {
        "vertices": mesh.n_vertices,
        "faces": mesh.n_faces,
        "edges": mesh.n_edges,
        "interior_vertices": int(mesh.interior_vertex_mask.sum()),
        "boundary_loops": len(mesh.boundary_loops),
        "max_abs_angle_defect_rad": float(k.max()) if len(k) else 0.0,
        "mean_abs_angle_defect_rad": float(k.mean()) if len(k) else 0.0,
        "max_planarity": float(p.max()) if len(p) else 0.0,
        "mean_planarity": float(p.mean()) if len(p) else 0.0,
        "min_edge_m": float(L.min()) if len(L) else 0.0,
        "max_edge_m": float(L.max()) if len(L) else 0.0,
        "size_m": mesh.size,
    }
