"""Catmull–Clark speed: the vectorised sparse operator vs a plain-Python reference.

The baseline is `reference_catmull_clark` below (dicts and loops over faces, the textbook
algorithm with the same boundary rules and numbering), timed in the same run. The table gives,
per input, the reference's time, the vectorised step's (positions and quads: the same output as
the reference; directly and through the sparse matrix) and the full `catmull_clark` call (which
also builds the new mesh's connectivity), with the ratios; the last row makes a million output
faces.

    .venv/bin/python -m bench.bench_subdivide
"""
from __future__ import annotations

import numpy as np

from bench.common import best_time, report


def reference_catmull_clark(vertices: list, faces: list[list[int]]) -> tuple[np.ndarray, list[list[int]]]:
    """One Catmull–Clark step in plain Python (no numpy in the loops); same rules and numbering as
    `fabkit.generate.subdivide` (old vertices, then edge points in sorted-edge order, then face points)."""
    n = len(vertices)
    V = [tuple(map(float, v)) for v in vertices]

    def add(a, b):
        return (a[0] + b[0], a[1] + b[1], a[2] + b[2])

    def mul(a, s):
        return (a[0] * s, a[1] * s, a[2] * s)

    face_pts = []
    for f in faces:
        acc = (0.0, 0.0, 0.0)
        for v in f:
            acc = add(acc, V[v])
        face_pts.append(mul(acc, 1.0 / len(f)))
    edge_faces: dict[tuple[int, int], list[int]] = {}
    for fi, f in enumerate(faces):
        for k, a in enumerate(f):
            b = f[(k + 1) % len(f)]
            edge_faces.setdefault((min(a, b), max(a, b)), []).append(fi)
    edges = sorted(edge_faces)
    edge_index = {e: i for i, e in enumerate(edges)}
    edge_pts = []
    for e in edges:
        fs = edge_faces[e]
        if len(fs) == 2:
            edge_pts.append(mul(add(add(V[e[0]], V[e[1]]), add(face_pts[fs[0]], face_pts[fs[1]])), 0.25))
        else:
            edge_pts.append(mul(add(V[e[0]], V[e[1]]), 0.5))
    v_faces: dict[int, list[int]] = {}
    for fi, f in enumerate(faces):
        for v in f:
            v_faces.setdefault(v, []).append(fi)
    v_edges: dict[int, list[tuple[int, int]]] = {}
    for e in edges:
        v_edges.setdefault(e[0], []).append(e)
        v_edges.setdefault(e[1], []).append(e)
    new_v = []
    for v in range(n):
        es = v_edges.get(v, [])
        boundary = [e for e in es if len(edge_faces[e]) == 1]
        if not es:
            new_v.append(V[v])
        elif not boundary:
            k = len(es)
            q = (0.0, 0.0, 0.0)
            for fi in v_faces[v]:
                q = add(q, face_pts[fi])
            q = mul(q, 1.0 / k)
            r = (0.0, 0.0, 0.0)
            for e in es:
                r = add(r, mul(add(V[e[0]], V[e[1]]), 0.5))
            r = mul(r, 1.0 / k)
            new_v.append(mul(add(add(q, mul(r, 2.0)), mul(V[v], k - 3.0)), 1.0 / k))
        elif len(boundary) == 2 and len(v_faces[v]) >= 2:
            nb = [e[1] if e[0] == v else e[0] for e in boundary]
            new_v.append(mul(add(add(V[nb[0]], V[nb[1]]), mul(V[v], 6.0)), 1.0 / 8.0))
        else:
            new_v.append(V[v])
    out_faces = []
    E = len(edges)
    for fi, f in enumerate(faces):
        for k, v in enumerate(f):
            nxt, prv = f[(k + 1) % len(f)], f[k - 1]
            e_n = edge_index[(min(v, nxt), max(v, nxt))]
            e_p = edge_index[(min(v, prv), max(v, prv))]
            out_faces.append([v, n + e_n, n + E + fi, n + e_p])
    return np.array(new_v + edge_pts + face_pts), out_faces


def _points_only(mesh):
    """The vectorised step without building the new mesh's topology: `(points, quads)`, as the
    reference computes; this is what `catmull_clark` uses (bincount evaluation)."""
    from fabkit.generate.subdivide import catmull_clark_points, catmull_clark_quads

    return catmull_clark_points(mesh.topology, mesh.vertices), catmull_clark_quads(mesh.topology)[0]


def _sparse_only(mesh):
    """The same through the assembled sparse operator: `(S @ V, quads)`."""
    from fabkit.generate.subdivide import catmull_clark_operator

    S, quads, _ = catmull_clark_operator(mesh.topology)
    return S @ mesh.vertices, quads


def main() -> dict:
    from fabkit.generate import catmull_clark, delete_faces, prism
    from fabkit.generate.polyhedra import grid

    rows = []
    small = catmull_clark(prism(12), 2)  # an open mesh with extraordinary vertices and corners
    small, _ = delete_faces(small, np.arange(0, small.n_faces, 17))
    cases = [("small open mesh", small, 3), ("grid 250x250", grid(250, 250), 1), ("grid 500x500", grid(500, 500), 0)]
    for name, mesh, ref_repeat in cases:
        out_faces = int(mesh.topology.face_sizes.sum())
        _ = mesh.topology.halfedge_twin  # the input's topology is built once, outside the timings
        if ref_repeat:
            Vl, Fl = mesh.vertices.tolist(), mesh.faces_list()
            t_ref = best_time(lambda: reference_catmull_clark(Vl, Fl), repeat=ref_repeat)
        else:
            t_ref = float("nan")
        reps = 3 if out_faces < 1e5 else 1
        t_op = best_time(lambda: _points_only(mesh), repeat=reps)
        t_sparse = best_time(lambda: _sparse_only(mesh), repeat=reps)
        t_full = best_time(lambda: catmull_clark(mesh), repeat=reps)
        rows.append({"case": name, "in_faces": mesh.n_faces, "out_faces": out_faces, "python_s": t_ref,
                     "points_s": t_op, "sparse_operator_s": t_sparse, "with_topology_s": t_full,
                     "speedup_points": t_ref / t_op, "speedup_with_topology": t_ref / t_full})
    return report("subdivide", rows, meta={
        "baseline": "plain-Python reference_catmull_clark (same rules and numbering), same run",
        "points_s": "new positions and quads (what the reference computes), bincount evaluation",
        "sparse_operator_s": "the same through the assembled sparse matrix S (S @ V)",
        "with_topology_s": "catmull_clark(): operator plus the new PolyMesh and its MeshTopology"})


if __name__ == "__main__":
    main()
