"""Unfold speed and accuracy against libigl's LSCM and ARAP, on the same meshes in the same run.

Meshes (quad grids, 2,500 and 10,000 vertices):
- developable: a half-cylinder strip (exact development known);
- bumped: the same with x scaled by 1 + 0.1 sin(pi y / h) (not developable, like a panel that is
  not yet relaxed; the reference notes' test mesh);
- relaxed: the bumped 2,500-vertex panel after `fabkit.relax` (when that stage is available).

Rows: fabkit isometric (the paper's least-squares spring energy, the default), fabkit isometric
with the p = 4 spring energy (`norm=4`: smaller max for a larger mean), fabkit conformal, igl
LSCM, igl ARAP; `*_vs_arap` are ratios to ARAP in the same run (< 1: better).

Every result is measured the same way (`fabkit.unfold.development.measure_development` on the quad
mesh: every edge and both diagonals of every quad), and also on the edges of the fan triangulation
libigl works on ("tri" columns). libigl runs on that fan triangulation: LSCM pins the two farthest
boundary vertices and is rescaled by its least-squares best scale; ARAP starts from that LSCM
result, pins one vertex (it fails with none) and runs 100 iterations.

Run: `.venv/bin/python -m bench unfold` (writes bench/results/bench_unfold.json).
"""
from __future__ import annotations

import time

import numpy as np

from bench.common import best_time, report
from fabkit.mesh import PolyMesh
from fabkit.unfold import develop, reference_lengths
from fabkit.unfold.conformal import best_scale
from fabkit.unfold.development import measure_development
from fabkit.unfold.metrics import spring_lengths


def grid_faces(nu: int, nv: int) -> np.ndarray:
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
    a = (i * nv + j).ravel()
    return np.stack([a, a + nv, a + nv + 1, a + 1], axis=1)


def cylinder(n: int, bump: float = 0.0, radius: float = 0.5, height: float = 1.0) -> PolyMesh:
    phi = np.linspace(-np.pi / 2, np.pi / 2, n)
    y = np.linspace(0.0, height, n)
    P, Y = np.meshgrid(phi, y, indexing="ij")
    X = radius * np.sin(P) * (1 + bump * np.sin(np.pi * Y / height))
    V = np.stack([X, Y, radius * (1 - np.cos(P))], axis=-1).reshape(-1, 3)
    return PolyMesh(V, grid_faces(n, n))


def relaxed(mesh: PolyMesh) -> PolyMesh | None:
    try:
        from fabkit.relax import relax
    except ImportError:
        return None
    try:
        return relax(mesh).mesh
    except Exception as exc:  # the relax stage is another module's; report and go on
        print(f"   (relax failed: {type(exc).__name__}: {exc})")
        return None


def tri_edge_error(V: np.ndarray, tris: np.ndarray, uv: np.ndarray) -> tuple[float, float]:
    e = np.unique(np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1), axis=0)
    rel = np.abs(spring_lengths(uv, e) / spring_lengths(V, e) - 1)
    return float(rel.mean()), float(rel.max())


def igl_lscm(V, tris, mesh):
    import igl

    b = np.concatenate(mesh.boundary_loops)
    P = V[b]
    i = int(np.argmax(np.linalg.norm(P - P[0], axis=1)))
    j = int(np.argmax(np.linalg.norm(P - P[i], axis=1)))
    pins = np.array([b[i], b[j]], dtype=np.int64)
    bc = np.array([[0.0, 0.0], [1.0, 0.0]])
    uv, _ = igl.lscm(V, tris, pins, bc)
    pairs, rest = reference_lengths(mesh)
    return uv * best_scale(uv, pairs, rest)


def igl_arap(V, tris, start):
    import igl

    data = igl.ARAPData()
    data.max_iter = 100
    b = np.array([0], dtype=np.int32)
    igl.arap_precomputation(V, tris, 2, b, data)
    return igl.arap_solve(start[b], data, start)


def run_case(name: str, mesh: PolyMesh, rows: list, repeat: int) -> None:
    V = np.ascontiguousarray(mesh.vertices)
    tris = np.ascontiguousarray(mesh.triangulate()[0])
    results = {}

    dev = develop(mesh)
    t_ours = best_time(lambda: develop(mesh), repeat)
    results["fabkit isometric"] = (t_ours, dev.uv, dev)
    if dev.max_relative_deviation > 1e-12:  # p only matters when there is an error to distribute
        t0 = time.perf_counter()
        dev_p = develop(mesh, norm=4)
        results["fabkit isometric p=4"] = (time.perf_counter() - t0, dev_p.uv, dev_p)
    t = best_time(lambda: develop(mesh, "conformal"), repeat)
    results["fabkit conformal"] = (t, develop(mesh, "conformal").uv, None)
    try:
        import igl  # noqa: F401

        lscm_uv = igl_lscm(V, tris, mesh)
        t_l = best_time(lambda: igl_lscm(V, tris, mesh), repeat)
        results["igl lscm"] = (t_l, lscm_uv, None)
        arap_uv = igl_arap(V, tris, lscm_uv)
        t_a = best_time(lambda: igl_arap(V, tris, lscm_uv), repeat)
        results["igl arap (+lscm start)"] = (t_a + t_l, arap_uv, None)
    except ImportError:
        print("   (libigl not installed: baselines skipped; pip install '.[bench]')")
    arap = results.get("igl arap (+lscm start)")
    arap_dev = measure_development(mesh, arap[1], method="arap") if arap else None
    for method, (t, uv, d) in results.items():
        d = d or measure_development(mesh, uv, method=method)
        tm, tx = tri_edge_error(V, tris, uv)
        rows.append({
            "mesh": name, "vertices": mesh.n_vertices, "method": method, "time_s": t,
            "time_vs_arap": (t / arap[0]) if arap else "",
            "mean_rel": d.mean_relative_deviation, "max_rel": d.max_relative_deviation,
            "mean_vs_arap": d.mean_relative_deviation / arap_dev.mean_relative_deviation if arap else "",
            "max_vs_arap": d.max_relative_deviation / arap_dev.max_relative_deviation if arap else "",
            "tri_mean_rel": tm, "tri_max_rel": tx, "flipped": d.n_flipped,
        })


def main() -> dict:
    rows: list[dict] = []
    meta = {"repeat": 3, "metric": "|l2D-l3D|/l3D over quad edges + both diagonals; tri_* over fan-triangle edges"}
    for n in (50, 100):
        run_case("developable", cylinder(n), rows, 3)
        run_case("bumped 0.1", cylinder(n, bump=0.1), rows, 1)
    t0 = time.perf_counter()
    r = relaxed(cylinder(50, bump=0.1))
    if r is not None:
        meta["relax_time_s"] = time.perf_counter() - t0
        run_case("relaxed (bumped 0.1)", r, rows, 1)
    return report("bench_unfold", rows, meta)


if __name__ == "__main__":
    main()
