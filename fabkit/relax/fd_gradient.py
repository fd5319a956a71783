"""Finite-difference gradient of the relaxation energy, vectorised by vertex colouring.

A numerical cross-check of the analytic gradient in `fabkit.relax.energy` (tests) and the baseline
the benchmark compares it with (paper §2.3: analytic against numerical gradients). Not used by the
solvers.
"""
from __future__ import annotations

import numpy as np

from fabkit.relax.energy import EnergyModel
from fabkit.relax.planes import planarity_rows


def colored_fd_gradient(model: EnergyModel, X: np.ndarray, h: float | None = None) -> np.ndarray:
    """Central finite-difference gradient of E_dev + E_plan (+ E_edge), vectorised by vertex colouring.

    Vertices with disjoint stars (distance-2 colouring of the face-vertex graph) are perturbed at the
    same time; each residual then depends on at most one perturbed vertex, so per-residual differences
    can be attributed exactly. Costs 6 residual evaluations per colour.
    """
    h = 1e-6 * model.L if h is None else h
    colors = distance2_coloring(model)
    G = np.zeros((model.n, 3))
    owner_rows = row_vertices(model)
    for col in range(colors.max() + 1):
        members = (colors == col) & model.free_mask
        if not members.any():
            continue
        # for each row, the (unique) perturbed vertex it touches, if any
        touched = np.where(members[np.maximum(owner_rows, 0)] & (owner_rows >= 0), owner_rows, -1).max(axis=1)
        has = touched >= 0
        for k in range(3):
            Xp = X.copy()
            Xm = X.copy()
            Xp[members, k] += h
            Xm[members, k] -= h
            rp, _ = model.residuals_and_jacobian(Xp, need_jacobian=False)
            rm, _ = model.residuals_and_jacobian(Xm, need_jacobian=False)
            dE = 0.5 * (rp * rp - rm * rm) / (2 * h)
            G[:, k] += np.bincount(touched[has], weights=dE[has], minlength=model.n)
    return G


def distance2_coloring(model: EnergyModel) -> np.ndarray:
    """Greedy colouring so that no face and no defect-vertex star holds two vertices of one colour."""
    t = model.topology
    fverts, foff = t.vertex_faces
    nbr = [set() for _ in range(model.n)]
    for f in range(t.n_faces):
        vs = t.face(f).tolist()
        for a in vs:
            nbr[a].update(vs)
    for v in model.defect_vertices.tolist():
        star = set()
        for f in fverts[foff[v]:foff[v + 1]].tolist():
            star.update(t.face(f).tolist())
        for a in star:
            nbr[a].update(star)
    colors = np.full(model.n, -1, dtype=np.int64)
    for v in range(model.n):
        used = {colors[u] for u in nbr[v] if colors[u] >= 0}
        c = 0
        while c in used:
            c += 1
        colors[v] = c
    return colors


def row_vertices(model: EnergyModel) -> np.ndarray:
    """For each residual row of `model`, the vertices it depends on, (n_rows, width) int64, -1 padded."""
    t = model.topology
    fverts, foff = t.vertex_faces
    star_sets = [np.unique(np.concatenate([t.face(f) for f in fverts[foff[v]:foff[v + 1]]]))
                 for v in model.defect_vertices]
    width = max([1] + [len(s) for s in star_sets] + [g.k for g in model.groups])
    out = np.full((model.n_rows, width), -1, dtype=np.int64)
    for i, s in enumerate(star_sets):  # defect rows: the vertex star
        out[i, :len(s)] = s
    for g, off in zip(model.groups, model.group_row_offset):
        nr = planarity_rows(g, model.plane_method)
        out[off:off + g.m * nr, :g.k] = np.repeat(g.faces, nr, axis=0)
    if model.n_edge:
        out[model.edge_row_offset:model.edge_row_offset + model.n_edge, :2] = model.edge_pairs
    return out
