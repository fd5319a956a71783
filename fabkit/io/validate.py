"""The one check every reader makes on the coordinates it read: finite and of a physical size.

A fabkit model is a sheet-metal panel or a building-scale surface; 1e6 m (1000 km) is far beyond
any of them and keeps every derived quantity (squared lengths, areas, Newton steps) far from
float64 overflow, so a larger value is a broken or hostile file, not a design.
"""
from __future__ import annotations

import numpy as np

from fabkit.errors import MeshError

__all__ = ["MAX_COORDINATE_M", "check_coordinates"]

#: largest |coordinate| fabkit reads, in metres
MAX_COORDINATE_M = 1e6


def check_coordinates(values, source: str | None, what: str = "vertex") -> np.ndarray:
    """Return `values` as a float array; `MeshError` naming the first row with a non-finite or
    absurd (> 1e6 m in magnitude) coordinate: "<what> <row> has a coordinate ..."."""
    a = np.asarray(values, dtype=np.float64)
    rows = a.reshape(len(a), -1) if a.ndim else a.reshape(1, 1)
    bad = ~np.all(np.isfinite(rows) & (np.abs(rows) <= MAX_COORDINATE_M), axis=1)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        worst = rows[i][np.argmax(~np.isfinite(rows[i]) | (np.abs(np.nan_to_num(rows[i], nan=np.inf))
                                                           > MAX_COORDINATE_M))]
        why = (f"a non-finite coordinate {worst:g}" if not np.isfinite(worst) else
               f"coordinate {worst:g}, beyond ±{MAX_COORDINATE_M:g} m (1000 km): not a fabrication-scale model")
        raise MeshError(f"{what} {i} has {why}", source=source)
    return a
