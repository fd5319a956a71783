"""Triangulate a panel for rigid-origami kinematics and keep the map back to its polygons.

Degree-4 vertices of a quad mesh have no rigid folding freedom (paper §3.6, Tachi 2009), so every
quad is split by one diagonal; the diagonal becomes a `J` hinge whose angle is free (about 0 where
the target quad is planar). Each triangle edge is classified once here:

- ``diagonal``: both triangles come from the same polygon (FOLD ``J``);
- ``boundary``: one triangle only (FOLD ``B``);
- ``crease``: a crease of the panel (`fabkit.structure.PanelStructure.crease`: strip tags, or inferred
  from the folded target);
- ``ruling``: any other polygon edge (the bending hinges of a developable strip).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabkit.errors import InputError
from fabkit.mesh import MeshTopology, PolyMesh
from fabkit.structure import PanelStructure, panel_structure

__all__ = ["TriangulatedPanel", "triangulate_panel", "EDGE_KINDS"]

EDGE_KINDS = ("boundary", "crease", "ruling", "diagonal")
BOUNDARY, CREASE, RULING, DIAGONAL = range(4)


@dataclass(frozen=True)
class TriangulatedPanel:
    """Triangles of a polygon panel plus the maps back to the polygons and their edges.

    `tris` (t, 3) CCW like the polygons; `tri_face` (t,) polygon of each triangle; `topology` the
    triangle mesh's `MeshTopology` (edges sorted lo<hi); `edge_kind` (E,) index into `EDGE_KINDS`;
    `edge_poly_edge` (E,) the polygon mesh's edge id with the same vertex pair (-1 for diagonals);
    `edge_crease` (E,) crease row = the lower of the two strips for crease edges, else -1;
    `edge_column` (E,) the `column` tag of the edge's faces where both agree (rulings between
    columns take the lower column), -1 without columns; `face_strip` (F,) the strip of each polygon;
    `middle_hinges` the crease hinges of the middle column (the paper's driven hinges).
    """

    tris: np.ndarray
    tri_face: np.ndarray
    topology: MeshTopology
    edge_kind: np.ndarray
    edge_poly_edge: np.ndarray
    edge_crease: np.ndarray
    edge_column: np.ndarray
    face_strip: np.ndarray
    middle_hinges: np.ndarray

    @property
    def n_tris(self) -> int:
        return len(self.tris)

    @property
    def edges(self) -> np.ndarray:
        return self.topology.edges

    @property
    def hinge_mask(self) -> np.ndarray:
        """Interior triangle edges: the fold-angle variables."""
        return self.edge_kind != BOUNDARY


def _quad_split(V: np.ndarray, quads: np.ndarray, diagonal: str) -> np.ndarray:
    """Per quad: True to split along 1-3, False along 0-2."""
    if diagonal == "02":
        return np.zeros(len(quads), bool)
    if diagonal == "13":
        return np.ones(len(quads), bool)
    if diagonal != "short":
        raise ValueError(f"unknown diagonal rule {diagonal!r} (short, 02 or 13)")
    d02 = np.linalg.norm(V[quads[:, 2]] - V[quads[:, 0]], axis=1)
    d13 = np.linalg.norm(V[quads[:, 3]] - V[quads[:, 1]], axis=1)
    return d13 < d02 * (1.0 - 1e-12)  # ties keep 0-2, so the choice is deterministic


def triangulate_panel(mesh: PolyMesh, diagonal: str = "short",
                      structure: PanelStructure | None = None) -> TriangulatedPanel:
    """Split quads along a diagonal (the shorter one in `mesh` by default) and fan larger polygons.

    Pass the flat pattern as `mesh`: the diagonal choice then depends only on the cut file.
    `structure` (of the same faces; default `panel_structure(mesh)`) says which edges are creases.
    """
    if structure is None:
        structure = panel_structure(mesh)
    t = mesh.topology
    sizes = t.face_sizes
    tris_parts, face_parts = [], []
    q = np.flatnonzero(sizes == 4)
    if len(q):
        quads = t.face_indices[t.face_offsets[q][:, None] + np.arange(4)]
        split13 = _quad_split(mesh.vertices, quads, diagonal)
        a = np.where(split13[:, None], quads[:, [0, 1, 3]], quads[:, [0, 1, 2]])
        b = np.where(split13[:, None], quads[:, [1, 2, 3]], quads[:, [0, 2, 3]])
        tris_parts += [a, b]
        face_parts += [q, q]
    other = np.flatnonzero(sizes != 4)
    if len(other):
        sub = PolyMesh(mesh.vertices, [t.face(int(f)) for f in other], validate=False)
        ft, ff = sub.triangulate()
        tris_parts.append(ft)
        face_parts.append(other[ff])
    tris = np.concatenate(tris_parts).astype(np.int64)
    tri_face = np.concatenate(face_parts).astype(np.int64)
    order = np.argsort(tri_face, kind="stable")  # triangles of polygon f are consecutive
    tris, tri_face = tris[order], tri_face[order]
    topo = MeshTopology(tris.ravel(), np.arange(0, 3 * len(tris) + 1, 3), mesh.n_vertices)

    E = topo.n_edges
    ef = topo.edge_faces
    boundary = np.any(ef < 0, axis=1)
    fl = np.where(ef[:, 0] >= 0, tri_face[np.maximum(ef[:, 0], 0)], -1)
    fr = np.where(ef[:, 1] >= 0, tri_face[np.maximum(ef[:, 1], 0)], -1)
    diag = ~boundary & (fl == fr)
    kind = np.full(E, RULING, np.int64)
    column = structure.column
    # map to the polygon mesh's edges (same sorted vertex pair)
    poly_edge = t.edge_ids(topo.edges)
    pe = np.maximum(poly_edge, 0)
    crease = ~boundary & ~diag & (poly_edge >= 0) & structure.crease[pe]
    kind[crease] = CREASE
    kind[diag] = DIAGONAL
    kind[boundary] = BOUNDARY
    edge_crease = np.where(crease, structure.crease_row[pe], -1).astype(np.int64)
    edge_column = np.full(E, -1, np.int64)
    if column is not None:
        column = np.asarray(column, np.int64)
        f0 = np.where(fl >= 0, fl, fr)
        f1 = np.where(fr >= 0, fr, fl)
        edge_column = np.minimum(column[f0], column[f1])
    middle = np.flatnonzero(crease & np.isin(poly_edge, structure.middle_creases))
    found = poly_edge >= 0
    if np.any(found == diag):
        e = int(np.flatnonzero(found == diag)[0])
        raise InputError(f"triangulation edge {topo.edges[e].tolist()} is both a polygon edge and a diagonal "
                         "(two polygons share a diagonal's vertex pair)")
    return TriangulatedPanel(tris=tris, tri_face=tri_face, topology=topo, edge_kind=kind,
                             edge_poly_edge=poly_edge.astype(np.int64), edge_crease=edge_crease,
                             edge_column=edge_column, face_strip=np.asarray(structure.strip, np.int64),
                             middle_hinges=middle)
