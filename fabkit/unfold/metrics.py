"""How isometric a development is: spring length deviation, area change, flips, outline overlap.

The paper's two metrics (§3.3) are the mean and the maximum deviation between the 3D (or target)
and the 2D lengths, taken here over every edge and every face diagonal (`springs`), in relative
(|l2 - l3| / l3) and absolute (metres) form.
"""
from __future__ import annotations

import numpy as np
import shapely

from fabkit.mesh import PolyMesh

__all__ = ["spring_lengths", "polygon_areas_2d", "face_area_change", "flipped_faces", "outline_self_overlaps",
           "outline_polygon"]

#: A 2D corner whose (normalised) cross product is below this is counted as degenerate, i.e. flipped.
FLIP_EPS = 1e-12


def spring_lengths(points: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Length of every spring (vertex pair) in 2D or 3D."""
    return np.linalg.norm(points[pairs[:, 1]] - points[pairs[:, 0]], axis=1)


def polygon_areas_2d(mesh: PolyMesh, uv: np.ndarray) -> np.ndarray:
    """Signed (counter-clockwise positive) shoelace area of every face in the development."""
    t = mesh.topology
    p = uv[t.face_indices]
    q = uv[t.face_indices[t.corner_next]]
    cross = p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]
    return 0.5 * np.add.reduceat(cross, t.face_offsets[:-1])


def face_area_change(mesh: PolyMesh, uv: np.ndarray) -> np.ndarray:
    """Relative area change per face, (A2D - A3D) / A3D (the 3D area is the vector area)."""
    return polygon_areas_2d(mesh, uv) / mesh.face_areas - 1.0


def flipped_faces(mesh: PolyMesh, uv: np.ndarray) -> np.ndarray:
    """Ids of faces with a corner whose turning sense in 2D differs from the one in 3D.

    For a triangle this is a negative (or zero) signed area; for a quad the corner triangles are
    the four triangles of both diagonals, so a quad folded over itself in the plane is caught even
    when its shoelace area stays positive.
    """
    t = mesh.topology
    here = uv[t.face_indices]
    u = uv[t.face_indices[t.corner_next]] - here
    w = uv[t.face_indices[t.corner_prev]] - here
    cross2 = u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]
    scale2 = np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1)
    sign3 = np.einsum("ij,ij->i", mesh.corner_cross, mesh.face_normal_sums[t.corner_face])
    convex3 = sign3 > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        s2 = np.where(scale2 > 0, cross2 / scale2, 0.0)
    bad = np.where(convex3, s2 <= FLIP_EPS, s2 >= -FLIP_EPS)
    return np.unique(t.corner_face[bad])


def outline_polygon(mesh: PolyMesh, uv: np.ndarray):
    """The outline of the development as a shapely Polygon (largest loop the shell, others holes)."""
    loops = [uv[loop] for loop in mesh.boundary_loops]
    if not loops:
        return None
    areas = [abs(_shoelace(p)) for p in loops]
    k = int(np.argmax(areas))
    return shapely.Polygon(loops[k], [p for i, p in enumerate(loops) if i != k])


def _shoelace(p: np.ndarray) -> float:
    q = np.roll(p, -1, axis=0)
    return 0.5 * float(np.sum(p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]))


def outline_self_overlaps(mesh: PolyMesh, uv: np.ndarray) -> bool:
    """True when the outline of the development crosses or touches itself (shapely validity)."""
    loops = mesh.boundary_loops
    if not loops:
        return True
    for loop in loops:
        if not shapely.LinearRing(uv[loop]).is_simple:
            return True
    return not outline_polygon(mesh, uv).is_valid
