"""The parts of a multi-panel run (flat patterns in mm) and their nesting."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry import Polygon

from fabkit.nest.engines import NestOptions, Nesting, nest_parts

__all__ = ["PanelNesting", "panel_parts", "nest_panels", "MM_PER_M"]

MM_PER_M = 1000.0


@dataclass(frozen=True)
class PanelNesting:
    """`nesting` of `parts` (polygons in part coordinates, mm); `pre[i]` (2x3) maps panel i's
    development (mm) to its part coordinates: its first arc along +x (the grain axis), lower-left at 0."""

    nesting: Nesting
    parts: tuple
    pre: tuple
    names: tuple

    @property
    def placements(self):
        return self.nesting.placements

    def sheet_transform(self, i: int) -> np.ndarray:
        """2x3 matrix: panel i's development (mm) -> its sheet (mm)."""
        P = self.nesting.placements[i].matrix()
        A = np.vstack([self.pre[i], [0, 0, 1]])
        return (np.vstack([P, [0, 0, 1]]) @ A)[:2]


def _outline_mm(panel, uv: np.ndarray) -> np.ndarray:
    loop = max(panel.mesh.boundary_loops, key=len)
    return np.asarray(uv)[loop] * MM_PER_M


def panel_parts(run) -> tuple[list[Polygon], list[np.ndarray]]:
    """Outline polygon (mm) of every panel's development, turned so its first arc runs along +x."""
    parts, pre = [], []
    for p, r in zip(run.layout.panels, run.results):
        uv = np.asarray(r.uv) * MM_PER_M
        d = uv[len(p.stations) - 1] - uv[0]  # the first grid row: along the arc
        a = -np.arctan2(d[1], d[0])
        R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        pts = _outline_mm(p, r.uv) @ R.T
        t = -pts.min(axis=0)
        parts.append(Polygon(pts + t))
        pre.append(np.column_stack([R, t]))
    return parts, pre


def nest_panels(production_or_geometry, options: NestOptions = NestOptions()) -> PanelNesting:
    """Nest every panel's flat pattern (a `ProductionRun` or a `PanelsRun`)."""
    run = getattr(production_or_geometry, "geometry", production_or_geometry)
    parts, pre = panel_parts(run)
    nesting = nest_parts(parts, options)
    return PanelNesting(nesting=nesting, parts=tuple(parts), pre=tuple(pre),
                        names=tuple(p.name for p in run.layout.panels))
