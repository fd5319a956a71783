"""The creases of a FOLD panel as the sheet models need them: hinge edges, arc length, flat-pattern
geodesic curvature and the width of the panels beside them.

Crease edges: `edges_fabkit:kind` == 1 when present (fabkit's refold output), else every M/V edge.
Rows: `edges_fabkit:crease` when present, else the connected chains of crease edges. Curvature:
total turning of the row's flat polyline / its length (the mean geodesic curvature; exact for the
circular arcs of the reflect preset). Panel width b: the mean area of the two strips beside the
row / its length with strip tags; else panel area / ((rows + 1) x row length).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

__all__ = ["Crease", "panel_creases"]


@dataclass(frozen=True, eq=False)
class Crease:
    """One crease row: `name` ("crease k"), `edges` (FOLD edge ids), `length` [m], `kappa_g` [1/m]
    (mean |geodesic curvature| in the flat pattern), `panel_width` [m]."""

    name: str
    edges: np.ndarray
    length: float
    kappa_g: float
    panel_width: float


def _tri_areas(V, faces) -> np.ndarray:
    out = np.zeros(len(faces))
    for i, f in enumerate(faces):
        p = V[np.asarray(f)]
        # polygon area by the fan of cross products (flat pattern: z = 0)
        c = np.cross(p[1:-1] - p[0], p[2:] - p[0])
        out[i] = 0.5 * np.linalg.norm(c.sum(0))
    return out


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
        n = len(V)
        a, b = ev[ids, 0], ev[ids, 1]
        g = coo_matrix((np.ones(len(ids)), (a, b)), shape=(n, n))
        _, lab = connected_components(g, directed=False)
        _, rows = np.unique(lab[a], return_inverse=True)
    faces = model.faces_vertices
    areas = _tri_areas(V, faces)
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
