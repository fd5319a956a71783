"""Isometric development (paper §2.8): spring energy between 3D (or target) and 2D lengths.

Energy: sum over springs s (edges and face diagonals) of w_s ((l2D_s - L_s) / L_s)^2, i.e. the
relative length deviation the paper reports (w_s = 1 for edges, 2/k for the diagonals of a k-gon:
see `springs.spring_weights`), minimised as a sparse nonlinear least-squares problem
by Gauss-Newton with a line search (sparse analytic Jacobian, sparse direct solves with
`scipy.sparse.linalg.splu`), from the exact incremental layout. Three coordinates (the layout's
anchor vertex and the y of its second vertex) are held fixed to remove the rigid-motion freedom.

Optionally (`norm` p > 2) the least-squares result is carried on to minimise sum |r_s|^p, which
trades a little mean deviation for a smaller maximum (p -> infinity would be minimax); see
`refine_pnorm`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix, diags
from scipy.sparse.linalg import splu

from fabkit.mesh import PolyMesh

__all__ = ["SpringProblem", "corner_triangles", "refine_isometric", "refine_pnorm", "gauss_newton"]

#: The layout counts as exact when every spring is within this relative deviation (round-off).
EXACT_RTOL = 1e-12
#: The solver stops once every residual is this small (nothing left to gain in float64).
ROUNDOFF = 1e-13
EPS = float(np.finfo(float).eps)


#: Flip guard: a corner triangle whose 2D/3D signed area ratio drops below this is pushed back ...
FLIP_GUARD_RATIO = 0.05
#: ... with this weight per unit of ratio (springs count with weight 1 per unit relative deviation).
FLIP_GUARD_WEIGHT = 10.0


@dataclass(frozen=True)
class SpringProblem:
    """Springs `pairs` (S, 2) with rest lengths `rest` (S,) over `n` vertices; `free` (2n,) marks the
    coordinates the solver may move (row-major u0, v0, u1, v1, ...).

    Optional flip guard: `guard_tris` (G, 3) corner triangles (prev, here, next) with their signed 3D
    areas `guard_area` (G,) add one residual each, FLIP_GUARD_WEIGHT * max(0, FLIP_GUARD_RATIO -
    A2D/A3D): zero for every triangle that keeps at least 5 % of its area with the right orientation
    (so exact and ordinary developments are untouched), growing as a triangle collapses or turns over.
    """

    pairs: np.ndarray
    rest: np.ndarray
    n: int
    free: np.ndarray
    guard_tris: np.ndarray | None = None
    guard_area: np.ndarray | None = None
    weights: np.ndarray | None = None

    def spring_residuals(self, uv: np.ndarray) -> np.ndarray:
        """Relative length deviation (l - L) / L of every spring (unweighted)."""
        d = uv[self.pairs[:, 1]] - uv[self.pairs[:, 0]]
        return np.sqrt(np.einsum("ij,ij->i", d, d)) / self.rest - 1.0

    @property
    def _root_weights(self):
        return 1.0 if self.weights is None else np.sqrt(self.weights)

    def _areas(self, uv: np.ndarray) -> np.ndarray:
        i, j, k = self.guard_tris.T
        return 0.5 * ((uv[j, 0] - uv[i, 0]) * (uv[k, 1] - uv[i, 1]) - (uv[k, 0] - uv[i, 0]) * (uv[j, 1] - uv[i, 1]))

    def residuals(self, uv: np.ndarray) -> np.ndarray:
        """Spring residuals (times the square root of their energy weights), then the flip guards."""
        r = self.spring_residuals(uv) * self._root_weights
        if self.guard_tris is None:
            return r
        ratio = self._areas(uv) / self.guard_area
        return np.concatenate([r, FLIP_GUARD_WEIGHT * np.maximum(0.0, FLIP_GUARD_RATIO - ratio)])

    def jacobian(self, uv: np.ndarray) -> csr_matrix:
        """Sparse d residuals / d coordinates: four entries per spring, six per active guard."""
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        d = uv[j] - uv[i]
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        g = d / np.maximum(length * self.rest, 1e-300)[:, None]
        g = g * (self._root_weights if self.weights is None else self._root_weights[:, None])
        S = len(self.pairs)
        rows = np.repeat(np.arange(S), 4)
        cols = np.stack([2 * i, 2 * i + 1, 2 * j, 2 * j + 1], axis=1).ravel()
        vals = np.stack([-g[:, 0], -g[:, 1], g[:, 0], g[:, 1]], axis=1).ravel()
        n_rows = S
        if self.guard_tris is not None:
            G = len(self.guard_tris)
            active = np.flatnonzero(self._areas(uv) / self.guard_area < FLIP_GUARD_RATIO)
            a, b, c = self.guard_tris[active].T
            x, y = uv[:, 0], uv[:, 1]
            w = -FLIP_GUARD_WEIGHT * 0.5 / self.guard_area[active]
            gv = np.stack([(y[b] - y[c]) * w, (x[c] - x[b]) * w, (y[c] - y[a]) * w, (x[a] - x[c]) * w,
                           (y[a] - y[b]) * w, (x[b] - x[a]) * w], axis=1).ravel()
            gc = np.stack([2 * a, 2 * a + 1, 2 * b, 2 * b + 1, 2 * c, 2 * c + 1], axis=1).ravel()
            gr = np.repeat(S + active, 6)
            rows, cols, vals = np.concatenate([rows, gr]), np.concatenate([cols, gc]), np.concatenate([vals, gv])
            n_rows = S + G
        return csr_matrix((vals, (rows, cols)), shape=(n_rows, 2 * self.n))


def corner_triangles(mesh: PolyMesh) -> tuple[np.ndarray, np.ndarray]:
    """`(tris (C, 3), signed 3D area (C,))`: the triangle (prev, here, next) at every corner, its area
    signed positive when the corner turns like its face (convex corner)."""
    t = mesh.topology
    tris = np.stack([t.face_indices[t.corner_prev], t.face_indices, t.face_indices[t.corner_next]], axis=1)
    cross = mesh.corner_cross  # (next - here) x (prev - here): towards the front at convex corners
    area = 0.5 * np.linalg.norm(cross, axis=1)
    sign = np.where(np.einsum("ij,ij->i", cross, mesh.face_normal_sums[t.corner_face]) < 0, -1.0, 1.0)
    return tris, sign * np.maximum(area, 1e-300)


def _anchored_free(n: int, anchor: tuple[int, int], used: np.ndarray) -> np.ndarray:
    free = np.repeat(used, 2)
    a, b = anchor
    free[[2 * a, 2 * a + 1, 2 * b + 1]] = False
    return free


def refine_isometric(mesh: PolyMesh, uv0: np.ndarray, pairs: np.ndarray, rest: np.ndarray,
                     anchor: tuple[int, int], *, max_iterations: int = 100,
                     tol: float = 1e-12, norm: float = 2.0, weights: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """Minimise the spring energy from `uv0`; returns `(uv, info)` with iterations/converged/message.

    `weights`: energy weight per spring (default 1). When `uv0` already meets every rest length to
    `EXACT_RTOL` with no flip guard active (exactly developable input laid out exactly) the solver
    is not started: that is the minimum. `norm` > 2 continues from the least-squares minimum with
    `refine_pnorm`.
    """
    n = len(uv0)
    tris, area = corner_triangles(mesh)
    problem = SpringProblem(pairs=pairs, rest=rest, n=n, free=_anchored_free(n, anchor, mesh.topology.used_vertex_mask),
                            guard_tris=tris, guard_area=area, weights=weights)
    r0 = problem.residuals(uv0)
    start_max = float(np.max(np.abs(problem.spring_residuals(uv0))))
    if not np.all(np.isfinite(r0)):
        raise FloatingPointError("the starting layout has non-finite spring lengths")
    if start_max <= EXACT_RTOL and not np.any(r0[len(pairs):]):  # springs exact, no guard active
        return uv0, {"iterations": 0, "converged": True, "message": "layout already exact (no refinement needed)",
                     "initial_max_relative_deviation": start_max}
    uv, info = gauss_newton(problem.residuals, problem.jacobian, uv0, problem.free,
                            max_iterations=max_iterations, tol=tol)
    if norm != 2.0 and info["converged"] and np.max(np.abs(problem.residuals(uv))) > ROUNDOFF:
        uv, info_p = refine_pnorm(problem, uv, norm, max_iterations=max_iterations)
        info = {**info_p, "iterations": info["iterations"] + info_p["iterations"],
                "message": f"least squares: {info['message']}; p = {norm:g}: {info_p['message']}"}
    info["initial_max_relative_deviation"] = start_max
    return uv, info


def refine_pnorm(problem: SpringProblem, uv0: np.ndarray, p: float, *, max_iterations: int = 100,
                 tol: float = 1e-10) -> tuple[np.ndarray, dict]:
    """Minimise f = sum |r_s|^p (p > 2) over the problem's (weighted) residuals from `uv0` by
    generalised Gauss-Newton.

    Gradient Jᵀ(p |r|^(p-1) sign r); Hessian model Jᵀ diag(p (p-1) |r|^(p-2)) J, with |r| floored at
    1e-3 of its RMS so springs that are already exact keep some stiffness; one SuperLU solve per
    iteration and a backtracking line search on f itself (so every accepted step lowers f).
    """
    if not (np.isfinite(p) and p > 2):
        raise ValueError(f"norm must be a number above 2 here, got {p}")
    n = len(uv0)
    cols = np.flatnonzero(problem.free)
    z = uv0.ravel().copy()
    r = problem.residuals(uv0)
    f = float(np.sum(np.abs(r) ** p))
    message, converged, it = f"stopped after {max_iterations} iterations without meeting the tolerance", False, 0
    for it in range(1, max_iterations + 1):
        J = problem.jacobian(z.reshape(n, 2))[:, cols].tocsc()
        a = np.abs(r)
        g = J.T @ (p * a ** (p - 1) * np.sign(r))
        w = p * (p - 1) * np.maximum(a, 1e-3 * np.sqrt(np.mean(r * r))) ** (p - 2)
        H = (J.T @ diags(w) @ J).tocsc()
        H = (H + diags(1e-9 * np.maximum(H.diagonal(), 1e-300))).tocsc()
        step = -splu(H, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True}).solve(g)
        t, accepted = 1.0, False
        for _ in range(30):  # bounded backtracking
            trial = z.copy()
            trial[cols] += t * step
            r_new = problem.residuals(trial.reshape(n, 2))
            f_new = float(np.sum(np.abs(r_new) ** p))
            if np.isfinite(f_new) and f_new < f:
                accepted = True
                break
            t *= 0.5
        if not accepted:
            message, converged = "no step lowers the energy any more", True
            break
        drop = f - f_new
        z, r, f_prev, f = trial, r_new, f, f_new
        if drop <= tol * f_prev:
            message, converged = "energy no longer decreases", True
            break
    if not np.all(np.isfinite(z)):
        raise FloatingPointError("the spring solver diverged (non-finite coordinates)")
    return z.reshape(n, 2), {"iterations": it, "converged": converged, "message": message}


def gauss_newton(residuals, jacobian, uv0: np.ndarray, free: np.ndarray, *, max_iterations: int = 100,
                 tol: float = 1e-12, damping: float = 1e-9) -> tuple[np.ndarray, dict]:
    """Gauss-Newton with a backtracking line search on the coordinates marked `free`.

    `residuals(uv) -> (S,)`, `jacobian(uv) -> (S, 2n)` sparse. Each iteration solves the normal
    equations (JᵀJ + damping·diag JᵀJ) δ = -Jᵀr once with SuperLU (`scipy.sparse.linalg.splu`,
    symmetric mode, minimum-degree ordering) and halves the step until the energy ½|r|² drops
    (at most 30 halvings, each only a residual evaluation). Stops when the energy drops by less
    than `tol` relative, every residual is at round-off, the gradient vanishes, no step lowers the
    energy any more, or after `max_iterations`; the message says which.
    The loop is ours because `scipy.optimize.least_squares` has no sparse direct inner solver: its
    LSMR inner solves took 5 s without converging on a 10k-vertex panel.
    """
    n = len(uv0)
    cols = np.flatnonzero(free)
    z = uv0.ravel().copy()
    r = residuals(z.reshape(n, 2))
    cost = 0.5 * float(r @ r)
    message = f"stopped after {max_iterations} iterations without meeting the tolerance"
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        J = jacobian(z.reshape(n, 2))[:, cols].tocsc()
        g = J.T @ r
        if np.max(np.abs(g)) <= 1e-300 or not np.any(g):
            message, converged = "gradient vanished", True
            break
        H = (J.T @ J).tocsc()
        H = (H + diags(damping * np.maximum(H.diagonal(), 1e-300))).tocsc()
        try:
            step = -splu(H, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                         options={"SymmetricMode": True}).solve(g)
        except RuntimeError as exc:  # singular: the spring network does not hold the panel's shape
            raise FloatingPointError(f"the spring system is singular ({exc})") from None
        predicted = -0.5 * float(g @ step)  # the Gauss-Newton model's gain for the full step
        # below this the energy change is decided by round-off in the residuals (a few eps each)
        noise_floor = 4 * EPS * float(np.sum(np.abs(r))) + len(r) * (8 * EPS) ** 2
        if predicted <= max(tol * cost, noise_floor):
            message, converged = "converged (the model predicts no further gain)", True
            break
        t, accepted = 1.0, False
        for _ in range(30):  # bounded backtracking
            trial = z.copy()
            trial[cols] += t * step
            r_new = residuals(trial.reshape(n, 2))
            cost_new = 0.5 * float(r_new @ r_new)
            if np.isfinite(cost_new) and cost_new < cost:
                accepted = True
                break
            t *= 0.5
        if not accepted:
            message, converged = "no step lowers the energy any more (converged to round-off)", True
            break
        drop = cost - cost_new
        z, r = trial, r_new
        cost_prev, cost = cost, cost_new
        if np.max(np.abs(r)) <= ROUNDOFF:
            message, converged = "every residual at round-off", True
            break
        if drop <= max(tol * cost_prev, noise_floor):
            message, converged = "energy no longer decreases", True
            break
    if not np.all(np.isfinite(z)):
        raise FloatingPointError("the spring solver diverged (non-finite coordinates)")
    return z.reshape(n, 2), {"iterations": it, "converged": converged, "message": message,
                             "energy": cost}
