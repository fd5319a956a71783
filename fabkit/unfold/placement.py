"""Put a development where a cutter wants it: smallest bounding rectangle along x/y, corner at (0, 0)."""
from __future__ import annotations

import numpy as np
import shapely

__all__ = ["place_on_sheet"]


def place_on_sheet(uv: np.ndarray, used: np.ndarray | None = None) -> np.ndarray:
    """Rigidly move `uv` (a rotation and a translation, never a mirror) so that its minimum-area
    bounding rectangle (shapely's oriented envelope) is axis-aligned with its long side along x,
    and its bounding box starts at (0, 0).

    The direction of the long side is fixed by the first used vertex (it lands on the -x side of
    the centroid, or on it), so the result does not depend on the input's position or rotation.
    """
    uv = np.asarray(uv, dtype=np.float64)
    used = np.ones(len(uv), dtype=bool) if used is None else np.asarray(used, dtype=bool)
    P = uv[used]
    c = P.mean(axis=0)
    X = P - c
    rect = shapely.oriented_envelope(shapely.MultiPoint(X))
    a = np.array([1.0, 0.0])
    if isinstance(rect, shapely.Polygon):
        corners = np.asarray(rect.exterior.coords)[:4]
        sides = np.diff(np.vstack([corners, corners[:1]]), axis=0)
        k = int(np.argmax(np.linalg.norm(sides, axis=1)))
        if np.linalg.norm(sides[k]) > 0:
            a = sides[k] / np.linalg.norm(sides[k])
    elif isinstance(rect, shapely.LineString) and rect.length > 0:  # collinear points
        q = np.asarray(rect.coords)
        a = (q[-1] - q[0]) / np.linalg.norm(q[-1] - q[0])
    if X[0] @ a > 0:
        a = -a
    b = np.array([-a[1], a[0]])
    out = (uv - c) @ np.stack([a, b], axis=1)
    out -= out[used].min(axis=0)
    out[~used] = 0.0
    return out
