"""Nesting engines: row nesting (`fabkit.nest.rows`), sparrow strip packing split into sheets, and
the bounding-box shelf baseline."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import Polygon, box

from fabkit.errors import InputError, ToleranceError
from fabkit.nest.spacing import CutSpacing, cut_spacing

__all__ = ["NestOptions", "Placement", "Nesting", "nest_parts", "place", "grain_angles", "ENGINES"]

#: nesting engines: row nesting (default), sparrow, and the bounding-box shelf baseline
ENGINES = ("rows", "packingsolver", "shelf")


#: the distances of the sheet a run is costed as when no material is named: 1 mm, laser cut
_DEFAULT_CUT = cut_spacing()


@dataclass(frozen=True)
class NestOptions:
    """Sheet size, distances and engine of a nesting; the default distances are
    `fabkit.nest.spacing.cut_spacing()` (1 mm sheet, laser cut; `for_cut` for another sheet)."""

    sheet: tuple[float, float] = (2500.0, 1250.0)  # mm
    spacing: float = _DEFAULT_CUT.spacing          # web between parts' kerfs [mm] (gap = spacing + kerf)
    kerf: float = _DEFAULT_CUT.kerf                # cutting kerf [mm], added to the gap between parts
    edge: float = _DEFAULT_CUT.edge                # part outlines to the sheet's edge [mm]
    grain: str = "none"                            # "none" (any rotation), "x" or "y": grain axis direction
    engine: str = "rows"                           # "rows", "packingsolver" (sparrow) or "shelf"
    time_limit: float = 30.0                       # seconds per strip solve (packingsolver)
    seed: int = 0

    @property
    def gap(self) -> float:
        return self.spacing + self.kerf

    @classmethod
    def for_cut(cls, cut: CutSpacing, **kw) -> "NestOptions":
        """Options with the distances of `cut` (`fabkit.nest.spacing.cut_spacing`), the rest from `kw`."""
        return cls(spacing=cut.spacing, kerf=cut.kerf, edge=cut.edge, **kw)


@dataclass(frozen=True)
class Placement:
    """Part `part` on sheet `sheet`: sheet point = R(angle) @ part point + (x, y), angle in degrees."""

    part: int
    sheet: int
    angle: float
    x: float
    y: float

    def matrix(self) -> np.ndarray:
        a = math.radians(self.angle)
        return np.array([[math.cos(a), -math.sin(a), self.x], [math.sin(a), math.cos(a), self.y]])

    def apply(self, pts: np.ndarray) -> np.ndarray:
        M = self.matrix()
        return np.asarray(pts, float) @ M[:, :2].T + M[:, 2]


@dataclass(frozen=True)
class Nesting:
    options: NestOptions
    placements: tuple[Placement, ...]     # one per part, in part order
    n_sheets: int
    part_area: float                      # mm^2
    seconds: float
    engine: str
    notes: tuple[str, ...] = field(default=())

    @property
    def sheet_area(self) -> float:
        return self.options.sheet[0] * self.options.sheet[1]

    @property
    def utilisation(self) -> float:
        """Part area / area of the sheets used (every sheet counted whole)."""
        return self.part_area / (self.n_sheets * self.sheet_area) if self.n_sheets else 0.0

    def used_length_utilisation(self, parts) -> float:
        """Part area / area used, the last sheet counted only up to its rightmost part (plus the margin):
        the rest of the last sheet is an offcut for the next job."""
        if not self.n_sheets:
            return 0.0
        last = [place(parts[p.part], p) for p in self.placements if p.sheet == self.n_sheets - 1]
        length = max(g.bounds[2] for g in last) + self.options.edge
        W, H = self.options.sheet
        return self.part_area / ((self.n_sheets - 1) * W * H + min(length, W) * H)

    def verify(self, parts, tol: float = 1e-6) -> list[str]:
        """Problems (empty when fine): every part exactly once, inside its sheet's margin, no two
        parts on a sheet closer than the gap (less `tol` mm)."""
        problems = []
        ids = sorted(p.part for p in self.placements)
        if ids != list(range(len(parts))):
            problems.append(f"parts placed {len(ids)} times for {len(parts)} parts (each must be placed once)")
        W, H = self.options.sheet
        m = self.options.edge
        inner = box(m - tol, m - tol, W - m + tol, H - m + tol)
        by_sheet: dict[int, list] = {}
        for p in self.placements:
            g = place(parts[p.part], p)
            if not inner.contains(g):
                problems.append(f"part {p.part} leaves sheet {p.sheet} or its {m:g} mm margin")
            by_sheet.setdefault(p.sheet, []).append((p.part, g))
        for s, items in by_sheet.items():
            geoms = [g for _, g in items]
            tree = shapely.STRtree(geoms)
            for i, g in enumerate(geoms):
                for j in tree.query(g, predicate="dwithin", distance=self.options.gap - tol):
                    if j > i:
                        problems.append(f"parts {items[i][0]} and {items[j][0]} on sheet {s} are "
                                        f"{g.distance(geoms[j]):.3f} mm apart (gap {self.options.gap:g} mm)")
        return problems


def place(part: Polygon, p: Placement) -> Polygon:
    """The part's polygon where `p` puts it on its sheet."""
    g = affinity.rotate(part, p.angle, origin=(0.0, 0.0))
    return affinity.translate(g, p.x, p.y)


def grain_angles(options: NestOptions) -> list[float] | None:
    """Allowed rotations of parts whose grain axis is along their x: None = free."""
    if options.grain == "none":
        return None
    if options.grain == "x":
        return [0.0, 180.0]
    if options.grain == "y":
        return [90.0, 270.0]
    raise InputError(f"grain must be none, x or y, got {options.grain!r}", source="--grain")


def _check_fits(parts, options: NestOptions) -> None:
    W, H = options.sheet
    m = options.edge
    for i, g in enumerate(parts):
        if options.grain == "none":
            a, b = sorted(_rect_sides(g.minimum_rotated_rectangle))
            s0, s1 = sorted((W - 2 * m, H - 2 * m))
            fits = a <= s0 and b <= s1
        else:
            x0, y0, x1, y1 = affinity.rotate(g, 0.0 if options.grain == "x" else 90.0, origin=(0, 0)).bounds
            a, b = sorted((x1 - x0, y1 - y0))
            fits = x1 - x0 <= W - 2 * m and y1 - y0 <= H - 2 * m
        if not fits:
            raise InputError(f"part {i} ({b:.0f} x {a:.0f} mm) does not fit a {W:g} x {H:g} mm sheet with "
                             f"{m:g} mm margins")


def _rect_sides(r: Polygon) -> tuple[float, float]:
    c = np.asarray(r.exterior.coords)[:4]
    return float(np.linalg.norm(c[1] - c[0])), float(np.linalg.norm(c[2] - c[1]))


# ---- shelf baseline ---------------------------------------------------------------------------

def _shelf(parts, options: NestOptions) -> tuple[list[Placement], int]:
    """First-fit decreasing height on shelves of bounding rectangles (the baseline)."""
    W, H = options.sheet
    m, gap = options.edge, options.gap
    oriented = []
    for i, g in enumerate(parts):
        if options.grain == "none":
            r = np.asarray(g.minimum_rotated_rectangle.exterior.coords)[:4]
            e = r[1] - r[0] if np.linalg.norm(r[1] - r[0]) >= np.linalg.norm(r[2] - r[1]) else r[2] - r[1]
            angle = -math.degrees(math.atan2(e[1], e[0]))  # long side along x
        else:
            angle = 0.0 if options.grain == "x" else 90.0
        gg = affinity.rotate(g, angle, origin=(0.0, 0.0))
        x0, y0, x1, y1 = gg.bounds
        oriented.append((i, angle, x0, y0, x1 - x0, y1 - y0))
    oriented.sort(key=lambda t: -t[5])
    shelves: list[list[float]] = []  # [sheet, y, height, x cursor]
    sheets = 0
    out = []
    for i, angle, x0, y0, w, h in oriented:
        spot = next((s for s in shelves if s[3] + w <= W - m and h <= s[2]), None)
        if spot is None:
            top = max((s[1] + s[2] + gap for s in shelves if s[0] == sheets - 1), default=None)
            if top is None or top + h > H - m:
                sheets += 1
                top = m
            spot = [sheets - 1, top, h, m]
            shelves.append(spot)
        out.append(Placement(part=i, sheet=int(spot[0]), angle=angle, x=spot[3] - x0, y=spot[1] - y0))
        spot[3] += w + gap
    return sorted(out, key=lambda p: p.part), sheets


# ---- sparrow (spyrrow) --------------------------------------------------------------------------

def _sparrow(parts, options: NestOptions) -> tuple[list[Placement], int, list[str]]:
    """Fill sheets from sparrow strip packings (module docstring of `fabkit.nest`)."""
    import spyrrow

    W, H = options.sheet
    m, gap = options.edge, options.gap
    usable = W - 2 * m
    angles = grain_angles(options)
    remaining = list(range(len(parts)))
    placements: list[Placement] = []
    sheets = 0
    notes = []
    rounds = 0
    while remaining:
        rounds += 1
        if rounds > 2 * len(parts) + 2:
            raise RuntimeError("nesting made no progress")
        items = [spyrrow.Item(str(i), [tuple(map(float, xy)) for xy in np.asarray(parts[i].exterior.coords)[:-1]],
                              demand=1, allowed_orientations=angles) for i in remaining]
        inst = spyrrow.StripPackingInstance("fabkit", strip_height=H - 2 * m, items=items)
        cfg = spyrrow.StripPackingConfig(early_termination=True, min_items_separation=gap if gap > 0 else None,
                                         total_computation_time=max(1, int(round(options.time_limit))),
                                         num_workers=1, seed=options.seed)
        sol = inst.solve(cfg)
        placed = []
        for it in sol.placed_items:
            i = int(it.id)
            p = Placement(part=i, sheet=0, angle=float(it.rotation), x=float(it.translation[0]),
                          y=float(it.translation[1]))
            g = place(parts[i], p)
            placed.append((i, p, g.bounds))
        n_whole = int(sol.width // usable) if sol.width > usable else 0
        last_round = sol.width <= usable
        keep, again = [], []
        for i, p, (x0, y0, x1, y1) in placed:
            k = int(max(0.0, x0) // usable)
            inside = x1 <= (k + 1) * usable + 1e-9
            if inside and (last_round or k < n_whole):
                keep.append((i, p, k))
            else:
                again.append(i)
        if not keep:  # a strip shorter than a sheet that still straddles: take it as one sheet
            raise RuntimeError("nesting made no progress (a part is longer than the sheet)")
        used = sorted({k for _, _, k in keep})
        renumber = {k: sheets + n for n, k in enumerate(used)}
        for i, p, k in keep:
            placements.append(Placement(part=i, sheet=renumber[k], angle=p.angle, x=p.x - k * usable + m, y=p.y + m))
        sheets += len(used)
        remaining = sorted(again)
    notes.append(f"sparrow strip packing: {rounds} strip solve(s), {options.time_limit:g} s limit each")
    return sorted(placements, key=lambda p: p.part), sheets, notes


def nest_parts(parts: list[Polygon], options: NestOptions = NestOptions()) -> Nesting:
    """Place `parts` (shapely polygons, mm) on sheets (see the module docstring of `fabkit.nest`)."""
    if options.engine not in ENGINES:
        raise InputError(f"unknown nesting engine {options.engine!r} ({', '.join(ENGINES)})", source="--nester")
    if not all(g.is_valid and g.area > 0 for g in parts):
        bad = next(i for i, g in enumerate(parts) if not (g.is_valid and g.area > 0))
        raise InputError(f"part {bad} is not a valid polygon (self-overlapping or empty outline)")
    grain_angles(options)
    _check_fits(parts, options)
    t0 = time.perf_counter()
    notes: list[str] = []
    if options.engine == "shelf" or not parts:
        placements, n = _shelf(parts, options)
    elif options.engine == "rows":
        from fabkit.nest.rows import nest_rows

        placements, n, notes = nest_rows(parts, options)
    else:
        placements, n, notes = _sparrow(parts, options)
    nesting = Nesting(options=options, placements=tuple(placements), n_sheets=n,
                      part_area=float(sum(g.area for g in parts)), seconds=time.perf_counter() - t0,
                      engine=options.engine, notes=tuple(notes))
    problems = nesting.verify(parts)
    if problems:  # never a cut file with parts missing, twice, overlapping or off the sheet
        raise ToleranceError(f"the {options.engine} nesting fails its verification ({len(problems)} problem"
                             f"{'s' if len(problems) > 1 else ''}; first: {problems[0]}); nothing is nested"
                             f"{'' if options.engine == 'rows' else ': try --nester rows'}")
    return nesting
