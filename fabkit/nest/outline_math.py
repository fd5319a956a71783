"""Closed outlines as arrays: turned, grown by a gap, and as padded arrays their extremes at many
heights and the least shift putting one right of another, for many outlines or pairs in one numpy
computation.

The nestings' outlines have ~15-30 vertices, so one outline at a time their time goes to numpy's
per-call cost. These do the arithmetic of `rows._outline_x_at` and `rows._shift_past` (the edge
through a height interpolated as start + t * step), so they give the same numbers bit for bit.
Arrays are float64; an outline is (vertices, 2), closed (its last vertex repeats its first).
"""
from __future__ import annotations

import math

import numpy as np
import shapely
from shapely.geometry import Polygon

__all__ = ["rotate_points", "grow", "grow_all", "padded", "edges", "extremes", "greatest", "least", "shifts_past"]


def padded(outlines: list[np.ndarray]) -> np.ndarray:
    """The outlines as one (outlines, most vertices, 2) array, each padded with its closing vertex
    (a repeated vertex adds no edge and no height)."""
    n = max(len(G) for G in outlines)
    out = np.empty((len(outlines), n, 2))
    for i, G in enumerate(outlines):
        out[i, :len(G)] = G
        out[i, len(G):] = G[-1]
    return out


def edges(V: np.ndarray, H: np.ndarray) -> tuple[np.ndarray, ...]:
    """The edges of closed outlines, one a row (values `V`, heights `H`, each (rows, vertices)), as
    (low, high, start height, height step, start value, value step), each (rows, edges). An edge
    along a height (no height step) becomes a point at its start vertex; its end vertex is the next
    edge's start, so every outline's extremes keep every vertex value at its height."""
    y0, y1 = H[:, :-1], H[:, 1:]
    flat = y0 == y1
    return (np.minimum(y0, y1), np.maximum(y0, y1), y0, np.where(flat, 1.0, y1 - y0), V[:, :-1],
            np.where(flat, 0.0, V[:, 1:] - V[:, :-1]))


def _at(Y: np.ndarray, E: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Which edges of each row's outline cross each of its heights `Y`, and their values there
    (rows, heights, edges): start + t * step, as `rows._outline_x_at`."""
    lo, hi, y0, dy, v0, dv = (e[:, None, :] for e in E)
    Yb = Y[:, :, None]
    return (Yb >= lo) & (Yb <= hi), v0 + ((Yb - y0) / dy) * dv


def extremes(Y: np.ndarray, E: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Greatest and least value of each row's outline (`edges`) at each of its heights `Y` (rows,
    heights): -inf and inf where it has none. The same arithmetic as `rows._outline_x_at`, so the
    same numbers, for many outlines at once."""
    cross, v = _at(Y, E)
    return np.where(cross, v, -np.inf).max(axis=2), np.where(cross, v, np.inf).min(axis=2)


def greatest(Y: np.ndarray, E: tuple[np.ndarray, ...]) -> np.ndarray:
    """The greatest of `extremes` alone."""
    cross, v = _at(Y, E)
    return np.where(cross, v, -np.inf).max(axis=2)


def least(Y: np.ndarray, E: tuple[np.ndarray, ...]) -> np.ndarray:
    """The least of `extremes` alone."""
    cross, v = _at(Y, E)
    return np.where(cross, v, np.inf).min(axis=2)


def shifts_past(grown: list[np.ndarray], parts: list[np.ndarray]) -> np.ndarray:
    """Per pair (grown[k], parts[k]) of (x, y) outlines: the least x shift putting the part right of
    the grown outline at every height both span (-inf when they share none), `rows._shift_past` for
    every pair in one go. The largest difference of the two lies at one of their vertices' heights,
    so it is taken over those: each outline at its own and at the other's."""
    G, P = padded(grown), padded(parts)
    Hs = np.concatenate([G[:, :, 1], P[:, :, 1]], axis=1)
    g_right = greatest(Hs, edges(G[:, :, 0], G[:, :, 1]))
    p_left = least(Hs, edges(P[:, :, 0], P[:, :, 1]))
    lo = np.maximum(G[:, :, 1].min(axis=1), P[:, :, 1].min(axis=1))[:, None]
    hi = np.minimum(G[:, :, 1].max(axis=1), P[:, :, 1].max(axis=1))[:, None]
    return np.where((Hs >= lo) & (Hs <= hi), g_right - p_left, -np.inf).max(axis=1)


def grow(P: np.ndarray, gap: float) -> np.ndarray:
    """Outline `P` grown by `gap` with mitred corners (shapely `buffer`: never closer than the gap)."""
    return np.asarray(Polygon(P).buffer(gap, join_style="mitre", mitre_limit=10.0).exterior.coords)


def grow_all(outlines: list[np.ndarray], gap: float) -> list[np.ndarray]:
    """`grow` of each outline, all of the same length, in one call of shapely's vectorised buffer."""
    grown = shapely.buffer(shapely.polygons(np.stack(outlines)), gap, quad_segs=16, cap_style="round",
                           join_style="mitre", mitre_limit=10.0)
    xy, which = shapely.get_coordinates(shapely.get_exterior_ring(grown), return_index=True)
    return np.split(xy, np.flatnonzero(np.diff(which)) + 1)


def rotate_points(P: np.ndarray, angle: float) -> np.ndarray:
    """Points `P` (n, 2) rotated by `angle` [deg] about the origin."""
    a = math.radians(angle)
    R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return P @ R.T
