"""The creases of a FOLD panel as the sheet models need them: hinge edges, arc length, flat-pattern
geodesic curvature and the width of the panels beside them.

Crease edges: `edges_fabkit:kind` == 1 when present (fabkit's refold output), else every M/V edge.
Rows: `edges_fabkit:crease` when present, else the crease rows of the panel structure
(`fabkit.structure`: the strips between the crease edges, a row the lower strip of its sides). Curvature:
total turning of the row's flat polyline / its length (the mean geodesic curvature; exact for the
circular arcs of the reflect preset). Panel width b: the mean area of the two strips beside the
row / its length with strip tags; else panel area / ((rows + 1) x row length).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Crease", "panel_creases", "ArmFold", "arm_folds"]


@dataclass(frozen=True, eq=False)
class Crease:
    """One crease row: `name` ("crease k"), `edges` (FOLD edge ids), `length` [m], `kappa_g` [1/m]
    (mean |geodesic curvature| in the flat pattern), `panel_width` [m]."""

    name: str
    edges: np.ndarray
    length: float
    kappa_g: float
    panel_width: float


def _turning(V, edges) -> float:
    """Total |turning angle| of a chain of edges at its degree-2 vertices."""
    total = 0.0
    inc: dict[int, list[int]] = {}
    for k, (a, b) in enumerate(edges):
        inc.setdefault(int(a), []).append(k)
        inc.setdefault(int(b), []).append(k)
    for v, ks in inc.items():
        if len(ks) != 2:
            continue
        d = []
        for k in ks:
            a, b = edges[k]
            other = b if a == v else a
            d.append(V[other] - V[v])
        u, w = d[0] / np.linalg.norm(d[0]), d[1] / np.linalg.norm(d[1])
        total += np.pi - float(np.arccos(np.clip(u @ w, -1.0, 1.0)))
    return total


def _structure_rows(model, ids: np.ndarray) -> np.ndarray:
    """Crease row (0..r-1) of each crease edge `ids` of a FOLD file without row tags: the strips
    between its creases (`fabkit.structure.strips_of_creases`, the numbering refold writes into
    `edges_fabkit:crease`), each row the lower strip of its two sides, renumbered 0..r-1."""
    from fabkit.structure import strips_of_creases

    mesh = model.mesh(validate=False)
    e = np.asarray(model.mesh_edge_index)[ids]
    crease = np.zeros(mesh.n_edges, bool)
    crease[e] = True
    crease &= ~mesh.topology.boundary_edge_mask
    strip = strips_of_creases(mesh, crease)
    ef = np.maximum(mesh.topology.edge_faces[e], 0)
    low = np.minimum(strip[ef[:, 0]], strip[ef[:, 1]])
    return np.unique(low, return_inverse=True)[1]


def panel_creases(model) -> tuple[Crease, ...]:
    """The crease rows of a `FoldModel` (module docstring), sorted by row."""
    V = np.asarray(model.vertices_coords)
    ev = np.asarray(model.edges_vertices)
    kind = model.edges_data.get("kind")
    if kind is not None:
        is_crease = np.asarray(kind) == 1
    else:
        is_crease = np.isin(np.asarray(model.edges_assignment), ["M", "V"])
    ids = np.flatnonzero(is_crease)
    if len(ids) == 0:
        return ()
    row_tag = model.edges_data.get("crease")
    if row_tag is not None and np.all(np.asarray(row_tag)[ids] >= 0):
        rows = np.asarray(row_tag, np.int64)[ids]
    else:
        rows = _structure_rows(model, ids)
    areas = np.asarray(model.mesh(validate=False).face_areas)  # the key frame: the flat pattern
    strip = model.faces_data.get("strip")
    out = []
    uniq = np.unique(rows)
    for r in uniq:
        e = ids[rows == r]
        seg = V[ev[e, 1]] - V[ev[e, 0]]
        L = float(np.linalg.norm(seg, axis=1).sum())
        kappa = _turning(V, ev[e]) / L if L > 0 else 0.0
        if strip is not None and row_tag is not None:
            s = np.asarray(strip)
            b = float((areas[s == r].sum() + areas[s == r + 1].sum()) / 2 / L)
        else:
            b = float(areas.sum() / (len(uniq) + 1) / L)
        out.append(Crease(name=f"crease {int(r)}", edges=e, length=L, kappa_g=float(kappa), panel_width=b))
    return tuple(out)


@dataclass(frozen=True)
class ArmFold:
    """A crease the arm folds in one fold state: `state`, `crease`, lever arm `lever` [m] from the
    crease to the grip face's centre (flat pattern), `pull` (the cup must pull: a valley turns the
    gripped face toward its front, so a cup on the front pulls and one on the back pushes; a
    mountain the reverse)."""

    state: int
    crease: Crease
    lever: float
    pull: bool


def arm_folds(model, creases, grip_face: int, fixed_face: int | None = None, side: str = "front") -> list[ArmFold]:
    """The creases between the clamped face and the gripped face, in every state where they fold
    further (mean |angle| over the crease grows). Needs strip tags (`faces_fabkit:strip`); without
    them every crease counts. Faces are polygon ids (`faces_fabkit:polygon`) or FOLD faces; `side`:
    the side of the sheet the cup grips (front or back)."""
    from fabkit.frames import face_groups

    groups = face_groups(model.faces_vertices, model.faces_data)
    V = np.asarray(model.vertices_coords)
    ev = np.asarray(model.edges_vertices)
    g = groups.index_of(int(grip_face))
    centre = V[np.asarray(groups.vertices[g])].mean(0)  # the grip face's centre in the flat pattern
    between = set(range(len(creases)))
    if fixed_face is not None and "strip" in model.faces_data and model.edges_data.get("crease") is not None:
        s_grip = int(groups.strip[g])
        s_fix = int(groups.strip[groups.index_of(int(fixed_face))])
        lo, hi = sorted((s_grip, s_fix))
        between = {i for i, c in enumerate(creases) if lo <= int(c.name.split()[-1]) < hi}
    out = []
    angles = [np.asarray(f.edges_fold_angle) if f.edges_fold_angle is not None else None for f in model.frames]
    for i in sorted(between):
        c = creases[i]
        a, b = V[ev[c.edges, 0]], V[ev[c.edges, 1]]
        d = b - a
        t = np.clip(((centre - a) * d).sum(1) / (d * d).sum(1), 0.0, 1.0)
        lever = float(np.linalg.norm(a + t[:, None] * d - centre, axis=1).min())
        for s in range(1, len(angles)):
            if angles[s] is None or angles[s - 1] is None:
                continue
            now, before = angles[s][c.edges].mean(), angles[s - 1][c.edges].mean()
            if abs(now) > abs(before) + 1e-12:
                out.append(ArmFold(s, c, lever, bool(now > 0) if side == "front" else bool(now < 0)))
    return out
