"""Rigid-origami kinematics with fold angles as the state (Tachi 2009, paper §3.6).

Loop closure at an interior vertex v: walking around v through its faces f_0, f_1, ..., f_{n-1},
f_n = f_0, each step rotates by the fold angle rho_k about the crease e_k between f_k and f_{k+1}.
All rotations are about lines through v in the flat crease pattern, so closure is

    P_v(rho) = R(a_0, rho_0) R(a_1, rho_1) ... R(a_{n-1}, rho_{n-1}) = I,

with a_k = sigma_k * (unit flat direction lo->hi of e_k), sigma_k = +1 when f_{k+1} is the edge's
left face (this makes valley positive, like `fabkit.measures.dihedral_angles`). The residual is
r_v = rotvec(P_v) (3 numbers, radians). Its derivative: dP/drho_k = [omega_k]x P with
omega_k = (R_0 ... R_{k-1}) a_k, the crease direction in f_0's frame; at P = I that is the exact
Jacobian of r (Tachi's direction-cosine rows), and away from it an O(|r|) approximation, so Newton
still converges fast once close.

The update is Tachi's `d_rho = -C^+ r + (I - C^+ C) d_rho0` over the free angles (the driven
angles are set, not solved for), computed as `d_rho0 + argmin |x| s.t. C x = -r - C d_rho0`. The
refold driver applies it in two halves: `d_rho0` moves every angle onto the reference path (the
driven angles exactly, the free ones to the same fraction of their targets) and the Newton
corrections `-C^+ r` (d_rho0 = 0) bring the state back onto the constraint manifold with the least
change. Keeping `d_rho0 = rho_ref - rho` in every step (`pull_steps`) gives the nearest point of the
manifold instead, but converges only linearly (30+ steps where the Newton corrections take 3-4 on a
two-crease panel).

Minimum-norm solves: a sparse factorisation of `C C^T` (default), scipy's LSMR, or a dense
pseudo-inverse (the baseline); see `MinNormSolver`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from fabkit.mesh import MeshTopology

__all__ = ["VertexLoops", "build_vertex_loops", "loop_closure", "NewtonResult", "project_to_constraints",
           "SOLVERS"]

SOLVERS = ("direct", "lsmr", "dense")
#: Chord steps (reusing a state's factorisation) continue while each shrinks the residual by at least
#: CHORD_FAST, or by at least CHORD_SLOW if at that rate tol is reached within CHORD_STEPS more steps.
#: A chord step costs about a tenth of a refactorising step on the 2,500-vertex bench panel
#: (1.8 ms vs 28 ms), so ~10 slow chord steps are cheaper than a refactorisation.
CHORD_FAST, CHORD_SLOW, CHORD_STEPS = 0.3, 0.7, 10


@dataclass(frozen=True)
class VertexLoops:
    """Interior vertices' face cycles, padded to the largest valence.

    `vertices` (nv,) interior vertex ids; `edge` (nv, k) hinge edge of each step (-1 = padding);
    `axis` (nv, k, 3) signed unit axis a_k in the flat pattern (0 for padding); `n_edges` E.
    """

    vertices: np.ndarray
    edge: np.ndarray
    axis: np.ndarray
    n_edges: int

    def __post_init__(self):
        # step-major copies for `loop_closure`: contiguous (3, k, nv) axes, (k, nv) edge ids and padding
        object.__setattr__(self, "_axis_t", np.ascontiguousarray(self.axis.transpose(2, 1, 0)))
        object.__setattr__(self, "_edge_t", np.ascontiguousarray(np.maximum(self.edge, 0).T))
        pad = np.ascontiguousarray((self.edge < 0).T)
        object.__setattr__(self, "_pad_t", pad if pad.any() else None)

    @property
    def n_loops(self) -> int:
        return len(self.vertices)


def build_vertex_loops(topology: MeshTopology, flat_vertices: np.ndarray) -> VertexLoops:
    """Cycle of faces and hinges around every interior vertex of a triangle mesh (vectorised)."""
    t = topology
    V = np.asarray(flat_vertices, np.float64)
    interior = np.flatnonzero(t.interior_vertex_mask)
    corners, offsets = t.vertex_corners
    valence = (offsets[1:] - offsets[:-1])[interior]
    kmax = int(valence.max()) if len(interior) else 0
    edge = np.full((len(interior), kmax), -1, np.int64)
    axis = np.zeros((len(interior), kmax, 3))
    c = corners[offsets[interior]]  # any corner at v starts the walk
    E = t.edges
    d = V[E[:, 1]] - V[E[:, 0]]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for k in range(kmax):
        live = k < valence
        p = t.corner_prev[c]  # half-edge (prev -> v) of f_k; its twin starts the next face at v
        e = t.halfedge_edge[p]
        nxt = t.halfedge_twin[p]
        if np.any(live & (nxt < 0)):
            raise ValueError("interior vertex walk reached the boundary (mesh topology is inconsistent)")
        f_next = t.corner_face[np.maximum(nxt, 0)]
        sigma = np.where(t.edge_faces[e, 0] == f_next, 1.0, -1.0)
        edge[live, k] = e[live]
        axis[live, k] = sigma[live, None] * d[e[live]]
        c = np.where(live, nxt, c)
    return VertexLoops(vertices=interior, edge=edge, axis=axis, n_edges=t.n_edges)


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of scalar-last quaternions (..., 4), scipy's convention."""
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n, 3) arrays (np.cross has a large per-call overhead)."""
    out = np.empty_like(b)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _qrotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (n, 3) by unit quaternions q (n, 4): v + 2w (u x v) + 2 u x (u x v)."""
    u, w = q[:, :3], q[:, 3:4]
    t = 2.0 * _cross(u, v)
    return v + w * t + _cross(u, t)


def loop_closure(loops: VertexLoops, rho: np.ndarray, *, jacobian: bool = True):
    """Residual `r` (nv, 3) = rotvec(P_v) and, if asked, the crease directions `omega` (nv, k, 3).

    `omega[i, k]` is the Jacobian entry d r_i / d rho_{edge[i, k]} (see the module docstring).
    Quaternion products, exp and log maps are written out in numpy on one contiguous array per
    component (the same arithmetic as `_qmul`/`_qrotate`; scipy's Rotation gives the same numbers,
    checked in the tests, but its per-call overhead dominated the solve, and the component-major
    layout is 2x faster than (nv, 4) rows).
    """
    nv, kmax = loops.edge.shape
    if nv == 0:
        return np.zeros((0, 3)), np.zeros((0, kmax, 3))
    ax = loops._axis_t                                  # (3, k, nv)
    half = np.asarray(rho)[loops._edge_t] * 0.5         # (k, nv)
    if loops._pad_t is not None:
        half[loops._pad_t] = 0.0
    sin, cos = np.sin(half), np.cos(half)
    bx, by, bz = ax[0] * sin, ax[1] * sin, ax[2] * sin  # exp map of every step (axis unit, or 0 for padding)
    omega = np.empty((nv, kmax, 3)) if jacobian else None
    if jacobian:
        omega[:, 0] = ax[:, 0].T
    x, y, z, w = bx[0], by[0], bz[0], cos[0]            # the identity times step 0
    for k in range(1, kmax):
        if jacobian:  # omega_k = acc rotating a_k: v + 2w (u x v) + u x (2 u x v)
            vx, vy, vz = ax[0, k], ax[1, k], ax[2, k]
            tx, ty, tz = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz), 2.0 * (x * vy - y * vx)
            omega[:, k, 0] = vx + w * tx + (y * tz - z * ty)
            omega[:, k, 1] = vy + w * ty + (z * tx - x * tz)
            omega[:, k, 2] = vz + w * tz + (x * ty - y * tx)
        qx, qy, qz, qw = bx[k], by[k], bz[k], cos[k]
        x, y, z, w = (w * qx + x * qw + y * qz - z * qy,
                      w * qy - x * qz + y * qw + z * qx,
                      w * qz + x * qy - y * qx + z * qw,
                      w * qw - x * qx - y * qy - z * qz)
    # log map (scipy's as_rotvec, written out to skip its per-call overhead): angle = 2 atan2(|u|, w)
    sign = np.where(w < 0, -1.0, 1.0)
    x, y, z, w = x * sign, y * sign, z * sign, w * sign
    s = np.sqrt(x * x + y * y + z * z)
    angle = 2.0 * np.arctan2(s, w)
    small = s < 1e-8
    scale = np.where(small, 2.0 / np.maximum(w, 1e-300) * (1.0 + s * s / 6.0), angle / np.where(small, 1.0, s))
    return np.stack([x * scale, y * scale, z * scale], axis=1), omega


@dataclass(frozen=True)
class NewtonResult:
    rho: np.ndarray          # all hinge angles (E,), radians
    residual: float          # max |rotvec(P_v)| component over interior vertices, radians
    iterations: int          # Newton steps taken
    converged: bool
    factorizations: int      # linear solves that factorised (direct) or pseudo-inverted (dense)


class JacobianPattern:
    """Sparse structure of C restricted to the free hinges, built once; `matrix(omega)` fills it."""

    def __init__(self, loops: VertexLoops, free_edges: np.ndarray):
        col_of_edge = np.full(loops.n_edges, -1, np.int64)
        col_of_edge[free_edges] = np.arange(len(free_edges))
        cols = np.where(loops.edge >= 0, col_of_edge[np.maximum(loops.edge, 0)], -1)
        self.mask = cols >= 0                      # (nv, k) slots that are free hinges
        self.free_edges = np.asarray(free_edges, np.int64)
        nv = loops.n_loops
        vi = np.broadcast_to(np.arange(nv)[:, None], cols.shape)[self.mask]
        rows = (3 * vi[:, None] + np.arange(3)).ravel()
        cc = np.repeat(cols[self.mask], 3)
        self.shape = (3 * nv, len(free_edges))
        # each (row, column) pair occurs once, so the CSR data is a permutation of omega[mask]
        order = sp.csr_matrix((np.arange(1, len(rows) + 1, dtype=np.float64), (rows, cc)), shape=self.shape)
        self._perm = order.data.astype(np.int64) - 1
        self._indices, self._indptr = order.indices.copy(), order.indptr.copy()

    def matrix(self, omega: np.ndarray) -> sp.csr_matrix:
        data = omega[self.mask].ravel()[self._perm]
        return sp.csr_matrix((data, self._indices, self._indptr), shape=self.shape)


class MinNormSolver:
    """argmin |x| subject to C x = b (least squares if inconsistent), by one of three methods.

    "direct": x = C^T y with (C C^T + mu I) y = b, a sparse LU of C C^T (SuperLU in symmetric mode
    with a minimum-degree ordering); mu = 1e-13 * max diag only guards the rank deficiency of the
    flat state. When C has more rows than columns (planar quads held flat, see `RefoldSolver`) the
    smaller (C^T C + mu I) x = C^T b is factorised instead: the same pseudo-inverse solution. `solve(C, b, reuse=True)` uses the last factorised C and its LU instead (the chord
    step of `project_to_constraints`: an exact right inverse of that C). "lsmr": scipy's LSMR from x0 = 0 (its iterates stay
    in the row space of C, so it returns the minimum-norm solution); exact but slow on large panels
    for the same conditioning reason. "dense": numpy's pinv, the baseline.
    """

    def __init__(self, method: str = "direct", tol: float = 1e-15):
        if method not in SOLVERS:
            raise ValueError(f"unknown solver {method!r} ({', '.join(SOLVERS)})")
        self.method, self.tol = method, tol
        self.factorizations = 0
        self.inner_iterations = 0   # LSMR iterations
        self._kept = None           # (C, LU) of the last direct factorisation

    def solve(self, C: sp.csr_matrix | None, b: np.ndarray, reuse: bool = False) -> np.ndarray:
        """Minimum-norm x with C x = b; `reuse=True` (direct only) uses the last factorised C instead."""
        if reuse:
            if self.method != "direct" or self._kept is None:
                raise ValueError("no kept factorisation to reuse")
            C0, lu, tall = self._kept
            return lu.solve(C0.T @ b) if tall else C0.T @ lu.solve(b)
        if C.shape[1] == 0:
            return np.zeros(0)
        if self.method == "lsmr":
            out = spla.lsmr(C, b, atol=self.tol, btol=self.tol, maxiter=20 * max(C.shape))
            self.inner_iterations += int(out[2])
            return out[0]
        self.factorizations += 1
        if self.method == "dense":
            return np.linalg.pinv(C.toarray(), rcond=1e-12) @ b
        tall = C.shape[0] > C.shape[1]  # more equations than unknowns: the smaller normal matrix is C^T C
        N = ((C.T @ C) if tall else (C @ C.T)).tocsc()
        scale = float(N.diagonal().max()) if N.nnz else 1.0
        N = N + sp.identity(N.shape[0], format="csc") * (1e-13 * max(scale, 1e-300))
        lu = spla.splu(N, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
        self._kept = (C, lu, tall)
        return lu.solve(C.T @ b) if tall else C.T @ lu.solve(b)


def _chord_stalls(res: float, prev: float, tol: float) -> bool:
    """Refactorise after a chord step that took the residual from `prev` to `res`?"""
    if not res > CHORD_FAST * prev:
        return False
    if not res <= CHORD_SLOW * prev or res <= 0.0:
        return True
    return np.log(tol / res) / np.log(res / prev) > CHORD_STEPS


def project_to_constraints(loops: VertexLoops, rho_start: np.ndarray, rho_ref: np.ndarray,
                           pattern: JacobianPattern, solver: MinNormSolver, *,
                           tol: float = 1e-12, max_iter: int = 30, pull_steps: int = 0,
                           chord: bool = False) -> NewtonResult:
    """Newton iteration onto the loop-closure manifold with the driven angles held fixed.

    Free angles (`pattern.free_edges`) start at `rho_start`; the others are `rho_ref` throughout.
    Each step is Tachi's update `d = -C^+ r + (I - C^+ C) d0` over the free angles. The first
    `pull_steps` steps use `d0 = rho_ref - rho` (move toward the reference angles along the
    constraint tangent space while fixing the residual); the rest use `d0 = 0`, the minimum-norm
    Newton correction back onto the manifold. With `chord`, every correction after the first reuses the
    last factorisation while it contracts fast enough (`CHORD_FAST`, `CHORD_SLOW`), then
    refactorise (a Newton-chord method: ~4x fewer factorisations on large panels). Which points
    are factorised depends only on the start, so the result is still a function of the inputs
    alone. Converged when max |r| <= tol after the pull steps.
    """
    free = pattern.free_edges
    rho = np.array(rho_ref, dtype=np.float64, copy=True)
    rho[free] = rho_start[free]
    f0 = solver.factorizations

    def evaluate(x, jac):
        r, omega = loop_closure(loops, x, jacobian=jac)
        return r, omega, (float(np.abs(r).max()) if len(r) else 0.0)

    def done(ok, res, its):
        return NewtonResult(rho, res, its, ok, solver.factorizations - f0)

    chord = chord and solver.method == "direct"
    r, omega, res = evaluate(rho, True)
    if not np.isfinite(res):
        return done(False, float("nan"), 0)
    if len(free) == 0:  # every hinge is held: nothing to solve for
        return done(res <= tol, res, 0)
    its = 0
    refresh = False
    while True:
        d0 = rho_ref[free] - rho[free] if its < pull_steps else None
        if d0 is not None and float(np.abs(d0).max(initial=0.0)) <= tol:
            d0 = None
        if res <= tol and d0 is None:
            return done(True, res, its)
        if its >= max_iter:
            return done(False, res, its)
        its += 1
        b = -r.ravel()
        reuse = chord and its > 1 and not refresh and d0 is None
        if reuse:  # chord step: the kept C and its factorisation, no new Jacobian needed
            step = solver.solve(None, b, reuse=True)
        else:
            if omega is None:
                _, omega = loop_closure(loops, rho)
            C = pattern.matrix(omega)
            step = solver.solve(C, b) if d0 is None else d0 + solver.solve(C, b - C @ d0)
        if not np.all(np.isfinite(step)):
            return done(False, float("nan"), its)
        rho[free] += step
        prev = res
        r, omega, res = evaluate(rho, not chord)
        refresh = reuse and _chord_stalls(res, prev, tol)
        if not np.isfinite(res) or res > 1e3 * max(prev, tol):
            return done(False, res if np.isfinite(res) else float("nan"), its)  # diverging
