"""The drawing a cutter gets, in millimetres: outline, mountain/valley score lines, labels.

`cut_pattern` turns a development (metres) into a `CutPattern` (millimetres) that the DXF and SVG
writers only draw; both files therefore always show the same geometry.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabkit.cutfiles.creases import CreaseAssignment, chain_edges
from fabkit.errors import MeshError
from fabkit.mesh import PolyMesh

__all__ = ["CutPattern", "Label", "cut_pattern", "face_up", "face_up_text", "LAYERS", "MM_PER_M"]

MM_PER_M = 1000.0

#: layer name -> (DXF colour index (ACI), SVG colour, what it is)
LAYERS = {
    "CUT": (7, "#000000", "outline: cut through"),
    "MOUNTAIN": (1, "#d62728", "mountain fold score line"),
    "VALLEY": (5, "#1f4fd6", "valley fold score line"),
    "SCORE": (6, "#b000b0", "crease of unknown mountain/valley sense"),
    "LABEL": (3, "#2ca02c", "panel id, the face up, edge ids (engrave or ignore)"),
}
_SCORE_LAYER = {"M": "MOUNTAIN", "V": "VALLEY", "U": "SCORE"}


@dataclass(frozen=True)
class Label:
    text: str
    x: float
    y: float
    height: float
    layer: str = "LABEL"


@dataclass(frozen=True)
class CutPattern:
    """`outlines`: closed loops (k, 2) in mm (first the outer one, counter-clockwise);
    `polylines`: layer -> open or closed vertex chains (k, 2) in mm; `labels`; `extent` (2, 2) mm
    bounding box of the outline; `panel_id`."""

    outlines: tuple
    polylines: dict
    labels: tuple
    extent: np.ndarray
    panel_id: str


def face_up(mesh: PolyMesh, uv: np.ndarray) -> str:
    """Which face of the panel the drawing shows, seen from above: "front" (the side the mesh's face
    normals point to, by its vertex order) when the development keeps the faces' turning sense,
    "back" when it mirrors them (total signed area of the faces in `uv`)."""
    P = np.asarray(uv, dtype=np.float64)[:, :2]
    t = mesh.topology
    x, y = P[t.face_indices, 0], P[t.face_indices, 1]
    nxt = np.arange(len(t.face_indices)) + 1  # the next corner of the same face (wrapping)
    ends = t.face_offsets[1:] - 1
    nxt[ends] = t.face_offsets[:-1]
    return "front" if float(np.sum(x * y[nxt] - x[nxt] * y)) >= 0 else "back"


def face_up_text(side: str, note: str = "") -> str:
    """The LABEL layer's face-up mark: the side up, and which folds then come up toward the viewer
    (a valley has the front face inside)."""
    toward = "valleys" if side == "front" else "mountains"
    return f"FACE UP: {side.upper()} ({toward} fold up){f'; {note}' if note else ''}"


def cut_pattern(mesh: PolyMesh, uv: np.ndarray, assignment: CreaseAssignment, panel_id: str = "",
                label_edges: bool = False, sheet_note: str = "") -> CutPattern:
    """Build the drawing of `uv` (metres, the panel's vertex order) with `assignment`'s creases.

    The LABEL layer always carries the face-up mark (`face_up`), with `sheet_note` (e.g. the
    sheet and where its grooves go) after it."""
    P = np.asarray(uv, dtype=np.float64)[:, :2] * MM_PER_M
    if P.shape[0] != mesh.n_vertices or not np.all(np.isfinite(P[mesh.topology.used_vertex_mask])):
        raise ValueError(f"uv must be finite with one row per vertex ({mesh.n_vertices}), got shape {P.shape}")
    if not mesh.boundary_loops:
        raise MeshError("the mesh has no boundary: there is no outline to cut")
    loops = [P[loop] for loop in mesh.boundary_loops]
    areas = [0.5 * np.sum(q[:, 0] * np.roll(q[:, 1], -1) - q[:, 1] * np.roll(q[:, 0], -1)) for q in loops]
    order = np.argsort(-np.abs(np.array(areas)))
    outlines = tuple(loops[i] for i in order)
    polylines = {}
    for kind, layer in _SCORE_LAYER.items():
        e = mesh.edges[assignment.edges_with(kind)]
        if len(e):
            polylines[layer] = tuple(P[np.array(c)] for c in chain_edges(e))
    lo, hi = outlines[0].min(axis=0), outlines[0].max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    h = float(np.clip(0.02 * size, 2.0, 20.0))
    labels = []
    t = mesh.topology
    fc = np.add.reduceat(P[t.face_indices], t.face_offsets[:-1], axis=0) / t.face_sizes[:, None]
    # labels go at the centroids of the faces nearest the development's centroid: inside the sheet
    near = np.argsort(np.linalg.norm(fc - P[t.used_vertex_mask].mean(axis=0), axis=1))
    if panel_id:
        f = int(near[0])
        labels.append(Label(str(panel_id), float(fc[f, 0]), float(fc[f, 1]), h))
    f = int(near[1] if panel_id and len(near) > 1 else near[0])
    labels.append(Label(face_up_text(face_up(mesh, uv), sheet_note), float(fc[f, 0]), float(fc[f, 1]), h / 2))
    if label_edges:
        # edge ids sit just inside the sheet: 40 % of the way from the edge's midpoint to its face's centroid
        b = np.flatnonzero(t.boundary_edge_mask)
        face = t.edge_faces[b].max(axis=1)
        mid = 0.5 * (P[mesh.edges[b, 0]] + P[mesh.edges[b, 1]])
        pos = mid + 0.4 * (fc[face] - mid)
        labels.extend(Label(f"e{int(e)}", float(x), float(y), h / 3) for e, (x, y) in zip(b, pos))
    return CutPattern(outlines=outlines, polylines=polylines, labels=tuple(labels),
                      extent=np.array([lo, hi]), panel_id=str(panel_id))
