"""The row nesting's last sheet: nested again on its own, or across the sheet, when that leaves a
longer offcut at its right end (`fabkit.nest.rows`, module docstring)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from shapely.geometry import Polygon

from fabkit.nest.engines import NestOptions, Placement, grain_angles, place
from fabkit.nest.rows import _pack

__all__ = ["used_length", "last_sheet_across", "last_sheet_again"]


def used_length(placements: list[Placement], parts: list[Polygon]) -> float:
    """Rightmost x [mm] of the placed parts."""
    return max(place(parts[p.part], p).bounds[2] for p in placements)


def last_sheet_across(placements: list[Placement], n: int, parts: list[Polygon], options: NestOptions,
                      grain) -> list[Placement] | None:
    """The last sheet's parts nested again with shelves across the sheet (along its short side),
    stacked from its left end, when that leaves a longer offcut at its right end; None otherwise.
    Nested on the sheet turned by 90 deg (grain x there is grain y here), then turned back."""
    W, H = options.sheet
    m = options.edge
    last = [p for p in placements if p.sheet == n - 1]
    ids = [p.part for p in last]
    turned = {"none": "none", "x": "y", "y": "x"}[options.grain]
    across = replace(options, sheet=(H, W), grain=turned)
    items = [[(i, 0.0, np.asarray(parts[i].exterior.coords))] for i in ids]
    moved, sheets, _ = _pack(items, parts, across, grain_angles(across))
    if sheets != 1:
        return None
    back = []
    for p in moved:  # (x', y') on the turned sheet is (y', H - x') here: a turn by -90 deg
        back.append(Placement(part=p.part, sheet=n - 1, angle=(p.angle - 90.0) % 360.0, x=p.y, y=H - p.x))
    inside = all(b[0] >= m - 1e-6 and b[1] >= m - 1e-6 and b[2] <= W - m + 1e-6 and b[3] <= H - m + 1e-6
                 for b in (place(parts[p.part], p).bounds for p in back))
    if not inside or used_length(back, parts) >= used_length(last, parts) - 1e-9:
        return None  # a part that only fits along the sheet, or no longer offcut
    keep = [p for p in placements if p.sheet != n - 1]
    return sorted(keep + back, key=lambda p: p.part)


def last_sheet_again(placements: list[Placement], n: int, parts: list[Polygon], options: NestOptions,
                     grain) -> list[Placement]:
    """The last sheet's parts nested again on their own (after some left it): kept when shorter."""
    ids = [p.part for p in placements if p.sheet == n - 1]
    items = [[(i, 0.0, np.asarray(parts[i].exterior.coords))] for i in ids]
    moved, sheets, _ = _pack(items, parts, options, grain)
    last = [p for p in placements if p.sheet == n - 1]
    if sheets != 1 or used_length(moved, parts) >= used_length(last, parts) - 1e-9:
        return placements
    keep = [p for p in placements if p.sheet != n - 1]
    return sorted(keep + [replace(p, sheet=n - 1) for p in moved], key=lambda p: p.part)
