"""Relaxation speed: time to tolerance on perturbed reflect panels (~600, ~2,500, ~10,000 vertices).

Compared in one run (ratios, not absolute claims):
- DR with kinetic damping + crease fairing / Gauss–Newton finish (the default; "dr+newton") vs scipy
  L-BFGS on the same energy (alone, and with the same finish) vs Gauss–Newton from the start, and vs
  the default with crease fairing off (`crease_fairness=0`: plain Gauss–Newton finish);
- DR + finish with every boundary edge kept at its unperturbed length (`edge_lengths`, the
  multi-panel workflow's use) vs the same without (~600 and ~2,500 only);
- analytic vs finite-difference gradient (paper §2.3 reports 2–3×): time per gradient, and the DR
  phase to max defect/planarity <= 1e-3 driven by each gradient (smallest size only: FD is slow).

Input: `reflect_panel` with Gaussian noise of σ = 1 % of the mean edge length on every coordinate
(seed 0); tolerance 1e-8 rad / 1e-8. Target: ~2,500 vertices in <= 1 s on one core, cost
about linear in size. Writes bench/results/bench_relax.json.
"""
from __future__ import annotations

import os
import time

import numpy as np

from bench.common import best_time, report
from fabkit.generate import reflect_panel
from fabkit.relax import Relaxer
from fabkit.relax.dynamic import dynamic_relaxation
from fabkit.relax.energy import Evaluation
from fabkit.relax.fd_gradient import colored_fd_gradient

SIZES = {"~600": (24, 12), "~2,500": (48, 25), "~10,000": (96, 50)}
NOISE = 0.01
CAP_S = float(os.environ.get("BENCH_RELAX_CAP_S", "60"))


def _panel(columns: int, rows: int):
    truth = reflect_panel(columns=columns, rows=rows)
    sigma = NOISE * float(truth.edge_lengths.mean())
    rng = np.random.default_rng(0)
    noisy = truth.with_vertices(truth.vertices + rng.normal(scale=sigma, size=truth.vertices.shape))
    return truth, noisy, sigma


def _run(noisy, truth, sigma, **options) -> dict:
    solver = Relaxer(noisy, max_seconds=CAP_S, fallback=False, **options)
    t0 = time.perf_counter()
    res = solver.solve()
    seconds = time.perf_counter() - t0
    return {"converged": res.converged, "seconds": seconds, "iterations": res.iterations,
            "phases": " ".join(f"{k}:{v}" for k, v in res.phase_iterations.items()),
            "max_defect": res.max_defect, "max_planarity": res.max_planarity,
            "max_edge_length_error": res.max_edge_length_error,
            "max_disp_sigma": float(np.linalg.norm(res.mesh.vertices - truth.vertices, axis=1).max() / sigma)}


class _FDModel:
    """The same energy with the gradient replaced by coloured central differences (bench only)."""

    def __init__(self, model):
        self.m = model
        self.free_mask, self.n, self.L, self.w_c = model.free_mask, model.n, model.L, model.w_c

    def evaluate(self, X, need_grad=True, planarity_weight=None):
        ev = self.m.evaluate(X, need_grad=False, planarity_weight=planarity_weight)
        if not need_grad:
            return ev
        G = colored_fd_gradient(self.m, X)
        G[~self.m.free_mask] = 0.0
        force = float(np.linalg.norm(G, axis=1).max()) * self.m.L
        return Evaluation(ev.energy, ev.defect, ev.planarity, G, force)

    def residuals_and_jacobian(self, X, need_jacobian=True, planarity_weight=None):
        return self.m.residuals_and_jacobian(X, need_jacobian, planarity_weight)


def _uncached_evaluate(model, X):
    """evaluate(X) without the model's one-entry geometry cache (repeated calls at one X would hit it)."""
    model._geo_X = None
    return model.evaluate(X)


def _dr_to(model, X, threshold=1e-3):
    t0 = time.perf_counter()
    out = dynamic_relaxation(model, X, max_iter=2000, done=lambda ev: ev.max_defect <= threshold and
                             ev.max_planarity <= threshold, deadline=time.perf_counter() + CAP_S)
    return time.perf_counter() - t0, out


def main() -> dict:
    rows = []
    for label, (cols, nrows) in SIZES.items():
        truth, noisy, sigma = _panel(cols, nrows)
        base = {"size": label, "vertices": noisy.n_vertices}
        runs = {
            "dr+newton": dict(method="dr"),
            "lbfgs": dict(method="lbfgs", finish=False, max_iter=100000),
            "lbfgs+newton": dict(method="lbfgs"),
            "newton": dict(method="newton"),
            "dr+newton, fairing off": dict(method="dr", crease_fairness=0.0),
        }
        results = {}
        for name, opts in runs.items():
            results[name] = r = _run(noisy, truth, sigma, **opts)
            rows.append({**base, "method": name, **r})
        dr = results["dr+newton"]["seconds"]
        for name in ("lbfgs", "lbfgs+newton", "newton", "dr+newton, fairing off"):
            r = results[name]
            rows.append({**base, "method": f"ratio {name} / dr+newton",
                         "seconds": r["seconds"] / dr if r["converged"] else float("nan"),
                         "converged": r["converged"]})
        if label != "~10,000":
            b = np.flatnonzero(truth.topology.boundary_edge_mask)
            kept = _run(noisy, truth, sigma, method="dr", edge_lengths=(b, truth.edge_lengths[b]))
            rows.append({**base, "method": f"dr+newton, {len(b)} boundary edges kept", **kept})
            rows.append({**base, "method": "ratio edges kept / dr+newton",
                         "seconds": kept["seconds"] / dr if kept["converged"] else float("nan"),
                         "converged": kept["converged"]})
        # gradient cost: analytic vs coloured finite differences
        solver = Relaxer(noisy)
        X = np.array(noisy.vertices)
        t_an = best_time(lambda: _uncached_evaluate(solver.model, X), repeat=5)
        t_fd = best_time(lambda: colored_fd_gradient(solver.model, X), repeat=1 if noisy.n_vertices > 5000 else 3)
        rows.append({**base, "method": "gradient analytic", "seconds": t_an})
        rows.append({**base, "method": "gradient finite-diff", "seconds": t_fd})
        rows.append({**base, "method": "ratio gradient fd / analytic", "seconds": t_fd / t_an})
        if label == "~600":
            t_a, out_a = _dr_to(solver.model, X)
            t_f, out_f = _dr_to(_FDModel(solver.model), X)
            rows.append({**base, "method": "DR to 1e-3 analytic", "seconds": t_a, "iterations": out_a.iterations,
                         "converged": out_a.status == "converged"})
            rows.append({**base, "method": "DR to 1e-3 finite-diff", "seconds": t_f, "iterations": out_f.iterations,
                         "converged": out_f.status == "converged"})
            rows.append({**base, "method": "ratio DR fd / analytic", "seconds": t_f / t_a})
    per_vertex = {r["size"]: r["seconds"] / r["vertices"] for r in rows if r["method"] == "dr+newton"}
    meta = {"noise_sigma_rel": NOISE, "tolerance": 1e-8, "cap_s": CAP_S, "cpu_count": os.cpu_count(),
            "load_avg_1min": os.getloadavg()[0], "dr_seconds_per_vertex": per_vertex,
            "target": "~2,500 vertices at 1% noise to 1e-8 in <= 1 s on one core; about linear in size"}
    return report("bench_relax", rows, meta)


if __name__ == "__main__":
    main()
