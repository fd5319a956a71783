"""A pleated canopy: the smooth canopy corrugated by alternating mountain and valley creases.

The installation the paper describes was pleated aluminium. Starting from the canopy's subdivided
grid (paper §3.1: every iso-line across it is a planar arc), each arc is offset *within its own
plane* along its in-plane normal by a triangle wave d(j) over the grid rows j: zero on the band
boundaries, +-A at the middle row of every band, the sign alternating band by band. An in-plane
offset of a planar curve is planar, so every grid row — the creases included — stays a planar arc.
The wave is straight between its zero crossings and its peaks, so the surface kinks only on the
crease rows (one per band, in the band's middle); a band boundary is not a kink, so `fabkit panels`
finds the creases (`fabkit.panels.layout.crease_rows`) and puts the panel boundaries between them,
each crease inside its band's panels.

The amplitude at each crease is A = h tan(fold / 2), h the mean distance from the crease row to the
nearer band boundary row, so the surface's dihedral angle at the creases is about `fold`.
"""
from __future__ import annotations

import numpy as np

from fabkit.errors import InputError
from fabkit.mesh import PolyMesh

__all__ = ["pleated_canopy", "pleat_rows", "band_rows"]


def band_rows(nv: int, rows: int) -> np.ndarray:
    """Grid-row index of each band boundary (`rows + 1`), rounded mirror-symmetrically (as the layout)."""
    return np.array([(b * (nv - 1)) // rows if 2 * b <= rows else nv - 1 - ((rows - b) * (nv - 1)) // rows
                     for b in range(rows + 1)], dtype=np.int64)


def pleat_rows(nv: int, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """(band boundary rows, crease rows): one crease per band, in its middle row (symmetric rounding)."""
    arcs = band_rows(nv, rows)
    creases = np.array([(arcs[b] + arcs[b + 1]) // 2 if 2 * b < rows else -((-(arcs[b] + arcs[b + 1])) // 2)
                        for b in range(rows)], dtype=np.int64)
    if np.any(creases <= arcs[:-1]) or np.any(creases >= arcs[1:]):
        raise InputError(f"{rows} pleats need at least 2 grid rows per band; the surface has {nv} rows "
                         "(subdivide more or use fewer rows)")
    return arcs, creases


def _arc_offset_directions(P: np.ndarray) -> np.ndarray:
    """Unit in-plane normals of every arc P[:, j] (nu, nv, 3), oriented with the surface normal."""
    nu, nv, _ = P.shape
    T = np.gradient(P, axis=0)
    S = np.gradient(P, axis=1)
    surface_normal = np.cross(T, S)
    out = np.empty_like(P)
    for j in range(nv):
        X = P[:, j] - P[:, j].mean(axis=0)
        plane = np.linalg.svd(X)[2][-1]
        m = np.cross(plane, T[:, j])
        m /= np.linalg.norm(m, axis=1, keepdims=True)
        if np.sum(m * surface_normal[:, j]) < 0:
            m = -m
        out[:, j] = m
    return out


def _triangle_wave(P: np.ndarray, creases: np.ndarray, fold: float) -> np.ndarray:
    """Offset d(j) per grid row: peaks of alternating sign on the crease rows, straight in between.

    Peak b has amplitude A_b = h_b tan(fold / 2), h_b the distance [m] from the crease to halfway to
    its neighbours; the zero crossing between two peaks sits where both straight pieces have the
    same slope, so the wave does not kink there (only on the crease rows). Beyond the first and last
    crease the wave continues straight.
    """
    nv = P.shape[1]
    spacing = np.linalg.norm(np.diff(P, axis=1), axis=2).mean(axis=0)  # (nv - 1,) row spacing [m]
    cum = np.concatenate([[0.0], np.cumsum(spacing)])                   # distance along the rows
    c = cum[creases]
    gaps = np.diff(c)
    half = 0.5 * np.concatenate([[gaps[0]], gaps]) if len(gaps) else np.array([0.5 * (cum[-1] - c[0])])
    half = np.minimum(half, 0.5 * np.concatenate([gaps, [gaps[-1]]])) if len(gaps) else half
    A = half * np.tan(fold / 2) * np.where(np.arange(len(c)) % 2 == 0, 1.0, -1.0)
    # zero crossing z between peaks b, b+1 with equal slopes: |A_b| / (z - c_b) = |A_b+1| / (c_b+1 - z)
    z = (np.abs(A[:-1]) * c[1:] + np.abs(A[1:]) * c[:-1]) / (np.abs(A[:-1]) + np.abs(A[1:]))
    knots_x = np.concatenate([c, z])
    knots_y = np.concatenate([A, np.zeros(len(z))])
    order = np.argsort(knots_x)
    knots_x, knots_y = knots_x[order], knots_y[order]
    d = np.interp(cum, knots_x, knots_y)
    if len(z):  # straight continuation past the end peaks
        s0 = A[0] / (z[0] - c[0])
        s1 = A[-1] / (c[-1] - z[-1])
        d = np.where(cum < c[0], A[0] - s0 * (c[0] - cum), d)
        d = np.where(cum > c[-1], A[-1] - s1 * (cum - c[-1]), d)
    return d


def pleated_canopy(rows: int = 14, fold: float = np.radians(30.0), levels: int = 4, **canopy) -> PolyMesh:
    """The pleated canopy as a high-resolution quad grid (vertex ids: i across + nu * j along).

    rows: bands = creases (even: bands come in staggered pairs); fold: approximate dihedral angle at
    the creases [rad]; levels: Catmull-Clark levels of the canopy low-poly; `canopy`: parameters of
    `fabkit.panels.surface.canopy_lowpoly`. Face normals point like the canopy's (upwards).
    """
    from fabkit.panels.surface import canopy_lowpoly, subdivide_grid

    if rows < 2 or rows % 2:
        raise InputError(f"rows must be an even number >= 2 (bands come in aligned pairs), got {rows}")
    if not 0 < fold < np.radians(120.0):
        raise InputError(f"fold must be between 0 and 120 degrees, got {np.degrees(fold):g}")
    if levels < 1:
        raise InputError(f"levels must be >= 1, got {levels}")
    surface = subdivide_grid(canopy_lowpoly(**canopy), levels)
    P = surface.points
    nu, nv, _ = P.shape
    arcs, creases = pleat_rows(nv, rows)
    d = _triangle_wave(P, creases, fold)
    Q = P + d[None, :, None] * _arc_offset_directions(P)
    ids = np.arange(nu * nv).reshape(nv, nu).T  # vertex id of grid point (i, j)
    quads = np.stack([ids[:-1, :-1], ids[1:, :-1], ids[1:, 1:], ids[:-1, 1:]], axis=-1).reshape(-1, 4)
    V = Q.transpose(1, 0, 2).reshape(-1, 3)
    mesh = PolyMesh(V, quads)
    if np.dot(mesh.face_normal_sums.sum(axis=0), surface.mesh.face_normal_sums.sum(axis=0)) < 0:
        mesh = PolyMesh(V, quads[:, ::-1])
    return mesh
