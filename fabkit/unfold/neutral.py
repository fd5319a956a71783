"""Neutral-surface development of a thick sheet from the development of its design surface.

The mesh is the design surface (one face of the sheet, or its mid-surface) with sharp creases; a
sheet of thickness t folded around inside radius R_i has a neutral surface whose flat length across
each crease differs by `fabkit.sheet.crease_correction` (the K-factor amount: mountain and valley
differ, since the top face is the inside of a valley and the outside of a mountain). Here a strip
of that width is inserted along every crease edge: each face beside a crease grows (or shrinks) by
half of it perpendicular to the crease edge in its flat layout, and the panel is developed again
(isometric, to those target lengths of edges and face diagonals). On curved creases the width
follows the local fold angle; faces meeting at crease ends are fitted in the least-squares sense.
"""
from __future__ import annotations

import numpy as np

from fabkit.mesh import PolyMesh
from fabkit.unfold.development import Development
from fabkit.unfold.springs import face_diagonals

__all__ = ["crease_strip_widths", "neutral_development"]


def crease_strip_widths(mesh: PolyMesh, spec, crease_mask: np.ndarray, design_surface: str = "top") -> np.ndarray:
    """Width [m] of the strip the neutral surface adds along every edge (0 off the creases)."""
    from fabkit.measures import dihedral_angles
    from fabkit.sheet import crease_correction

    angles = dihedral_angles(mesh)
    out = np.zeros(mesh.n_edges)
    for e in np.flatnonzero(crease_mask):
        out[e] = crease_correction(spec, float(angles[e]), design_surface)
    return out


def neutral_development(mesh: PolyMesh, dev: Development, spec, crease_mask: np.ndarray,
                        design_surface: str = "top", **develop_options) -> Development:
    """The development of the neutral surface (module docstring); `dev` is the design surface's
    (its `uv` is the starting layout), `crease_mask` (E,) the crease edges. A rigid material returns
    `dev` itself."""
    from fabkit.unfold import develop

    if spec.rigid:
        return dev
    widths = crease_strip_widths(mesh, spec, np.asarray(crease_mask, bool), design_surface)
    t = mesh.topology
    uv = np.asarray(dev.uv, np.float64)
    E = mesh.n_edges
    diag, diag_face = face_diagonals(mesh)
    edge_sum = np.zeros(E)
    edge_cnt = np.zeros(E)
    diag_len = np.zeros(len(diag))
    face_diags: dict[int, list[int]] = {}
    for k, f in enumerate(diag_face):
        face_diags.setdefault(int(f), []).append(k)
    for f in range(mesh.n_faces):
        lo, hi = t.face_offsets[f], t.face_offsets[f + 1]
        verts = t.face_indices[lo:hi]
        p = {int(v): uv[v].copy() for v in verts}
        centre = uv[verts].mean(0)
        for h in range(lo, hi):
            e = int(t.halfedge_edge[h])
            w = widths[e]
            if w == 0.0:
                continue
            a, b = (int(v) for v in t.edges[e])
            d = uv[b] - uv[a]
            n = np.array([-d[1], d[0]]) / np.linalg.norm(d)
            if n @ (uv[a] - centre) < 0:
                n = -n  # out of the face, toward the crease
            p[a] = p[a] + 0.5 * w * n
            p[b] = p[b] + 0.5 * w * n
        for h in range(lo, hi):
            e = int(t.halfedge_edge[h])
            a, b = (int(v) for v in t.edges[e])
            edge_sum[e] += np.linalg.norm(p[b] - p[a])
            edge_cnt[e] += 1
        for k in face_diags.get(f, []):
            a, b = (int(v) for v in diag[k])
            diag_len[k] = np.linalg.norm(p[b] - p[a])
    targets = np.concatenate([edge_sum / np.maximum(edge_cnt, 1), diag_len])
    out = develop(mesh, "isometric", targets, **develop_options)
    nz = widths[widths != 0] * 1000
    details = {**out.details, "surface": "neutral", "design_surface": design_surface,
               "crease_strip_mm": [float(nz.min()), float(nz.max())] if len(nz) else [0.0, 0.0]}
    from dataclasses import replace

    return replace(out, details=details)
