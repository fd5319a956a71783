"""Refold speed: 100 fold states of a ~2,500-vertex two-crease reflect panel (target: <= 2 s on one core).

Wall and CPU time are both reported (CPU time is the fairer number on a shared machine); run with
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 for the one-core target.

Rows:
- `sequence`: the whole schedule with each minimum-norm solver ("direct" sparse factorisation,
  "lsmr", "dense" numpy pinv = the baseline); time per state, Newton iterations and factorisations
  per state, and the accuracy reached. By default the diagonals of the (planar) quads are held, so
  the direct solver factorises C^T C (6912 x 4702 Jacobian). On the large panel also plain Newton
  (`newton=full`: a factorisation at every step) and `held=none` (diagonals solved for: C C^T of
  the 6912 x 7103 Jacobian). The dense baseline and LSMR run only on the smaller panel (a dense
  pinv of the large Jacobian takes minutes); `ratio` = CPU time / the first row's CPU time on the
  same panel in the same run.
- `one_step`: a single Newton linear solve on the large panel, mid-fold, with and without the
  diagonals held (and, with FABKIT_BENCH_DENSE_LARGE=1, the dense baseline: minutes).
- `intersections`: the interpenetration check per state on the large panel (off in `sequence`).
"""
from __future__ import annotations

import os
import time

import numpy as np

from bench.common import report


def _pair(columns: int, rows):
    from fabkit.generate import MirrorPlane, reflect_panel
    from fabkit.mesh import PolyMesh

    panel = reflect_panel(planes=[MirrorPlane(0.15, np.radians(60)), MirrorPlane(0.35, np.radians(-60))],
                          columns=columns, rows=rows)
    uv = np.asarray(panel.vertex_data["uv"])
    flat = PolyMesh(np.column_stack([uv, np.zeros(len(uv))]), panel.faces_list(), face_data=panel.face_data)
    return flat, panel


def _run(flat, target, frames, solver, chord=True, hold=True):
    from fabkit.refold import RefoldSolver
    from fabkit.refold.sequence import build_schedule

    t0 = time.perf_counter()
    s = RefoldSolver(flat, target, solver=solver, chord=chord, hold_planar_quads=hold)
    driven, _ = s.driven_hinges("middle-row")
    F, steps = build_schedule(s.panel, driven, None, frames)
    setup = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    seq = s.solve(F, driven, steps, check_intersections=False)
    solve, cpu = time.perf_counter() - t0, time.process_time() - c0
    its = seq.newton_iterations[1:]
    return {"vertices": flat.n_vertices, "hinges": int(seq.summary()["hinges"]), "states": seq.n_states,
            "solver": solver, "newton": "chord" if chord else "full", "held": "planar_quads" if len(s.held) else "none", "setup_s": setup, "solve_s": solve, "cpu_s": cpu,
            "ms_per_state": 1e3 * solve / (seq.n_states - 1), "cpu_ms_per_state": 1e3 * cpu / (seq.n_states - 1),
            "newton_per_state_mean": float(its.mean()), "newton_per_state_max": int(its.max()),
            "factorizations": s.linear_solver.factorizations,
            "factorizations_per_state": s.linear_solver.factorizations / (seq.n_states - 1),
            "lsmr_iterations": s.linear_solver.inner_iterations,
            "max_loop_residual_rad": float(seq.residual.max()),
            "max_edge_length_error": float(seq.edge_length_error.max()),
            "target_distance_rel": seq.target_distance / seq.panel_size,
            "converged": bool(seq.converged.all())}, seq, s


def main(frames: int = 100) -> dict:
    from fabkit.refold.intersect import intersecting_pairs
    from fabkit.refold.kinematics import JacobianPattern, MinNormSolver, loop_closure

    rows = []
    big = _pair(49, [16, 16, 17])           # 50 x 50 = 2,500 vertices
    r, seq, solver = _run(*big, frames, "direct")
    rows.append({"case": "sequence", **r, "target_s": 2.0, "ratio": 1.0})
    full, _, _ = _run(*big, frames, "direct", chord=False)   # a factorisation at every Newton step
    rows.append({"case": "sequence", **full, "ratio": full["cpu_s"] / r["cpu_s"]})
    free, _, _ = _run(*big, frames, "direct", hold=False)    # diagonals solved for: the larger C C^T system
    rows.append({"case": "sequence", **free, "ratio": free["cpu_s"] / r["cpu_s"]})
    small = _pair(24, [8, 8, 8])             # 25 x 25 = 625 vertices
    small_frames = 6
    base, _, _ = _run(*small, small_frames, "direct")
    rows.append({"case": "sequence", **base, "ratio": 1.0})
    for method in ("lsmr", "dense"):
        r2, _, _ = _run(*small, small_frames, method)
        rows.append({"case": "sequence", **r2, "ratio": r2["cpu_s"] / base["cpu_s"]})

    # one Newton linear solve on the large panel, mid-fold: quads held planar (the default, C^T C) and with the
    # diagonals free (C C^T); best CPU time of 3
    rho = 0.5 * solver.target_angles
    driven, _ = solver.driven_hinges("middle-row")
    res, omega = loop_closure(solver.loops, rho)
    b = -res.ravel()
    one = {}
    for held in ("planar_quads", "none"):
        fixed = np.union1d(driven, solver.held) if held == "planar_quads" else driven
        C = JacobianPattern(solver.loops, np.setdiff1d(solver.hinges, fixed)).matrix(omega)
        cpu = []
        for _ in range(3):
            c0 = time.process_time()
            x = MinNormSolver("direct").solve(C, b)
            cpu.append(time.process_time() - c0)
        one[held] = (C, x, min(cpu))
        rows.append({"case": "one_step", "vertices": big[0].n_vertices, "held": held, "rows": C.shape[0],
                     "cols": C.shape[1], "solver": "direct", "cpu_s": min(cpu),
                     "ratio": min(cpu) / one["planar_quads"][2]})
    if os.environ.get("FABKIT_BENCH_DENSE_LARGE", "0") != "0":  # minutes: opt in
        C, x_direct, c_direct = one["planar_quads"]
        c0 = time.process_time()
        x_dense = MinNormSolver("dense").solve(C, b)
        c_dense = time.process_time() - c0
        rows.append({"case": "one_step", "vertices": big[0].n_vertices, "held": "planar_quads", "rows": C.shape[0],
                     "cols": C.shape[1], "solver": "dense", "cpu_s": c_dense, "ratio": c_dense / c_direct,
                     "max_diff_vs_direct": float(np.abs(x_dense - x_direct).max())})

    t0, c0 = time.perf_counter(), time.process_time()
    hits = [len(intersecting_pairs(seq.positions[s], seq.tris, tol=1e-9 * seq.panel_size,
                                   neighbours=solver.neighbour_keys))
            for s in range(0, seq.n_states, 10)]
    t_int = (time.perf_counter() - t0) / len(hits)
    c_int = (time.process_time() - c0) / len(hits)
    rows.append({"case": "intersections", "vertices": big[0].n_vertices, "triangles": len(seq.tris),
                 "ms_per_state": 1e3 * t_int, "cpu_ms_per_state": 1e3 * c_int, "states_with_hits": int(np.sum(np.array(hits) > 0))})
    return report("bench_refold", rows, meta={
        "what": f"refold of a two-crease reflect panel, {frames} states, middle-row drive, tol 1e-13 rad",
        "target": "100 states of a ~2,500-vertex panel in <= 2 s on one core",
        "cpu_count": os.cpu_count()})


if __name__ == "__main__":
    main()
