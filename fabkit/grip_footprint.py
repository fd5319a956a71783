"""Can the suction cup hold this face? The cup's disc on one planar region of the panel.

A grip region is a set of faces joined across hinges that bend less than `max_bend` (rad) in every
fold state (default: the lip compliance over the cup radius). The cup's disc (radius from the cell's
tool) is put at the region's pole of inaccessibility (shapely's `polylabel`: the interior point
farthest from the outline) in the flat pattern; the region holds the cup when that distance is at
least the cup radius and the sheet under the disc is planar to `lip_compliance` (m) in every fold
state (points sampled over the disc, carried into each state by their triangle's barycentric
coordinates, distance to their best-fit plane). A single sliver face under a larger cup is refused.
Candidates are ranked by how much room the disc has (inscribed radius minus cup radius), then by
planarity, ties by the disc centre's coordinates (never by face or vertex order).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from shapely.geometry import Polygon
from shapely.ops import polylabel, unary_union

__all__ = ["GripCandidate", "grip_regions", "grip_candidates", "DEFAULT_LIP_COMPLIANCE"]

#: How far (m) the sheet under the cup may leave a plane and still seal (a bellows lip takes ~1 mm).
DEFAULT_LIP_COMPLIANCE = 0.5e-3
_RINGS = 4          # sample rings over the disc (plus the centre)


@dataclass(frozen=True)
class GripCandidate:
    """One grip region: `faces` polygon ids, `centre` (2,) disc centre in the flat pattern (m),
    `inscribed_m` the largest disc radius that fits, `planarity_m` worst distance of the sheet under
    the cup from a plane over all states, `ok` (fits and planar), `problem` why not."""

    faces: tuple[int, ...]
    centre: tuple[float, float]
    inscribed_m: float
    planarity_m: float
    ok: bool
    problem: str = ""

    @property
    def face(self) -> int:
        """The face under the disc centre (the grip face for the planner)."""
        return self.faces[0]


def grip_regions(seq, max_bend: float) -> list[np.ndarray]:
    """Triangle sets joined across hinges bending at most `max_bend` rad in every state of a
    `FoldSequence` (polygon diagonals always join)."""
    E = np.asarray(seq.edges)
    kind = np.asarray(seq.edge_kind)
    bend = np.abs(np.asarray(seq.angles)).max(axis=0)
    T = len(seq.tris)
    # triangle adjacency from the sorted edges of each triangle
    tri_edges = np.sort(np.stack([seq.tris[:, [0, 1]], seq.tris[:, [1, 2]], seq.tris[:, [2, 0]]], 1), axis=2)
    n = int(np.asarray(seq.flat_vertices).shape[0])
    keys = tri_edges[..., 0] * n + tri_edges[..., 1]
    ekeys = E[:, 0] * n + E[:, 1]
    eid = np.searchsorted(ekeys, keys)
    tri_of = np.repeat(np.arange(T), 3)
    eid = eid.ravel()
    join = (kind[eid] == "diagonal") | ((kind[eid] != "boundary") & (bend[eid] <= max_bend))
    order = np.argsort(eid[join], kind="stable")
    e_j, t_j = eid[join][order], tri_of[join][order]
    pair = e_j[1:] == e_j[:-1]
    a, b = t_j[:-1][pair], t_j[1:][pair]
    g = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(T, T))
    k, label = connected_components(g, directed=False)
    return [np.flatnonzero(label == c) for c in range(k)]


def _disc_samples(centre, radius) -> np.ndarray:
    pts = [np.asarray(centre, np.float64)]
    for i in range(1, _RINGS + 1):
        m = 8 * i
        ang = np.arange(m) * 2 * np.pi / m
        pts.append(np.column_stack([np.cos(ang), np.sin(ang)]) * radius * i / _RINGS + centre)
    return np.vstack([p.reshape(-1, 2) for p in pts])


def _planarity(seq, tris: np.ndarray, pts: np.ndarray) -> float:
    """Worst best-fit-plane distance of the disc samples over all states (m)."""
    V = np.asarray(seq.flat_vertices)[:, :2]
    X = np.asarray(seq.positions)
    tri_v = np.asarray(seq.tris)[tris]
    A, B, C = V[tri_v[:, 0]], V[tri_v[:, 1]], V[tri_v[:, 2]]
    det = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (C[:, 0] - A[:, 0]) * (B[:, 1] - A[:, 1])
    owner, bary = np.full(len(pts), -1), np.zeros((len(pts), 3))
    for i, p in enumerate(pts):
        u = ((p[0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (C[:, 0] - A[:, 0]) * (p[1] - A[:, 1])) / det
        v = ((B[:, 0] - A[:, 0]) * (p[1] - A[:, 1]) - (p[0] - A[:, 0]) * (B[:, 1] - A[:, 1])) / det
        w = 1 - u - v
        inside = (u >= -1e-9) & (v >= -1e-9) & (w >= -1e-9)
        if inside.any():
            j = int(np.flatnonzero(inside)[0])
            owner[i], bary[i] = j, (w[j], u[j], v[j])
    keep = owner >= 0
    worst = 0.0
    for s in range(X.shape[0]):
        P = np.einsum("kc,kcd->kd", bary[keep], X[s][tri_v[owner[keep]]])
        Q = P - P.mean(axis=0)
        normal = np.linalg.svd(Q, full_matrices=False)[2][-1]
        worst = max(worst, float(np.abs(Q @ normal).max()))
    return worst


def grip_candidates(seq, cup_radius: float, *, lip_compliance: float = DEFAULT_LIP_COMPLIANCE,
                    max_bend: float | None = None, faces=None) -> list[GripCandidate]:
    """Ranked grip regions of a `FoldSequence` for a cup of `cup_radius` (m); `faces` limits the
    regions to those containing one of these polygon ids (e.g. the faces of one wing)."""
    if not cup_radius > 0:
        raise ValueError("the cup radius must be positive")
    bend = lip_compliance / cup_radius if max_bend is None else float(max_bend)
    V = np.asarray(seq.flat_vertices)[:, :2]
    out = []
    for tris in grip_regions(seq, bend):
        polys = np.unique(np.asarray(seq.tri_face)[tris])
        if faces is not None and not np.isin(polys, list(faces)).any():
            continue
        region = unary_union([Polygon(V[t]) for t in np.asarray(seq.tris)[tris]]).buffer(0)
        if region.geom_type != "Polygon":
            region = max(region.geoms, key=lambda g: g.area)
        pole = polylabel(region, tolerance=cup_radius * 1e-3)
        centre = np.array(pole.coords[0])
        inscribed = float(region.exterior.distance(pole))
        for hole in region.interiors:
            inscribed = min(inscribed, float(hole.distance(pole)))
        flat_ok = inscribed >= cup_radius
        planarity = _planarity(seq, tris, _disc_samples(centre, min(cup_radius, inscribed)))
        # the face under the centre first
        tri_v = np.asarray(seq.tris)[tris]
        under = [int(np.asarray(seq.tri_face)[t]) for t, tv in zip(tris, tri_v) if Polygon(V[tv]).buffer(1e-12)
                 .contains(pole)]
        ordered = tuple(dict.fromkeys(under + polys.tolist()))
        problem = ""
        if not flat_ok:
            problem = (f"the {2000 * cup_radius:.0f} mm cup does not fit: the widest disc on faces "
                       f"{list(ordered[:4])}{'...' if len(ordered) > 4 else ''} is {2000 * inscribed:.1f} mm")
        elif planarity > lip_compliance:
            problem = f"the sheet under the cup leaves its plane by {planarity * 1000:.2f} mm (lip takes " \
                      f"{lip_compliance * 1000:.2f} mm)"
        out.append(GripCandidate(faces=ordered, centre=(float(centre[0]), float(centre[1])), inscribed_m=inscribed,
                                 planarity_m=planarity, ok=not problem, problem=problem))
    out.sort(key=lambda c: (not c.ok, -round(c.inscribed_m, 9), round(c.planarity_m, 9), round(c.centre[0], 9),
                            round(c.centre[1], 9)))
    return out
