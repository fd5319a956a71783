"""Which edges are creases, and mountain or valley (FOLD assignments), from the folded 3D panel.

The creases and their sense come from `fabkit.structure.panel_structure`: the strip tags when the
panel has them, else inferred from the geometry (the fold angle jumps along a chain of edges; see
`fabkit.structure.creases`), with mountain/valley from the signed fold angle unwrapped along each
crease (FOLD convention: valley positive). A crease that is flat in the given geometry (a tagged
crease on a flat sheet) cannot be told apart and is "U" (unassigned). An explicit
`angle_threshold` replaces the inference by a bare threshold on the dihedral angle, for users who
want exactly that.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabkit.measures import dihedral_angles
from fabkit.mesh import PolyMesh
from fabkit.structure import FLAT_ANGLE, chain_edges, panel_structure

__all__ = ["CreaseAssignment", "crease_assignment", "chain_edges"]


@dataclass(frozen=True)
class CreaseAssignment:
    """Per edge (mesh.edges order): `edges_assignment` in B (boundary), M, V, F (flat, not a crease),
    U (crease of unknown sense); `edges_fold_angle` [rad, valley +]; `source` says how creases were found."""

    edges_assignment: np.ndarray
    edges_fold_angle: np.ndarray
    source: str

    def edges_with(self, kind: str) -> np.ndarray:
        return np.flatnonzero(self.edges_assignment == kind)

    def counts(self) -> dict:
        return {k: int(np.sum(self.edges_assignment == k)) for k in "BMVFU"}


def crease_assignment(mesh: PolyMesh, angle_threshold: float | None = None) -> CreaseAssignment:
    """Crease edges and their mountain/valley sense from the folded panel `mesh` (see module doc)."""
    if angle_threshold is None:
        s = panel_structure(mesh)
        source = ("face_data strip tags" if s.source["creases"] == "tags"
                  else "dihedral-angle jump along crease chains (inferred from the geometry)")
        return CreaseAssignment(edges_assignment=s.assignment, edges_fold_angle=s.fold_angle, source=source)
    t = mesh.topology
    angle = dihedral_angles(mesh)
    inner = ~t.boundary_edge_mask
    crease = inner & (np.abs(angle) > angle_threshold)
    a = np.full(len(angle), "F", dtype="<U1")
    a[~inner] = "B"
    a[crease & (angle > FLAT_ANGLE)] = "V"
    a[crease & (angle < -FLAT_ANGLE)] = "M"
    return CreaseAssignment(edges_assignment=a, edges_fold_angle=angle,
                            source=f"dihedral angle above {np.degrees(angle_threshold):.3g} degrees (--crease-angle)")
