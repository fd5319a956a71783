"""Where the panel sits in the cell: its clamped face on the cell's clamp.

A cell with a `[clamp]` names the jaw's pose and footprint. The jaw clamps the sheet around the
clamped face: the face and the neighbours across rulings that the fold states keep within 0.1 mm of
their flat position under the jaw (`jaw_region`, `fabkit.clamp_region`). When the cell's
`[fixture]` already puts the footprint on that region with its centre on the clamped face, the
panel stays where the fixture puts it. Otherwise the panel frame (the frame of the fold states, in
which the clamped face never moves) is placed so that the jaw pose of `fabkit.clamp_region.
best_jaw_pose` (measured from `fabkit.placement.clamped_face_frame`: area centroid, principal axis
toward the panel's area centroid, front normal; from geometry alone, so any vertex or face order
gives the same placement) lands on the clamp pose. The planner plans in the placed cell and
records the placement in PATH.json (`placement` {clamped_face, fixture: UR pose panel frame ->
world, jaw: {faces under it, yaw_deg, slack_mm}}, inside the whole-document hash); the check poses
the panel with the recorded fixture and fails when the footprint leaves the region or the jaw's
centre leaves the clamped face (`footprint_check`). A cell without a clamp, or a FOLD file without
a clamped face, keeps the cell's `[fixture]`. With several clamped faces (a FOLD file naming none:
the faces its states hold still) the one nearest the panel's area centroid goes on the clamp.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

__all__ = ["placement_for", "placed_cell", "placement_of", "clamped_face_ring", "clamped_region_ring",
           "footprint_check", "jaw_region"]


def clamped_face_ring(fold_model, face: int) -> np.ndarray:
    """The outline (k, 2) of polygon `face` in the FOLD file's key frame (the flat pattern): the union
    of its triangles (`faces_fabkit:polygon`), counter-clockwise."""
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    from fabkit.hold_model_fold import fold_triangles

    V = np.asarray(fold_model.vertices_coords, np.float64)
    all_tris, poly = fold_triangles(fold_model)
    tris = [t for t, p in zip(all_tris, poly) if p == face]
    if not tris:
        raise ValueError(f"face {face} is not a face of the panel")
    shape = unary_union([Polygon(V[t][:, :2]) for t in tris]).buffer(0)
    if shape.geom_type != "Polygon":
        raise ValueError(f"face {face} is not one simple polygon in the flat pattern")
    ring = np.asarray(shape.exterior.coords)[:-1]
    area = 0.5 * np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1])
    return ring if area > 0 else ring[::-1]


def clamped_region_ring(fold_model, faces) -> np.ndarray:
    """The outline (k, 2) of the union of the clamped faces `faces` in the flat pattern (the largest
    piece when they are not connected), counter-clockwise."""
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    shape = unary_union([Polygon(clamped_face_ring(fold_model, int(f))) for f in faces]).buffer(0)
    if shape.geom_type != "Polygon":
        shape = max(shape.geoms, key=lambda g: g.area)
    ring = np.asarray(shape.exterior.coords)[:-1]
    area = 0.5 * np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1])
    return ring if area > 0 else ring[::-1]


def jaw_region(fold_model, faces, footprint):
    """`fabkit.clamp_region.ClampRegion` of the sheet the jaw may clamp around the clamped faces
    `faces` in the FOLD file's states (each face's region, joined; `faces` lists the first face's
    region first)."""
    from shapely.ops import unary_union

    from fabkit.clamp_region import clamp_region, region_joins
    from fabkit.grip_footprint import FoldGeometry

    g = FoldGeometry.of_fold(fold_model)
    reach = float(np.linalg.norm(np.asarray(footprint, np.float64), axis=1).max())
    joins = region_joins(g.tris, g.tri_face, g.edges, g.edge_kind)
    flat = np.asarray(fold_model.vertices_coords, np.float64)
    regions = [clamp_region(flat, g.tris, g.tri_face, joins, g.positions, int(f), reach) for f in faces]
    if len(regions) == 1:
        return regions[0]
    shape = unary_union([r.polygon for r in regions]).buffer(0)
    if shape.geom_type != "Polygon":
        shape = max(shape.geoms, key=lambda p: p.area)
    return replace(regions[0], polygon=shape, faces=tuple(dict.fromkeys(f for r in regions for f in r.faces)),
                   worst_m=max(r.worst_m for r in regions))


def footprint_check(fold_model, cell, faces, fixture=None, region=None):
    """`fabkit.placement.ClampCheck` of the cell's clamp footprint with the panel placed by `fixture`
    (default the cell's): the footprint must lie on the sheet the jaw can hold around the clamped
    faces (`jaw_region`: the faces and the neighbours the fold states keep still under the jaw) and
    the jaw's centre on a clamped face. `region`: the `jaw_region` of these faces, when computed."""
    from shapely.geometry import Point, Polygon
    from shapely.ops import unary_union

    from fabkit.placement import ClampCheck, check_clamp_footprint

    region = jaw_region(fold_model, faces, cell.clamp.footprint) if region is None else region
    ring = np.asarray(region.polygon.exterior.coords)[:-1]
    pts = np.column_stack([ring, np.zeros(len(ring))])
    fx = cell.fixture if fixture is None else fixture
    where = f" of the sheet the jaw can hold there (faces {list(region.faces)})" if len(region.faces) > 1 else ""
    res = check_clamp_footprint(pts, np.arange(len(ring)), int(faces[0]), fx, cell.clamp.pose, cell.clamp.footprint,
                                where=where)
    centre = np.linalg.inv(np.asarray(fx, np.float64)) @ np.asarray(cell.clamp.pose, np.float64) @ [0, 0, 0, 1.0]
    face = unary_union([Polygon(clamped_face_ring(fold_model, int(f))) for f in faces])
    off = float(face.distance(Point(centre[:2])))
    if off <= 1e-7:
        return res
    also = f" (and {list(faces[1:])})" if len(faces) > 1 else ""
    msg = f"the clamp jaw's centre is {off * 1000:.1f} mm off clamped face {int(faces[0])}{also}"
    return ClampCheck(ok=False, face=res.face, outside_area_m2=res.outside_area_m2, outside_m=max(res.outside_m, off),
                      off_plane_m=res.off_plane_m, problems=(*res.problems, msg))


def _area_centroid(fold_model) -> np.ndarray:
    from fabkit.hold_model_fold import fold_triangles

    V = np.asarray(fold_model.vertices_coords, np.float64)[:, :2]
    T, _ = fold_triangles(fold_model)
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    return ((a + b + c) / 3 * area[:, None]).sum(axis=0) / area.sum()


def placement_for(cell, fold_model) -> dict | None:
    """The `placement` record putting the FOLD file's clamped face on `cell`'s clamp, or None (no
    clamp in the cell, or no clamped face)."""
    from shapely.geometry import Polygon

    from fabkit.clamp_region import best_jaw_pose
    from fabkit.placement import clamped_face_frame
    from robot.cell import matrix_to_pose
    from robot.holds_record import clamped_faces_of

    if getattr(cell, "clamp", None) is None:
        return None
    clamped = clamped_faces_of(fold_model)
    if not clamped:
        return None
    centre = _area_centroid(fold_model)
    rings = {int(f): clamped_face_ring(fold_model, int(f)) for f in clamped}
    dist = {f: (round(float(np.linalg.norm(r.mean(axis=0) - centre)), 9), *np.round(r.mean(axis=0), 9))
            for f, r in rings.items()}
    face = min(rings, key=lambda f: dist[f])
    region = jaw_region(fold_model, [face, *sorted(set(rings) - {face})], cell.clamp.footprint)
    if footprint_check(fold_model, cell, clamped, region=region).ok:
        return None
    ring = rings[face]
    pts = np.column_stack([ring, np.zeros(len(ring))])
    frame = clamped_face_frame(pts, np.arange(len(ring)), centre)
    jaw = best_jaw_pose(region.polygon, Polygon(ring), cell.clamp.footprint, frame)
    T = np.eye(4)
    T[:2, :2], T[:2, 3] = jaw.frame[:2, :2], jaw.frame[:2, 2]
    fixture = np.asarray(cell.clamp.pose, np.float64) @ np.linalg.inv(T)
    out = {"clamped_face": face, "fixture": [float(x) for x in matrix_to_pose(fixture)]}
    if jaw.fits:
        jaw_faces = [f for f in region.faces if _under_jaw(fold_model, f, jaw.frame, cell.clamp.footprint)]
        out["jaw"] = {"faces": jaw_faces, "yaw_deg": round(jaw.yaw_deg, 6), "slack_mm": round(jaw.slack_m * 1000, 6)}
    return out


def _under_jaw(fold_model, face: int, frame, footprint) -> bool:
    from shapely.geometry import Polygon

    fp = np.asarray(footprint, np.float64) @ np.asarray(frame)[:2, :2].T + np.asarray(frame)[:2, 2]
    return Polygon(clamped_face_ring(fold_model, int(face))).intersection(Polygon(fp)).area > 1e-10


def placement_of(extra: dict) -> dict | None:
    """The validated `placement` record of a toolpath's extra keys, or None; `ValueError` naming the
    key for a malformed one."""
    p = extra.get("placement") if isinstance(extra, dict) else None
    if p is None:
        return None
    ok = (isinstance(p, dict) and isinstance(p.get("clamped_face"), int) and not isinstance(p["clamped_face"], bool)
          and isinstance(p.get("fixture"), list) and len(p["fixture"]) == 6
          and all(isinstance(x, (int, float)) and not isinstance(x, bool) and abs(x) <= 100 for x in p["fixture"]))
    if not ok:
        raise ValueError("placement: expected {clamped_face: face id, fixture: [x, y, z, rx, ry, rz]}")
    return p


def placed_cell(cell, placement: dict | None):
    """`cell` with the panel placed by `placement` (its fixture replaced), or `cell` for None."""
    from robot.cell import pose_to_matrix

    if placement is None:
        return cell
    return replace(cell, fixture=pose_to_matrix(placement["fixture"]))
