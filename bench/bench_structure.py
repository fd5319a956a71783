"""Crease inference accuracy against the bare 5° dihedral threshold, and its speed.

Accuracy: reflection-method panels (one and two creases, folds 30-175°, 12x3 and 24x4 quads) with
1 % vertex noise (σ = 1 % of the mean edge length) over 10 seeds, and faceted cylinder strips of
10-40 columns, exact and noisy: wrong crease edges (false + missed) and M/V errors. Speed: the
structure of a 15,000-face panel against `dihedral_angles` of the same mesh (the baseline) in the
same run.
"""
from __future__ import annotations

import numpy as np

from bench.common import best_time, report


def _panel(n, fold, columns, rows):
    from fabkit.generate import MirrorPlane, reflect_panel

    d = np.radians(fold)
    planes = [MirrorPlane(0.3, d)] if n == 1 else [MirrorPlane(0.2, d), MirrorPlane(0.42, -d)]
    return reflect_panel(planes=planes, columns=columns, rows=rows)


def _cylinder(columns, seed, radius=0.5, arc=60.0, rows=4, width=0.6):
    from fabkit.generate.reflect import grid_faces
    from fabkit.mesh import PolyMesh

    rng = np.random.default_rng(seed)
    step = np.full(columns, arc / columns) * (1.0 + 0.17 * rng.uniform(-1, 1, columns))
    phi = np.radians(np.concatenate([[0.0], np.cumsum(step)]) - arc / 2)
    V = np.array([[radius * np.sin(p), y, radius * (1 - np.cos(p))] for p in phi for y in np.linspace(0, width, rows + 1)])
    return PolyMesh(V, grid_faces(columns, rows + 1))


def _noisy(mesh, seed, rel=0.01):
    from fabkit.mesh import PolyMesh

    rng = np.random.default_rng(seed)
    V = mesh.vertices + rng.normal(0.0, rel * mesh.edge_lengths.mean(), mesh.vertices.shape)
    return PolyMesh(V, mesh.faces_list())


def main() -> dict:
    from fabkit.cutfiles import crease_assignment
    from fabkit.measures import dihedral_angles
    from fabkit.structure import panel_structure

    rows = []
    tally = {"inferred": [0, 0, 0], "threshold 5 deg": [0, 0, 0]}   # wrong edges, M/V errors, meshes
    for seed in range(10):
        for n, fold in ((1, 30), (1, 90), (1, 175), (2, 45), (2, 120), (2, 175)):
            for cols, rws in ((12, 3), (24, 4)):
                tagged = _panel(n, fold, cols, rws)
                truth = panel_structure(tagged)
                mesh = _noisy(tagged, seed)
                for name, a in (("inferred", crease_assignment(mesh).edges_assignment),
                                ("threshold 5 deg", crease_assignment(mesh, np.radians(5.0)).edges_assignment)):
                    crease = np.isin(a, ("M", "V", "U"))
                    t = tally[name]
                    t[0] += int(np.sum(crease != truth.crease))
                    t[1] += int(np.sum(a[truth.crease] != truth.assignment[truth.crease]))
                    t[2] += 1
    for name, (wrong, mv, k) in tally.items():
        rows.append({"case": f"reflect panels, 1% noise ({name})", "meshes": k, "wrong_crease_edges": wrong,
                     "mv_errors": mv})
    for label, noise in (("exact", False), ("1% noise", True)):
        for name in ("inferred", "threshold 5 deg"):
            wrong = k = 0
            for seed in range(10):
                for cols in (10, 13, 24, 40):
                    m = _cylinder(cols, seed)
                    m = _noisy(m, seed) if noise else m
                    a = (crease_assignment(m) if name == "inferred" else crease_assignment(m, np.radians(5.0)))
                    wrong += int(np.isin(a.edges_assignment, ("M", "V", "U")).sum())
                    k += 1
            rows.append({"case": f"cylinder strips, {label} ({name})", "meshes": k, "wrong_crease_edges": wrong,
                         "mv_errors": 0})
    big = _noisy(_panel(2, 60, 200, 25), 0)
    t_base = best_time(lambda: dihedral_angles(big))
    t_struct = best_time(lambda: panel_structure(big))
    rows.append({"case": f"speed: panel_structure, {big.n_faces} faces", "seconds": t_struct,
                 "ratio_to_dihedral_angles": t_struct / t_base})
    return report("structure", rows)
