"""Put a development where a cutter wants it: principal axes along x/y, bounding box at the origin."""
from __future__ import annotations

import numpy as np

__all__ = ["place_on_sheet"]


def place_on_sheet(uv: np.ndarray, used: np.ndarray | None = None) -> np.ndarray:
    """Rigidly move `uv` (a rotation and a translation, never a mirror) so that its longest
    principal axis runs along +x and its bounding box starts at (0, 0).

    The sign of the axis is fixed by the first used vertex (it lands on the -x side of the centroid
    or on it), so the result does not depend on the input's position or rotation.
    """
    uv = np.asarray(uv, dtype=np.float64)
    used = np.ones(len(uv), dtype=bool) if used is None else np.asarray(used, dtype=bool)
    P = uv[used]
    c = P.mean(axis=0)
    X = P - c
    _, vecs = np.linalg.eigh(X.T @ X)
    a = vecs[:, 1]
    if X[0] @ a > 0:
        a = -a
    b = np.array([-a[1], a[0]])
    out = (uv - c) @ np.stack([a, b], axis=1)
    out -= out[used].min(axis=0)
    out[~used] = 0.0
    return out
