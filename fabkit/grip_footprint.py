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

A pad of several cups (`fabkit.sheet.pad.CupPad`) sits where the planner puts the TCP, on the grip
face's centroid, turned by the tool's yaw: `pad_footprint` puts the disc that covers every lip
(`CupPad.footprint_radius`, any yaw) there and applies the same rule (inside the grip region,
planar to the lip compliance in every state). `FoldGeometry.of_fold` gives both functions what
they need from a FOLD file's fold states.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from shapely.geometry import Polygon
from shapely.ops import polylabel, unary_union

__all__ = ["GripCandidate", "grip_regions", "grip_candidates", "pad_footprint", "FoldGeometry", "cup_footprint_record",
           "cup_fit", "DEFAULT_LIP_COMPLIANCE"]

#: How far (m) the sheet under the cup may leave a plane and still seal (a bellows lip takes ~1 mm).
DEFAULT_LIP_COMPLIANCE = 0.5e-3
_RINGS = 4          # sample rings over the disc (plus the centre)


@dataclass(frozen=True)
class GripCandidate:
    """One grip region: `faces` polygon ids, `centre` (2,) disc centre in the flat pattern (m),
    `inscribed_m` the largest disc radius that fits, `planarity_m` worst distance of the sheet under
    the cup from a plane over all states, `ok` (fits and planar), `problem` why not, `fits` the disc
    lies on the region in the flat pattern (the part of the rule no fold state changes)."""

    faces: tuple[int, ...]
    centre: tuple[float, float]
    inscribed_m: float
    planarity_m: float
    ok: bool
    problem: str = ""
    fits: bool = True

    @property
    def face(self) -> int:
        """The face under the disc centre (the grip face for the planner)."""
        return self.faces[0]


def grip_regions(seq, max_bend: float, *, rulings_join: bool = False) -> list[np.ndarray]:
    """Triangle sets joined across hinges bending at most `max_bend` rad in every state of a
    `FoldSequence` (polygon diagonals always join; with `rulings_join` rulings too: the sheet is one
    piece across them and the planarity test then measures it)."""
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
    if rulings_join:
        join |= kind[eid] == "ruling"
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
                                 planarity_m=planarity, ok=not problem, problem=problem, fits=flat_ok))
    out.sort(key=lambda c: (not c.ok, -round(c.inscribed_m, 9), round(c.planarity_m, 9), round(c.centre[0], 9),
                            round(c.centre[1], 9)))
    return out


@dataclass(frozen=True, eq=False)
class FoldGeometry:
    """What the footprint rule reads from a fold sequence: triangle mesh `flat_vertices` (n, 3),
    `tris` (T, 3), `tri_face` (T,) polygon ids, `edges` (E, 2) sorted, `edge_kind` (E,) boundary /
    crease / ruling / diagonal, `angles` (S, E) rad and `positions` (S, n, 3) per fold state (the
    fields of a `fabkit.refold.FoldSequence`)."""

    flat_vertices: np.ndarray
    tris: np.ndarray
    tri_face: np.ndarray
    edges: np.ndarray
    edge_kind: np.ndarray
    angles: np.ndarray
    positions: np.ndarray

    @classmethod
    def of_fold(cls, model) -> "FoldGeometry":
        """From a `FoldModel` with fold states: its triangles (`fabkit.hold_model_fold.fold_triangles`),
        edge kinds (`edges_fabkit:kind`, else B boundary, M/V crease, F/J diagonal, others ruling)
        and each frame's fold angles (0 where a frame has none)."""
        from fabkit.hold_model_fold import fold_triangles

        tris, tri_face = fold_triangles(model)
        ev = np.sort(np.asarray(model.edges_vertices, np.int64), axis=1)
        order = np.lexsort((ev[:, 1], ev[:, 0]))
        kind_tag = model.edges_data.get("kind")
        if kind_tag is not None:
            names = np.array(["boundary", "crease", "ruling", "diagonal"])[np.asarray(kind_tag, np.int64)]
        else:
            a = np.char.upper(np.asarray(model.edges_assignment).astype(str))
            names = np.where(a == "B", "boundary", np.where(np.isin(a, ["M", "V"]), "crease",
                             np.where(np.isin(a, ["F", "J"]), "diagonal", "ruling")))
        frames = model.frames
        E = len(ev)
        angles = np.array([np.zeros(E) if f.edges_fold_angle is None else np.nan_to_num(np.asarray(f.edges_fold_angle))
                           for f in frames]).reshape(len(frames), E)
        V = np.asarray(model.vertices_coords, np.float64)
        pos = np.array([np.asarray(f.vertices_coords, np.float64) for f in frames]).reshape(len(frames), *V.shape)
        return cls(flat_vertices=V, tris=tris, tri_face=tri_face, edges=ev[order], edge_kind=names[order],
                   angles=angles[:, order], positions=pos)


def pad_footprint(seq, face: int, radius: float, *, lip_compliance: float = DEFAULT_LIP_COMPLIANCE,
                  max_bend: float | None = None, cup_radius: float | None = None,
                  rulings_join: bool = False, tool: str = "pad") -> GripCandidate:
    """The pad's footprint on grip face `face` (polygon id): the disc of `radius` [m] (the pad's
    `footprint_radius`) about the face's centroid in the flat pattern, on the grip region of that
    face (hinges bending at most `max_bend`, default the lip compliance over `cup_radius`, itself
    default `radius`). `ok` when the disc lies inside the region and the sheet under it is planar to
    `lip_compliance` in every state; `problem` says why not. With `rulings_join` the region is the
    sheet up to the creases and the outline (`grip_regions`). `tool` names it in `problem`."""
    if not radius > 0:
        raise ValueError(f"the {tool} radius must be positive")
    bend = lip_compliance / (radius if cup_radius is None else cup_radius) if max_bend is None else float(max_bend)
    V = np.asarray(seq.flat_vertices)[:, :2]
    tri_face = np.asarray(seq.tri_face)
    own = np.flatnonzero(tri_face == int(face))
    if len(own) == 0:
        raise ValueError(f"face {face} is not a face of the panel")
    verts = np.unique(np.asarray(seq.tris)[own])
    centre = V[verts].mean(axis=0)          # the face frame's origin: the mean of its distinct vertices
    tris = next(t for t in grip_regions(seq, bend, rulings_join=rulings_join) if np.isin(own, t).any())
    region = unary_union([Polygon(V[t]) for t in np.asarray(seq.tris)[tris]]).buffer(0)
    from shapely.geometry import Point

    polys = tuple(dict.fromkeys([int(face)] + np.unique(tri_face[tris]).tolist()))
    inside = region.contains(Point(centre).buffer(radius, quad_segs=32))
    room = float(region.boundary.distance(Point(centre))) if region.contains(Point(centre)) else 0.0
    planarity = _planarity(seq, tris, _disc_samples(centre, radius if inside else max(room, 1e-9)))
    problem = ""
    if not inside:
        problem = (f"the {tool} ({2000 * radius:.0f} mm across its lips) does not fit on grip face {face}: the sheet "
                   f"around the face centre is {2000 * room:.1f} mm across (faces {list(polys[:4])}"
                   f"{'...' if len(polys) > 4 else ''})")
    elif planarity > lip_compliance:
        problem = (f"the sheet under the {tool} leaves its plane by {planarity * 1000:.2f} mm (lips take "
                   f"{lip_compliance * 1000:.2f} mm)")
    return GripCandidate(faces=polys, centre=(float(centre[0]), float(centre[1])), inscribed_m=room,
                         planarity_m=planarity, ok=not problem, problem=problem, fits=bool(inside))


def cup_fit(fold_model, cup_radius: float, *, lip_compliance: float = DEFAULT_LIP_COMPLIANCE):
    """`fit(face) -> GripCandidate`: the cup's disc of `cup_radius` [m] about grip face `face`'s
    centre, where the planner puts the TCP, on the sheet up to the creases and the outline
    (`pad_footprint` with `rulings_join`), planar to `lip_compliance` in every fold state of the
    FOLD model `fold_model`. Each face is measured once; the planner orders its grip candidates by
    it and the check refuses a grip whose cup does not fit."""
    seq = FoldGeometry.of_fold(fold_model)
    seen: dict[int, GripCandidate] = {}

    def fit(face: int) -> GripCandidate:
        face = int(face)
        if face not in seen:
            seen[face] = pad_footprint(seq, face, float(cup_radius), lip_compliance=lip_compliance,
                                       rulings_join=True, tool="cup")
        return seen[face]

    return fit


def cup_footprint_record(fold_model, holds: dict, cup_radius: float | None, *,
                         lip_compliance: float = DEFAULT_LIP_COMPLIANCE, fit=None) -> dict | None:
    """The CHECK.json record of the cup's footprint (`cup_fit`) on every face an arm grips in a
    holds record (`robot.holds_record`): `cup_mm`, `lip_compliance_mm`, and per face `ok`,
    `room_mm` (the sheet across at the face centre), `planarity_mm`, `problem`. None without a cup
    (`cup_radius` None) or without a grip. `fit`: a `cup_fit` of that cup to reuse."""
    if cup_radius is None:
        return None
    faces = sorted({int(f) for row in holds.get("arms", {}).values() for f in row if f is not None})
    if not faces:
        return None
    fit = fit or cup_fit(fold_model, cup_radius, lip_compliance=lip_compliance)
    rows = []
    for f in faces:
        c = fit(f)
        rows.append({"face": f, "ok": bool(c.ok), "room_mm": round(2000 * c.inscribed_m, 3),
                     "planarity_mm": round(1000 * c.planarity_m, 4), "problem": c.problem})
    return {"cup_mm": round(2000 * float(cup_radius), 3), "lip_compliance_mm": lip_compliance * 1000,
            "enforced": True, "faces": rows}
