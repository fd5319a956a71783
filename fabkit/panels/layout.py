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
- Creases (a pleated surface): grid rows where the surface kinks (`crease_rows`) become the
  bands' middles: one crease per band, the band boundaries (arcs) halfway between neighbouring
  creases, so every panel's middle column of faces crosses its band's crease. Faces carry
  `strip` (0 before the crease, 1 after), `column` and `middle` (one face per strip, in the
  middle column) tags: the refold's and toolpath's contract for the hinges the robot drives.
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

__all__ = ["Panel", "PanelLayout", "layout_panels", "resample_rows", "crease_rows", "CREASE_ANGLE"]

#: A grid row whose edges' fold angle jumps by more than this on average is a crease [rad] (5 degrees).
CREASE_ANGLE = np.radians(5.0)


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
    creases: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # crease grid rows

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


def crease_rows(surface: GridSurface, min_angle: float = CREASE_ANGLE) -> np.ndarray:
    """Interior grid rows along which the surface kinks: the mean, over the row's edges, of the
    fold-angle jump against the parallel edges beside them (`fabkit.structure.creases.crease_jumps`,
    the crease measure every stage uses) exceeds `min_angle`. A jump, not a bare threshold: the
    facets of a coarsely subdivided smooth surface turn by 5-10 deg on several rows in a row and
    are no crease."""
    from fabkit.structure.creases import crease_jumps

    nu, nv = surface.shape
    if nu < 2 or nv < 3:
        return np.zeros(0, np.int64)
    jump, _ = crease_jumps(surface.mesh)
    idx = surface.index
    rows = []
    for j in range(1, nv - 1):  # the edges of grid row j run across the surface, from point (i, j) to (i+1, j)
        edges = surface.mesh.topology.edge_ids(np.stack([idx[:-1, j], idx[1:, j]], axis=1))
        row_jump = jump[edges[edges >= 0]]
        row_jump = row_jump[np.isfinite(row_jump)]
        if len(row_jump) and row_jump.mean() > min_angle:
            rows.append(j)
    return np.array(rows, dtype=np.int64)


def _arcs_between(creases: np.ndarray, nv: int) -> np.ndarray:
    """Band boundaries halfway between neighbouring creases (rounded mirror-symmetrically)."""
    R = len(creases)
    mid = [(creases[b - 1] + creases[b]) // 2 if 2 * b <= R else -((-(creases[b - 1] + creases[b])) // 2)
           for b in range(1, R)]
    return np.array([0, *mid, nv - 1], dtype=np.int64)


def layout_panels(surface: GridSurface, rows: int | None = None, cols: int = 3,
                  columns_per_panel: int = 6) -> PanelLayout:
    """Panelise `surface` into `rows` bands (in pairs) of `cols` panels (offset pairs: cols + 1).

    A surface with creases (`crease_rows`) gets one band per crease, the crease in its middle;
    `rows` must then be None or the number of creases. Without creases `rows` defaults to 14.
    """
    nu, nv = surface.shape
    creases = crease_rows(surface)
    if len(creases):
        if rows is not None and rows != len(creases):
            raise InputError(f"the surface has {len(creases)} creases, one per band: rows must be {len(creases)} "
                             f"(or left out), got {rows}")
        rows = len(creases)
    rows = 14 if rows is None else rows
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
    if len(creases):
        arcs = _arcs_between(creases, nv)
        if np.any(creases <= arcs[:-1]) or np.any(creases >= arcs[1:]):
            raise InputError("creases are too close together to put a band boundary between them")
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
            column = np.tile(np.arange(len(st) - 1), len(grid_rows) - 1)
            row = np.repeat(np.arange(len(grid_rows) - 1), len(st) - 1)
            fd = {"column": column, "row": row}
            inside = creases[(creases > grid_rows[0]) & (creases < grid_rows[-1])]
            if len(inside):
                # strip k: the faces past k creases; the middle column crosses every crease of the band
                fd["strip"] = np.searchsorted(inside, grid_rows[row], side="right").astype(np.int64)
                # one middle face per strip (the refold/toolpath contract): the middle column's face
                # in the strip's middle row; the crease hinges of that column are the driven ones
                strip = fd["strip"]
                mid_col = column == (len(st) - 1) // 2
                middle = np.zeros(len(column), np.int64)
                for s_id in range(len(inside) + 1):
                    rows_k = np.unique(row[strip == s_id])
                    middle[mid_col & (row == rows_k[len(rows_k) // 2])] = 1
                fd["middle"] = middle
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
                         singular_keys=singular, pair_offsets=offsets, creases=creases)
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
