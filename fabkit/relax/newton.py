"""Minimum-norm Gauss–Newton finish on the residual vector (angle defects, planarity residuals).

Step: solve (J Jᵀ + μ I) y = r + J p and take δ = p − Jᵀ y, where p = t (x_ref − x) is an optional
pull toward the input (closeness, t = w_c / (1 + w_c)). With p = 0 and μ → 0 this is the minimum-norm
step −J⁺ r: it moves the vertices as little as possible, adds no rigid motion (rigid motions lie in
J's null space) and converges quadratically near a solution. With p ≠ 0 the step also slides the
shape along the constraint manifold toward x_ref.

Why damped: the angle defect is nearly degenerate (second order) in some directions near flat or
cylindrical regions. Undamped minimum-norm steps from a noisy start then wander far along them
(measured: 40σ away from the unperturbed panel). μ = γ‖r‖∞² · boost (Yamashita–Fukushima) keeps the
early steps gradient-like and local and the last ones pure Gauss–Newton; a trust region on the
largest vertex move, adapted from the gain ratio ρ = actual / predicted decrease of ‖r‖², rejects
steps the linear model does not predict. Near the end the residual sits in those weak, curved
directions and trust-region steps crawl; geodesic acceleration (Transtrum & Sethna 2011: bend the
step with the second directional derivative of r, one extra residual and the same factorisation) and
a second-order correction from the trial point cut the Gauss–Newton steps at ~2,500 vertices from 33
to 16 (measured on the reflect panel at 1 % noise).

Why it crawls, what cut the number of steps and what was tried without gain: docs/relax.md,
"Gauss–Newton finish: measurements".

The linear algebra is scipy.sparse: the SPD system J Jᵀ + μI has one row per residual (about
n_interior + n_faces, fewer than the 3n coordinates); SuperLU factorises it with a minimum-degree
ordering on Jᵀ+J, computed by the first factorisation and reused by the later ones (`SPDFactor`).
"""
from __future__ import annotations

import time
import warnings
from typing import Callable

import numpy as np

from fabkit.relax.dynamic import PhaseOutcome
from fabkit.relax.energy import EnergyModel, Evaluation


class SPDFactor:
    """SuperLU factorisations of J Jᵀ + μI (symmetric mode) for one Jacobian pattern.

    The first factorisation orders with minimum degree on Aᵀ+A; later ones reuse that ordering
    (NATURAL on the permuted matrix), which skips SuperLU's ordering step: measured 15 % less time per
    factorisation at ~10,000 vertices, same fill. Reusing an earlier factorisation as a
    conjugate-gradient preconditioner, or for "chord" steps, was tried and measured: the weak
    directions change too much from step to step (chord steps were rejected or barely reduced ‖r‖).
    """

    def __init__(self):
        self.order = None       # row/column order of the permuted matrix (None: not yet known)

    def __call__(self, JJt, mu: float):
        """A solve function y = (J Jᵀ + μI)⁻¹ b, or None when the factorisation fails."""
        import scipy.sparse as sp  # on use (a panel already within tolerance needs no factorisation)
        import scipy.sparse.linalg as spla

        A = JJt + sp.identity(JJt.shape[0], format="csr") * mu
        q = self.order
        if q is not None:
            A = A[q][:, q]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", spla.MatrixRankWarning)
                lu = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A" if q is None else "NATURAL",
                               diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except (RuntimeError, spla.MatrixRankWarning):
            return None
        if q is None:
            # Pc maps column i to position perm_c[i]: the elimination order is its inverse
            self.order = np.argsort(lu.perm_c)
            return lu.solve

        def solve(b: np.ndarray) -> np.ndarray:
            y = np.empty_like(b)
            y[q] = lu.solve(b[q])
            return y
        return solve


def gauss_newton(model: EnergyModel, X0: np.ndarray, *, max_iter: int, done: Callable[[Evaluation], bool],
                 x_ref: np.ndarray | None = None, closeness: float = 0.0,
                 record: Callable[[str, Evaluation, float], None] | None = None,
                 deadline: float | None = None, gamma: float = 10.0, mu_min: float = 1e-15, mu_max: float = 1e-2, radius0: float = 0.05, second_order: bool = True,
                 geodesic: bool = True,
                 grow_above: float = 0.9, shrink: float = 0.5,
                 max_failures: int = 24, corrections: int = 1) -> PhaseOutcome:
    """Damped Gauss–Newton iterations from X0 until `done` holds (see module docstring).

    Trust region: a step may move no vertex further than `radius` × L (radius starts at `radius0` and
    adapts to the gain ratio ρ = actual / predicted decrease of ‖r‖²: × `shrink` on a rejection, which
    reuses the factorisation, × 2 at ρ > `grow_above`); each rejection raises μ for the next step.
    Keeping steps where the linear model holds stops the minimum-norm step from wandering along the
    nearly singular directions of the angle defect (nearly flat or cylindrical regions).
    """
    X = np.array(X0, dtype=np.float64, copy=True)
    ev = model.evaluate(X)
    if not ev.finite:
        return PhaseOutcome(X, ev, 0, "diverged")
    if done(ev):
        return PhaseOutcome(X, ev, 0, "converged")
    t = closeness / (1.0 + closeness) if (closeness > 0 and x_ref is not None) else 0.0
    radius = radius0 * model.L
    failures = 0
    status = "max_iter"
    it = 0
    r, J = model.residuals_and_jacobian(X)
    factor = SPDFactor()
    boost = 1.0
    for it in range(1, max_iter + 1):
        phi = float(r @ r)
        # Levenberg parameter ~ ‖r‖² (Yamashita–Fukushima): damped far out, pure Gauss–Newton near the end
        mu_rel = min(max(gamma * float(np.abs(r).max()) ** 2, mu_min), mu_max) * boost
        JJt = (J @ J.T).tocsr()
        diag_scale = max(float(JJt.diagonal().mean()) if JJt.shape[0] else 1.0, 1e-300)
        p = t * model.pack(x_ref - X) if t > 0 else np.zeros(J.shape[1])
        rhs = r + J @ p if t > 0 else r
        y0 = model.pack(X)
        accepted = False
        lu = None
        while failures <= max_failures:
            if lu is None:
                lu = factor(JJt, mu_rel * diag_scale)
                y = lu(rhs) if lu is not None else None
                if y is None or not np.all(np.isfinite(y)):
                    boost = min(boost * 100.0, 1e12)
                    mu_rel *= 100.0
                    failures += 2           # a failed factorisation counts as two cheap rejections
                    lu = None
                    continue
                full = p - J.T @ y
                full_size = float(np.sqrt((full.reshape(-1, 3) ** 2).sum(axis=1)).max()) if len(full) else 0.0
            # a rejected step only shrinks the trust region: the same factorisation and direction serve
            size = full_size
            beta = min(1.0, radius / size) if size > 0 else 1.0
            velocity = full * beta
            step = velocity
            if geodesic and size > 0:
                # geodesic acceleration (Transtrum & Sethna 2011): bend the step along the curved valley
                # with the second directional derivative of r, from one extra residual and the same LU
                h = 0.1
                r_h, _ = model.residuals_and_jacobian(model.unpack(y0 + h * velocity, X), need_jacobian=False)
                r_vv = (2.0 / h) * ((r_h - r) / h - J @ velocity)
                accel = -(J.T @ lu(r_vv))
                if np.all(np.isfinite(accel)) and np.linalg.norm(accel) <= 1.5 * np.linalg.norm(velocity):
                    step = velocity + 0.5 * accel
            size = float(np.sqrt((step.reshape(-1, 3) ** 2).sum(axis=1)).max()) if len(step) else 0.0
            lin = r + J @ velocity
            pred = phi - float(lin @ lin)
            X_try = model.unpack(y0 + step, X)
            r_try, _ = model.residuals_and_jacobian(X_try, need_jacobian=False)
            phi_try = float(r_try @ r_try)
            rho = (phi - phi_try) / pred if pred > 0 else -1.0
            if second_order and corrections > 0 and np.isfinite(phi_try) and (rho < 0.75 or corrections > 1):
                # second-order corrections: minimum-norm steps from the trial point with the same
                # factorisation pull a long step back onto the curved constraint manifold. One: only
                # when ρ < 0.75, kept when it helps. More: at every trial point, the further ones while
                # each cuts ‖r‖² by 30 % (for a start near the manifold, see the module docstring)
                r_c = r_try
                for k in range(corrections):
                    X_soc = model.unpack(model.pack(X_try) - J.T @ lu(r_c), X)
                    r_soc, _ = model.residuals_and_jacobian(X_soc, need_jacobian=False)
                    phi_soc = float(r_soc @ r_soc)
                    if not (np.isfinite(phi_soc) and phi_soc < (1.0 if k == 0 else 0.7) * phi_try):
                        break
                    X_try, phi_try, r_c = X_soc, phi_soc, r_soc
                rho = (phi - phi_try) / pred if pred > 0 else -1.0
            if np.isfinite(phi_try) and phi_try < phi and rho > 0.25:
                accepted = True
                if rho > grow_above:
                    radius = max(radius, 2.0 * size)
                    boost = max(boost / 10.0, 1.0)
                break
            radius = shrink * size
            boost = min(boost * 10.0, 1e12)
            failures += 1
        if not accepted:
            status = "stalled"
            break
        X = X_try
        failures = 0
        r, J = model.residuals_and_jacobian(X)
        ev = model.evaluate(X)
        if record is not None:
            record("newton", ev, 0.0)
        if done(ev):
            status = "converged"
            break
        if deadline is not None and time.perf_counter() > deadline:
            status = "timeout"
            break
    return PhaseOutcome(X, ev, it, status)
