"""Panels between neighbouring arcs, in a staggered arrangement (paper §3.1–3.2, Figs. 14–15).

Definitions (the paper shows them only in figures, so they are fixed here):
- Arcs: `rows + 1` grid rows of the subdivided surface (iso-lines across it, planar). Band b is
  the strip of surface between arc b and arc b+1; its panels use every grid row in between.
- Walking arc lengths: every grid row is parametrised by its own normalised arc length t in
  [0, 1]; all panels sample rows at the global stations t = s / (cols * K), so neighbouring panels
  share their boundary vertices exactly.
- Staggering: bands come in pairs (2m, 2m+1). The two bands of a pair are aligned: their panel
  corners meet on the arc between them, where four panels share a corner — the *singularity
  points* (conical apexes, held fixed by the solver). Successive pairs are offset by half a panel
  (their first and last panels are half panels), so the arcs between pairs carry only T-junctions.
  Pair m's offset is `min(m, pairs-1-m) % 2`, which keeps the layout mirror-symmetric.
- Count: an aligned pair of bands with `cols` panels each has `cols - 1` interior four-panel
  corners, an offset pair `cols` of them (its `cols + 1` panels include two halves); the paper's
  n/2 is the large-`cols` limit. `PanelLayout.singularity_ratio` reports the measured ratio.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fabkit.errors import InputError
from fabkit.mesh import PolyMesh
from fabkit.panels.surface import GridSurface

__all__ = ["Panel", "PanelLayout", "layout_panels", "resample_rows"]


@dataclass(frozen=True)
class Panel:
    """One panel: a (n_rows+1) x (n_cols+1) grid of surface points between two arcs."""

    id: int
    band: int
    index: int            # position along the band
    rows: np.ndarray      # global grid-row indices (n_rows + 1,)
    stations: np.ndarray  # global station indices (n_cols + 1,)
    keys: np.ndarray      # (n_rows+1, n_cols+1) global point key = row * n_stations + station
    mesh: PolyMesh        # quads, CCW as the surface; vertex order = keys.ravel()
    fixed: np.ndarray     # bool per vertex: singularity points

    @property
    def name(self) -> str:
        return f"P{self.id:03d}_b{self.band:02d}_{self.index:02d}"


@dataclass(frozen=True)
class PanelLayout:
    surface: GridSurface
    arcs: np.ndarray            # grid-row index of each arc (rows + 1,)
    n_stations: int             # global stations per row (cols * K + 1)
    points: np.ndarray          # (n_grid_rows, n_stations, 3) resampled surface points
    panels: tuple[Panel, ...]
    singular_keys: np.ndarray   # global keys of the four-panel corners
    pair_offsets: np.ndarray    # offset (0/1 half panel) of every band pair
    shared_edges: tuple = field(default=())  # (panel_a, edge_a, panel_b, edge_b) per shared boundary edge

    @property
    def singularity_ratio(self) -> float:
        """Four-panel corners per panel (the paper says 1/2)."""
        return len(self.singular_keys) / max(1, len(self.panels))


def resample_rows(points: np.ndarray, n_stations: int) -> np.ndarray:
    """Resample every grid row (along axis 0 of `points[:, j]`) at equal normalised arc length.

    points: (nu, nv, 3) -> (nv, n_stations, 3); station s sits at t = s / (n_stations - 1).
    """
    rows = np.transpose(points, (1, 0, 2))  # (nv, nu, 3): each row runs across the surface
    seg = np.linalg.norm(np.diff(rows, axis=1), axis=2)
    cum = np.concatenate([np.zeros((len(rows), 1)), np.cumsum(seg, axis=1)], axis=1)
    t = cum / cum[:, -1:]
    targets = np.arange(n_stations) / (n_stations - 1)
    out = np.empty((len(rows), n_stations, 3))
    for j in range(len(rows)):
        for d in range(3):
            out[j, :, d] = np.interp(targets, t[j], rows[j, :, d])
    return out


def _grid_quads(n_r: int, n_c: int) -> np.ndarray:
    """Quads of an (n_r+1) x (n_c+1) vertex grid, row-major vertex ids."""
    r, c = np.meshgrid(np.arange(n_r), np.arange(n_c), indexing="ij")
    a = r * (n_c + 1) + c
    return np.stack([a, a + 1, a + n_c + 2, a + n_c + 1], axis=-1).reshape(-1, 4)


def layout_panels(surface: GridSurface, rows: int = 14, cols: int = 3, columns_per_panel: int = 6) -> PanelLayout:
    """Panelise `surface` into `rows` bands (in pairs) of `cols` panels (offset pairs: cols + 1)."""
    nu, nv = surface.shape
    if rows < 2 or rows % 2:
        raise InputError(f"rows must be an even number >= 2 (bands come in aligned pairs), got {rows}")
    if cols < 1:
        raise InputError(f"cols must be >= 1, got {cols}")
    K = int(columns_per_panel)
    if K < 2 or K % 2:
        raise InputError(f"columns per panel must be even and >= 2 (half-panel offsets), got {K}")
    if rows > nv - 1:
        raise InputError(f"{rows} bands need at least {rows + 1} grid rows; the surface has {nv}")
    # arc rows: evenly spaced, rounded symmetrically (arc rows-b mirrors arc b) so a mirror-symmetric
    # surface gives a mirror-symmetric layout
    arcs = np.array([(b * (nv - 1)) // rows if 2 * b <= rows else nv - 1 - ((rows - b) * (nv - 1)) // rows
                     for b in range(rows + 1)], dtype=np.int64)
    if np.any(np.diff(arcs) < 1):
        raise InputError("bands would be empty: use fewer rows or subdivide more")
    n_st = cols * K + 1
    pts = resample_rows(surface.points, n_st)
    pairs = rows // 2
    offsets = np.array([min(m, pairs - 1 - m) % 2 for m in range(pairs)], dtype=np.int64)

    panels = []
    corners_per_key: dict[int, set[int]] = {}
    for b in range(rows):
        off = offsets[b // 2] * (K // 2)
        bounds = [0] + [off + k * K for k in range(cols + 1) if 0 < off + k * K < n_st - 1] + [n_st - 1]
        grid_rows = np.arange(arcs[b], arcs[b + 1] + 1)
        for k, (s0, s1) in enumerate(zip(bounds[:-1], bounds[1:])):
            st = np.arange(s0, s1 + 1)
            keys = grid_rows[:, None] * n_st + st[None, :]
            V = pts[grid_rows][:, st].reshape(-1, 3)
            quads = _grid_quads(len(grid_rows) - 1, len(st) - 1)
            n_faces = len(quads)
            fd = {"column": np.tile(np.arange(len(st) - 1), len(grid_rows) - 1),
                  "row": np.repeat(np.arange(len(grid_rows) - 1), len(st) - 1)}
            mesh = PolyMesh(V, quads, face_data=fd)
            if np.dot(mesh.face_normal_sums.sum(axis=0), surface.mesh.face_normal_sums.sum(axis=0)) < 0:
                mesh = PolyMesh(V, quads[:, ::-1], face_data=fd)
            pid = len(panels)
            for key in (keys[0, 0], keys[0, -1], keys[-1, 0], keys[-1, -1]):
                corners_per_key.setdefault(int(key), set()).add(pid)
            panels.append(Panel(id=pid, band=b, index=k, rows=grid_rows, stations=st, keys=keys, mesh=mesh,
                                fixed=np.zeros(mesh.n_vertices, dtype=bool)))
    singular = np.array(sorted(k for k, ps in corners_per_key.items() if len(ps) == 4), dtype=np.int64)
    sing_set = set(singular.tolist())
    final = []
    for p in panels:
        fixed = np.array([int(k) in sing_set for k in p.keys.ravel()])
        final.append(Panel(**{**p.__dict__, "fixed": fixed}))
    layout = PanelLayout(surface=surface, arcs=arcs, n_stations=n_st, points=pts, panels=tuple(final),
                         singular_keys=singular, pair_offsets=offsets)
    return PanelLayout(**{**layout.__dict__, "shared_edges": tuple(find_shared_edges(layout.panels))})


def find_shared_edges(panels) -> list[tuple[int, int, int, int]]:
    """Boundary edges that two panels share: `(panel_a, edge_a, panel_b, edge_b)` (edge ids per panel)."""
    owner: dict[tuple[int, int], tuple[int, int]] = {}
    shared = []
    for p in panels:
        keys = p.keys.ravel()
        E = p.mesh.edges
        bmask = p.mesh.topology.boundary_edge_mask
        for e in np.flatnonzero(bmask):
            a, b = int(keys[E[e, 0]]), int(keys[E[e, 1]])
            key = (min(a, b), max(a, b))
            if key in owner:
                pa, ea = owner[key]
                shared.append((pa, ea, p.id, int(e)))
            else:
                owner[key] = (p.id, int(e))
    return shared
