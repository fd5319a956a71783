"""The cup rule before the refold: grip faces the cup cannot hold in any refold that reaches the target.

The check refuses a grip face when the cup's disc about the face centre leaves the sheet up to the
creases and the outline (the grip region: faces joined across rulings, diagonals and creases that
bend less than the lip compliance over the cup radius in every state) or when the sheet under it
leaves a plane by more than the lip compliance in some fold state (`fabkit.grip_footprint.cup_fit`).
A refold that is kept starts flat and ends within `deviation_m` (its target tolerance times the
panel size) of the target, the relaxed panel. So the same rule applied to two states only, the flat
pattern and the target, with

- a crease joining the region when its target bend is within the join angle plus what a deviation
  of `deviation_m` can change it by (`angle_margin`): a region that holds the region of the refolded
  states (more joins, never fewer), so a disc that leaves it leaves theirs;
- planarity counted only above the lip compliance plus a margin for the deviation,

refuses a grip face only where the full rule refuses it on the refolded states: a sound pre-test
that needs no refold. Where the creases around the region bend far more than the join angle (the
usual panel) the region is the refolded states' region, and the problem text is the check's.
"""
from __future__ import annotations

import numpy as np

from fabkit.grip_footprint import DEFAULT_LIP_COMPLIANCE, FoldGeometry, GripCandidate, pad_footprint

__all__ = ["flat_and_target_geometry", "angle_margin", "cup_refused_before_refold"]


def flat_and_target_geometry(flat_vertices, tris, tri_face, edges, edge_kind, target_vertices,
                             target_angles) -> FoldGeometry:
    """A two-state `FoldGeometry`: the flat pattern (n, 3) and the target (n, 3) with its hinge
    angles (E,) [rad], over the refold's triangles, polygon ids, sorted edges and edge kinds (as a
    `fabkit.refold.RefoldSolver` has them before it solves)."""
    V = np.asarray(flat_vertices, np.float64)
    angles = np.asarray(target_angles, np.float64)
    return FoldGeometry(flat_vertices=V, tris=np.asarray(tris), tri_face=np.asarray(tri_face),
                        edges=np.asarray(edges), edge_kind=np.asarray(edge_kind),
                        angles=np.stack([np.zeros_like(angles), angles]),
                        positions=np.stack([V, np.asarray(target_vertices, np.float64)]))


def angle_margin(geometry: FoldGeometry, deviation_m: float) -> float:
    """How much [rad] moving every vertex by at most `deviation_m` can change a hinge angle: four
    times the deviation over the smallest triangle altitude of the flat pattern (each of the two
    triangles' normals turns by at most twice the deviation over its altitude)."""
    V = np.asarray(geometry.flat_vertices, np.float64)[:, :2]
    T = np.asarray(geometry.tris)
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    area2 = np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1)],
                     axis=0)
    altitude = float((area2 / longest).min())
    return 4.0 * float(deviation_m) / altitude if altitude > 0 else float("inf")


def cup_refused_before_refold(geometry: FoldGeometry, faces, cup_radius: float, *, deviation_m: float,
                              lip_compliance: float = DEFAULT_LIP_COMPLIANCE) -> list[GripCandidate] | None:
    """The cup's footprint (`pad_footprint`, as `cup_fit` measures it) on each of `faces` when the
    rule refuses every one of them on any refold of `geometry` (`flat_and_target_geometry`) whose
    last state is within `deviation_m` [m] of the target, else None (module docstring). A face
    whose planarity lies within the margin is not refused here: the full rule decides it."""
    faces = [int(f) for f in faces]
    if not faces or not cup_radius > 0:
        return None
    bend = lip_compliance / cup_radius + angle_margin(geometry, deviation_m)
    planar_margin = 4.0 * float(deviation_m)  # the best-fit plane's residuals, every sample moved by the deviation
    out = []
    for f in faces:
        c = pad_footprint(geometry, f, float(cup_radius), lip_compliance=lip_compliance, max_bend=bend,
                          rulings_join=True, tool="cup")
        if c.ok or (c.fits and c.planarity_m <= lip_compliance + planar_margin):
            return None
        out.append(c)
    return out
