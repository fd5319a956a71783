"""Panel structure, the one home of: creases, strips, crease chains, M/V, the middle row, the clamp
face and the grip candidates. Every stage asks `panel_structure(mesh)` instead of reading tags.

Explicit tags win (docs/CONTRACTS.md "Panel tags"): `face_data["strip"]` gives the creases (the
interior edges between different strips), `"column"` the columns, `"middle"` the middle row.
What is not tagged is inferred from the geometry of the *folded* panel — creases by the jump of
the fold angle against the smooth bending beside it (`fabkit.structure.creases`), strips, columns
and the middle row from the creases (`fabkit.structure.layout`). A flat, untagged mesh has no
creases to find. The result depends on coordinates only, not on vertex or face order.

`PanelStructure.face_data()` is the structure as tags; `with_tags(mesh)` attaches them, so
`fabkit tag` can write them for the user to edit.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabkit.measures import dihedral_angles
from fabkit.mesh import PolyMesh
from fabkit.structure.creases import CreaseDetection, chain_edges, chain_fold_angles, detect_creases
from fabkit.structure.layout import (comes_first, geometric_key, middle_row_faces, order_strips, quad_ribbons,
                                     strip_components)

__all__ = ["PanelStructure", "panel_structure", "pair_structure", "crease_mask", "strips_of_creases", "assigned_creases",
           "chain_edges", "detect_creases", "FLAT_ANGLE"]

#: The face tags that carry structure (docs/CONTRACTS.md "Panel tags").
TAG_NAMES = ("strip", "column", "middle")
#: A crease folded by less than this [rad] counts as flat: mountain/valley unknown ("U").
FLAT_ANGLE = 1e-9


@dataclass(frozen=True, eq=False)
class PanelStructure:
    """The structure of one panel (arrays over the mesh's edges `E` and faces `F`).

    `crease` (E,) bool; `fold_angle` (E,) [rad, valley +] unwrapped along crease chains;
    `assignment` (E,) FOLD letters B/M/V/F/U (U: a crease flat in this geometry); `crease_row` (E,)
    the lower strip number of crease edges, -1 elsewhere; `chains` crease polylines (vertex ids,
    closed loops repeat their first vertex); `strip` (F,) 0..k-1; `column` (F,) or None;
    `middle` (F,) 0/1; `middle_row` faces (one per strip, by strip); `middle_creases` crease edge
    ids of the middle column (the paper's driven creases); `clamp_face`; `grip_faces` candidates
    (middle row without the clamp face, farthest from it first); `source` says per part whether
    it came from tags, from given assignments (creases) or was inferred; `detection` the crease detection when creases were inferred.
    """

    crease: np.ndarray
    fold_angle: np.ndarray
    assignment: np.ndarray
    crease_row: np.ndarray
    chains: tuple
    strip: np.ndarray
    column: np.ndarray | None
    middle: np.ndarray
    middle_row: np.ndarray
    middle_creases: np.ndarray
    clamp_face: int
    grip_faces: np.ndarray
    source: dict
    detection: CreaseDetection | None = None

    @property
    def crease_edges(self) -> np.ndarray:
        return np.flatnonzero(self.crease)

    @property
    def n_strips(self) -> int:
        return int(len(np.unique(self.strip)))

    def face_data(self) -> dict[str, np.ndarray]:
        """The structure as panel tags: strip, middle, and column when known."""
        fd = {"strip": self.strip.astype(np.int64), "middle": self.middle.astype(np.int64)}
        if self.column is not None:
            fd["column"] = self.column.astype(np.int64)
        return fd

    def with_tags(self, mesh: PolyMesh) -> PolyMesh:
        return mesh.with_data(face_data=self.face_data())

    def summary(self, mesh: PolyMesh) -> dict:
        """JSON-ready description: creases per row with M/V counts and fold range [deg], strips, rows."""
        creases = []
        for r in sorted(set(self.crease_row[self.crease].tolist())):
            e = np.flatnonzero(self.crease_row == r)
            a = np.degrees(self.fold_angle[e])
            creases.append({"row": int(r), "between_strips": [int(r), int(r) + 1], "edges": int(len(e)),
                            "M": int(np.sum(self.assignment[e] == "M")), "V": int(np.sum(self.assignment[e] == "V")),
                            "U": int(np.sum(self.assignment[e] == "U")),
                            "min_fold_deg": float(a.min()), "max_fold_deg": float(a.max())})
        return {"source": dict(self.source), "strips": self.n_strips, "crease_edges": int(self.crease.sum()),
                "chains": len(self.chains), "creases": creases,
                "middle_row": [int(f) for f in self.middle_row],
                "middle_creases": [[int(u), int(v)] for u, v in mesh.edges[self.middle_creases]],
                "clamp_face": int(self.clamp_face), "grip_faces": [int(f) for f in self.grip_faces],
                "columns": None if self.column is None else int(len(np.unique(self.column))),
                "noise_deg": None if self.detection is None else float(np.degrees(self.detection.sigma)),
                "strong_jump_deg": None if self.detection is None else float(np.degrees(self.detection.strong))}


def crease_mask(mesh: PolyMesh) -> np.ndarray:
    """(E,) bool: the panel's crease edges (tags if present, else inferred), as `panel_structure(mesh).crease`
    without the middle row and the rest."""
    return _creases_and_strips(mesh, mesh.face_data, dihedral_angles(mesh))[0]


def assigned_creases(model) -> np.ndarray | None:
    """Mesh edge ids (of `model.mesh()`) a FOLD model assigns M, V or U: the creases the file
    states, for `panel_structure(..., crease_edges=)`; None when it assigns none."""
    ids = model.mesh_edge_index[np.isin(model.edges_assignment, ["M", "V", "U"])]
    ids = ids[ids >= 0]
    return ids if len(ids) else None


def assigned_letters(model, mesh: PolyMesh) -> np.ndarray:
    """(E,) the FOLD model's own assignment letter of every edge of `mesh` (its `model.mesh()`),
    "" where the file has none: for `panel_structure(..., crease_letters=)`."""
    letters = np.full(mesh.n_edges, "", dtype="<U1")
    idx = np.asarray(model.mesh_edge_index)
    ok = idx >= 0
    letters[idx[ok]] = np.asarray(model.edges_assignment)[ok]
    return letters


def strips_of_creases(mesh: PolyMesh, crease: np.ndarray) -> np.ndarray:
    """Strip number (F,) 0..k-1 of every face: the regions no crease edge (`crease` (E,) bool)
    separates, numbered along the strip adjacency from geometry alone (`layout.order_strips`), so
    the numbers do not depend on vertex or face order."""
    crease = np.asarray(crease, bool)
    return order_strips(mesh, strip_components(mesh, crease), crease)


def _creases_and_strips(mesh: PolyMesh, fd, angle, crease_edges=None):
    """(crease (E,), strip (F,) 0..k-1, oriented chains, detection or None, source)."""
    if crease_edges is not None and "strip" not in fd:
        given = np.zeros(mesh.n_edges, bool)
        given[np.asarray(crease_edges, np.int64)] = True
        strip = strips_of_creases(mesh, given)
        crease = _strip_crease(mesh, strip)
        return crease, strip, _oriented_chains(mesh, crease, None), None, "assignments"
    if "strip" in fd:
        raw = np.asarray(fd["strip"]).astype(np.int64)
        crease = _strip_crease(mesh, raw)
        strip = np.searchsorted(np.unique(raw), raw)
        return crease, strip, _oriented_chains(mesh, crease, None), None, "tags"
    detection = detect_creases(mesh, angle)
    strip = strips_of_creases(mesh, detection.crease)
    crease = _strip_crease(mesh, strip)  # a chain that separates nothing is not a crease
    kept = [c for c in detection.chains if crease[mesh.topology.edge_ids([[c[0], c[1]]])[0]]]
    return crease, strip, _oriented_chains(mesh, crease, kept), detection, "inferred"


def _strip_crease(mesh: PolyMesh, strip: np.ndarray) -> np.ndarray:
    t = mesh.topology
    inner = ~t.boundary_edge_mask
    ef = np.maximum(t.edge_faces, 0)
    return inner & (strip[ef[:, 0]] != strip[ef[:, 1]])


def _oriented_chains(mesh: PolyMesh, crease: np.ndarray, chains) -> list[list[int]]:
    """Crease chains, each starting at its end that comes first (`layout.comes_first`)."""
    if chains is None:
        chains = chain_edges(mesh.edges[crease]) if crease.any() else []
    V = mesh.vertices
    out = []
    for c in chains:
        c = list(c)
        if c[0] != c[-1] and not comes_first(V[c[0]], V[c[-1]]):
            c = c[::-1]
        out.append(c)
    return out


def panel_structure(mesh: PolyMesh, *, use_tags: bool = True, crease_edges=None,
                    crease_letters=None) -> PanelStructure:
    """The structure of `mesh` (folded, for inference): tags where present, geometry elsewhere.

    `crease_edges`: ids of `mesh.edges` that are creases by an explicit statement other than strip
    tags (a FOLD file's M/V/U assignments); they win over the geometry, strip tags win over them.
    Edges among them that separate no faces are dropped (strips must be regions).
    `crease_letters`: (E,) letters per mesh edge (a FOLD file's own assignments); a crease that is
    flat in `mesh` (a crease pattern without a folded frame) keeps its M or V from them."""
    t = mesh.topology
    fd = mesh.face_data if use_tags else {}
    angle = dihedral_angles(mesh)
    crease, strip, chains, detection, how = _creases_and_strips(mesh, fd, angle, crease_edges)
    source = {"creases": how, "strips": how}
    fold = chain_fold_angles(mesh, chains, angle)
    assignment = np.full(t.n_edges, "F", dtype="<U1")
    assignment[crease & (fold > FLAT_ANGLE)] = "V"
    assignment[crease & (fold < -FLAT_ANGLE)] = "M"
    assignment[crease & (np.abs(fold) <= FLAT_ANGLE)] = "U"
    if crease_letters is not None:  # flat: the crease pattern's own mountain / valley
        given = np.char.upper(np.asarray(crease_letters).astype(str))
        keep = crease & (np.abs(fold) <= FLAT_ANGLE) & np.isin(given, ["M", "V"])
        assignment[keep] = given[keep]
    assignment[t.boundary_edge_mask] = "B"
    ef = np.maximum(t.edge_faces, 0)
    crease_row = np.where(crease, np.minimum(strip[ef[:, 0]], strip[ef[:, 1]]), -1)

    # columns: ribbons through the lowest crease row's longest chain, in chain order
    ribbons: list[list[int]] = []
    if chains:
        row0 = [c for c in chains if crease_row[t.edge_ids([[c[0], c[1]]])[0]] == crease_row[crease].min()]
        c0 = max(row0, key=len)
        ribbons = quad_ribbons(mesh, t.edge_ids(np.stack([c0[:-1], c0[1:]], axis=1)))
    column = None
    if "column" in fd:
        column = np.asarray(fd["column"]).astype(np.int64)
        source["columns"] = "tags"
    elif ribbons and all(ribbons):
        col = np.full(t.n_faces, -1, np.int64)
        clash = False
        for i, r in enumerate(ribbons):
            clash |= bool(np.any(col[r] >= 0))
            col[r] = i
        if not clash and np.all(col >= 0):
            column, source["columns"] = col, "inferred"
    if "middle" in fd:
        middle = (np.asarray(fd["middle"]) != 0).astype(np.int64)
        mids = np.flatnonzero(middle)
        row = mids[np.argsort(strip[mids], kind="stable")]
        source["middle_row"] = "tags"
        best = -1
    else:
        row, best = middle_row_faces(mesh, strip, ribbons)
        row = np.asarray(row, np.int64)
        middle = np.zeros(t.n_faces, np.int64)
        middle[row] = 1
        source["middle_row"] = "inferred"
    mid_creases = _middle_creases(mesh, crease, crease_row, strip, column, row, ribbons[best] if best >= 0 else None)
    clamp, grips = _clamp_and_grips(mesh, strip, row, _valley_rows(crease_row, fold, mid_creases))
    return PanelStructure(crease=crease, fold_angle=fold, assignment=assignment, crease_row=crease_row,
                          chains=tuple(np.asarray(c, np.int64) for c in chains), strip=strip, column=column,
                          middle=middle, middle_row=np.asarray(row, np.int64), middle_creases=mid_creases,
                          clamp_face=clamp, grip_faces=grips, source=source, detection=detection)


def pair_structure(flat: PolyMesh, folded: PolyMesh) -> PanelStructure:
    """The structure of a FLAT / folded pair with the same faces: the tags of either (FLAT's win), the
    rest inferred from the folded geometry (a flat pattern shows no creases)."""
    tags = {k: v for k, v in {**folded.face_data, **flat.face_data}.items() if k in TAG_NAMES}
    return panel_structure(PolyMesh(folded.vertices, topology=folded.topology, face_data=tags, validate=False))


def _middle_creases(mesh, crease, crease_row, strip, column, row, ribbon) -> np.ndarray:
    """Crease edges of the middle column: both faces in it; per crease row without such an edge,
    the crease edge nearest the middle-row faces on either side."""
    t = mesh.topology
    ef = np.maximum(t.edge_faces, 0)
    ce = np.flatnonzero(crease)
    if len(ce) == 0 or len(row) == 0:
        return np.zeros(0, np.int64)
    if ribbon is not None:
        inside = np.zeros(t.n_faces, bool)
        inside[ribbon] = True
    elif column is not None:
        cols = np.unique(column[row])
        inside = np.isin(column, cols)
        same = column[ef[ce, 0]] == column[ef[ce, 1]]
        ce_ok = ce[same & inside[ef[ce, 0]] & inside[ef[ce, 1]]]
        inside = None
    else:
        inside = np.zeros(t.n_faces, bool)
        inside[row] = True
    if inside is not None:
        ce_ok = ce[inside[ef[ce, 0]] & inside[ef[ce, 1]]]
    out = list(ce_ok.tolist())
    C = mesh.face_centroids
    mid = mesh.vertices[mesh.edges].mean(axis=1)
    by_strip = {int(strip[f]): int(f) for f in row}
    for r in sorted(set(crease_row[ce].tolist())):
        if np.any(crease_row[ce_ok] == r):
            continue
        pts = [C[by_strip[s]] for s in (r, r + 1) if s in by_strip]
        if not pts:
            continue
        p = np.mean(pts, axis=0)
        e = ce[crease_row[ce] == r]
        d = np.round(np.linalg.norm(mid[e] - p, axis=1) / max(mesh.size, 1e-300) * 1e9)
        out.append(int(e[np.argmin(d)]))
    return np.unique(np.asarray(out, np.int64))


def _valley_rows(crease_row, fold, mid_creases) -> set[int]:
    """Crease rows whose middle-column edges fold as valleys (mean fold angle > FLAT_ANGLE)."""
    rows = crease_row[mid_creases]
    return {int(r) for r in np.unique(rows) if float(fold[mid_creases[rows == r]].mean()) > FLAT_ANGLE}


def _clamp_and_grips(mesh, strip, row, valley_rows=frozenset()) -> tuple[int, np.ndarray]:
    """The middle-row face of an end strip of the row, and the other middle-row faces farthest
    first. Clamping one end and gripping the other holds every crease between: cutting any crease
    row leaves the clamp on one side and the grip on the other (`fabkit.holds`), and a chain of
    curved creases is one mechanism, so the two ends fix it; a clamp in the middle leaves one wing
    held by nothing in a one-arm program. The end is the first strip, unless the crease beside it
    is a mountain and the crease beside the last strip a valley (`valley_rows`: crease rows that
    fold as valleys): the panel is clamped front up, and from a mountain the rest of the panel
    folds behind the clamped face (toward the clamp post and the table, where a letter or zigzag
    fold ends tucked under the clamp), from a valley it folds in front of it, toward the arm."""
    row = np.asarray(row, np.int64)
    if len(row) == 0:
        c = mesh.face_centroids
        centre = (c * mesh.face_areas[:, None]).sum(0) / mesh.face_areas.sum()
        d = np.round(np.linalg.norm(c - centre, axis=1) / max(mesh.size, 1e-300) * 1e9)
        near = np.flatnonzero(d == d.min())
        keys = geometric_key(c[near], mesh.size)
        return int(near[np.lexsort((keys[:, 2], keys[:, 1], keys[:, 0]))[0]]), np.zeros(0, np.int64)
    strips = strip[row]
    want = int(strips.min())
    last = int(strips.max())
    if last > want and want not in valley_rows and last - 1 in valley_rows:
        want = last
    clamp = int(row[np.argsort(np.abs(strips - want), kind="stable")[0]])
    others = row[row != clamp]
    d = np.linalg.norm(mesh.face_centroids[others] - mesh.face_centroids[clamp], axis=1)
    order = np.lexsort((strip[others], -np.round(d / max(mesh.size, 1e-300) * 1e9)))
    return clamp, others[order]
