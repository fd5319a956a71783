"""The reusable relaxation solver: set up once per mesh (masks, boundary row, sparsity), solve many times."""
from __future__ import annotations

import dataclasses
import time
from functools import cached_property

import numpy as np

from fabkit import measures
from fabkit.errors import InputError
from fabkit.mesh import PolyMesh
from fabkit.relax.boundary import ROW_KINDS, ExtendedMesh, add_boundary_row
from fabkit.relax.dynamic import PhaseOutcome, dynamic_relaxation
from fabkit.relax.energy import EnergyModel, Evaluation
from fabkit.relax.lbfgs import lbfgs
from fabkit.relax.newton import gauss_newton
from fabkit.relax.options import IterationRecord, RelaxOptions, RelaxResult, fixed_mask_from


def check_relaxable(mesh: PolyMesh, source: str | None = None) -> None:
    """Raise `InputError` (one line) for a mesh relaxation cannot work on."""
    V = mesh.vertices
    if not np.all(np.isfinite(V)):
        v = int(np.flatnonzero(~np.all(np.isfinite(V), axis=1))[0])
        raise InputError(f"vertex {v} has a non-finite coordinate", source=source)
    if mesh.n_faces < 2:
        raise InputError(f"the mesh has {mesh.n_faces} face: nothing to relax (a panel needs faces around "
                         "at least one interior vertex)", source=source)
    if not mesh.interior_vertex_mask.any():
        raise InputError(f"the mesh has no interior vertex ({mesh.n_faces} faces): there is no angle defect "
                         "to relax", source=source)
    if np.any(mesh.edge_lengths <= 0):
        e = int(np.flatnonzero(mesh.edge_lengths <= 0)[0])
        raise InputError(f"edge {mesh.edges[e].tolist()} has zero length", source=source)


class Relaxer:
    """Relaxation set up for one mesh and one set of options.

    `Relaxer(mesh, options, fixed=None)` validates the mesh, builds the problem (boundary row, fixed and
    free vertices, energy model and Jacobian pattern); `solve(X0=None)` relaxes from the mesh's own
    positions or from X0 (same vertex order) and returns a `RelaxResult`; `evaluate(X)` measures.
    """

    def __init__(self, mesh: PolyMesh, options: RelaxOptions | None = None, *, fixed=None,
                 source: str | None = None, **overrides):
        options = options or RelaxOptions()
        if overrides:
            options = dataclasses.replace(options, **overrides)
        check_relaxable(mesh, source)
        self.mesh = mesh
        self.options = options
        try:
            fixed_mask = fixed_mask_from(mesh, options.fixed) | fixed_mask_from(mesh, fixed)
        except ValueError as exc:
            raise InputError(str(exc), source=source) from None
        self.fixed_mask = fixed_mask
        self.length_scale = float(mesh.edge_lengths.mean())
        t = mesh.topology
        self.extended: ExtendedMesh | None = None
        if options.boundary in ROW_KINDS:
            self.extended = add_boundary_row(mesh, options.boundary, options.row_width)
            pmesh = self.extended.mesh
            row = self.extended.row_vertex_mask
            fixed_all = np.concatenate([fixed_mask, np.zeros(pmesh.n_vertices - mesh.n_vertices, bool)])
            free = pmesh.topology.used_vertex_mask & ~row & ~fixed_all
            defect = pmesh.interior_vertex_mask.copy()
            # the row only steers the angle sums; its own faces need not be planar (they are removed)
            plan = np.arange(pmesh.n_faces) < mesh.n_faces
        else:
            plan = None
            pmesh = mesh
            free = t.used_vertex_mask & ~fixed_mask
            if options.boundary == "fixed":
                free &= ~t.boundary_vertex_mask
            defect = t.interior_vertex_mask.copy()
        if not free.any():
            raise InputError("every vertex is fixed: nothing can move", source=source)
        edge_pairs, edge_rest = None, None
        if options.edge_lengths:
            ids = np.array([e for e, _ in options.edge_lengths], dtype=np.int64)
            edge_rest = np.array([length for _, length in options.edge_lengths])
            if ids.max() >= mesh.n_edges:
                raise InputError(f"edge_lengths: edge {int(ids.max())} does not exist (edges are "
                                 f"0..{mesh.n_edges - 1})", source=source)
            edge_pairs = mesh.edges[ids]   # original vertex ids are kept in the extended mesh
        self.edge_ids = None if edge_pairs is None else ids
        self.problem_mesh = pmesh
        self.x_ref = np.array(pmesh.vertices)
        self.model = EnergyModel(pmesh.topology, defect_mask=defect, free_mask=free,
                                 planarity_weight=options.planarity_weight, plane_method=options.plane_method,
                                 length_scale=self.length_scale, closeness_weight=options.closeness,
                                 x_ref=self.x_ref, planarity_mask=plan, edge_pairs=edge_pairs,
                                 edge_rest=edge_rest, edge_weight=options.edge_length_weight)

    # ------------------------------------------------------------------------------------------
    def _problem_positions(self, X0) -> np.ndarray:
        if X0 is None:
            return np.array(self.problem_mesh.vertices)
        X0 = np.asarray(X0, dtype=np.float64)
        if X0.shape != self.mesh.vertices.shape:
            raise InputError(f"start positions have shape {X0.shape}, expected {self.mesh.vertices.shape}")
        if not np.all(np.isfinite(X0)):
            raise InputError("start positions contain NaN or Inf")
        if self.extended is None:
            return X0.copy()
        X = np.array(self.problem_mesh.vertices)
        X[:self.mesh.n_vertices] = X0
        return X

    def evaluate(self, X: np.ndarray | None = None) -> Evaluation:
        """Energy and measures of the relaxation problem at X (original vertex order) or the input."""
        return self.model.evaluate(self._problem_positions(X))

    def _done(self, ev: Evaluation) -> bool:
        o = self.options
        return (ev.finite and ev.max_defect <= o.tol_defect and ev.max_planarity <= o.tol_planarity
                and ev.force_residual <= o.tol_force and ev.max_edge_length <= o.tol_edge_length)

    def solve(self, X0: np.ndarray | None = None) -> RelaxResult:
        o = self.options
        t0 = time.perf_counter()
        deadline = None if o.max_seconds is None else t0 + o.max_seconds
        X = self._problem_positions(X0)
        X_start = X.copy()
        history: list[IterationRecord] = []
        counts: dict[str, int] = {}

        def record(phase: str, ev: Evaluation, ke: float) -> None:
            counts[phase] = counts.get(phase, 0) + 1
            history.append(IterationRecord(phase, len(history) + 1, ev.max_defect, ev.mean_defect,
                                           ev.max_planarity, ev.mean_planarity, float(ke), float(ev.energy),
                                           ev.max_edge_length))

        def finish_switch(ev: Evaluation) -> bool:
            return ev.max_defect <= o.finish_below and ev.max_planarity <= o.finish_below

        statuses: list[str] = []
        ev0 = self.model.evaluate(X)
        if not ev0.finite:
            raise InputError("the energy of the input is not finite (degenerate faces?)")
        out: PhaseOutcome = PhaseOutcome(X, ev0, 0, "converged" if self._done(ev0) else "start")
        fair_done = False
        if out.status != "converged":
            budget = int(o.max_iter)
            if o.method in ("dr", "lbfgs") and o.stage:
                stage1 = dynamic_relaxation(self.model, X, max_iter=budget, done=lambda ev: False,
                                            switch=lambda ev: ev.max_defect <= o.stage_defect,
                                            damping=o.damping, planarity_weight=0.0, record=record,
                                            phase="dr-stage1", deadline=deadline)
                statuses.append(f"stage 1 {stage1.status}")
                budget = max(budget - stage1.iterations, 0)
                if stage1.status != "diverged":
                    X = stage1.X
            switch = finish_switch if o.finish else None
            if o.method == "dr":
                out = dynamic_relaxation(self.model, X, max_iter=budget, done=self._done, switch=switch,
                                         damping=o.damping, record=record, deadline=deadline)
                statuses.append(f"DR {out.status}")
            elif o.method == "lbfgs":
                out = lbfgs(self.model, X, max_iter=budget, done=self._done, switch=switch, record=record,
                            deadline=deadline)
                statuses.append(f"L-BFGS {out.status}")
            if o.method == "newton" and self._fairing_possible():
                # Gauss–Newton only to the hand-over point, then fairing (as after DR)
                first = gauss_newton(self.model, X, max_iter=int(o.newton_max_iter), done=finish_switch,
                                     record=record, deadline=deadline)
                statuses.append(f"Newton to the hand-over {first.status}")
                if first.status == "converged" and first.evaluation.finite:
                    out = PhaseOutcome(first.X, first.evaluation, first.iterations, "switch")
            if out.status == "switch" and self._fairing_possible():
                # fairing straight from the hand-over: its steps also close the residuals, so the
                # Gauss–Newton finish runs once, after it (measured 2x faster than fairing after it)
                faired = self._fair(out, record, deadline, statuses)
                if faired is not None:
                    out, fair_done = faired, True
            if not fair_done and (o.method == "newton" or (o.finish and out.status in ("switch", "stalled",
                                                                                         "max_iter"))):
                # Newton from the start restarts from the input unless it already reached the hand-over
                from_input = (o.method == "newton" and out.status != "switch") or out.status == "diverged"
                nt = self._newton(X if from_input else out.X, record, deadline, near=not from_input)
                statuses.append(f"Newton {nt.status}")
                out = self._better(out, nt)
            if o.fallback and not self._done(out.evaluation) and out.status != "timeout":
                # the first route went astray (fold-over, stall): try the other one from the input
                if o.method == "newton":
                    alt = dynamic_relaxation(self.model, X, max_iter=int(o.max_iter), done=self._done,
                                             switch=finish_switch, damping=o.damping, record=record,
                                             deadline=deadline)
                    statuses.append(f"fallback DR {alt.status}")
                    if alt.status in ("switch", "stalled", "max_iter"):
                        alt = self._newton(alt.X, record, deadline, near=True)
                        statuses.append(f"Newton {alt.status}")
                else:
                    alt = self._newton(X, record, deadline)
                    statuses.append(f"fallback Newton from the input {alt.status}")
                out = self._better(out, alt)
        if o.crease_fairness > 0 and not fair_done and self._done(out.evaluation) and not self._done(ev0):
            if not self._fairing_possible():
                statuses.append("crease fairing skipped: no crease to fair")
            else:
                faired = self._fair(out, record, deadline, statuses)
                if faired is None:
                    statuses.append("faired panel missed the tolerances: kept the unfaired result")
                else:
                    out = faired
        if not self._done(out.evaluation) and not (out.evaluation.energy <= ev0.energy):
            # every route ended worse than where it started: never hand back a panel worse than the input
            statuses.append("every route ended above the input's energy: returned the input positions")
            out = PhaseOutcome(X_start, ev0, out.iterations, "diverged")
        return self._result(out, history, counts, statuses, time.perf_counter() - t0)

    def _newton(self, X: np.ndarray, record, deadline, near: bool = False) -> PhaseOutcome:
        """Gauss–Newton from X; `near`: X comes from DR / L-BFGS (more second-order corrections pay)."""
        o = self.options
        return gauss_newton(self.model, X, max_iter=int(o.newton_max_iter), done=self._done, x_ref=self.x_ref,
                            closeness=o.closeness, record=record, deadline=deadline, corrections=4 if near else 1)

    @cached_property
    def fairness_operator(self):
        """The crease chains' third differences (sparse, over the problem's coordinates), built the
        first time fairing may run: a panel already within tolerance never needs the chains (nor
        scipy.sparse and the panel structure). None without crease fairing."""
        if self.options.crease_fairness <= 0:
            return None
        import scipy.sparse as sp

        from fabkit.relax.fairing import crease_chains, third_differences

        mesh = self.mesh
        D = third_differences(crease_chains(mesh), mesh.n_vertices, mesh.vertices)
        pad = self.problem_mesh.n_vertices - mesh.n_vertices   # boundary-row vertices come after the mesh's own
        return sp.hstack([D, sp.csr_matrix((D.shape[0], pad))], format="csr") if pad else D

    def _fairing_possible(self) -> bool:
        D = self.fairness_operator
        return self.options.crease_fairness > 0 and D is not None and D.shape[0] > 0

    def _fair(self, out: PhaseOutcome, record, deadline, statuses: list[str]) -> PhaseOutcome | None:
        """Crease fairing from `out`, then the Gauss–Newton finish if needed; None unless it converges."""
        from fabkit.relax.fairing import fair_creases

        fair = fair_creases(self.model, out.X, self.x_ref, self.fairness_operator, self.options.crease_fairness,
                            done=self._done, record=record, deadline=deadline)
        statuses.append(f"crease fairing {fair.status} ({fair.iterations} steps)")
        if not self._done(fair.evaluation) and fair.evaluation.finite:
            fair = self._newton(fair.X, record, deadline, near=True)
            statuses.append(f"Newton {fair.status}")
        if self._done(fair.evaluation):
            return PhaseOutcome(fair.X, fair.evaluation, out.iterations + fair.iterations, "converged")
        return None

    def _better(self, a: PhaseOutcome, b: PhaseOutcome) -> PhaseOutcome:
        """The converged one, else the finite one with the lower energy (a: the earlier outcome)."""
        if not b.evaluation.finite:
            return a
        if a.status == "start" or not a.evaluation.finite:
            return b
        if self._done(b.evaluation) != self._done(a.evaluation):
            return b if self._done(b.evaluation) else a
        return b if b.evaluation.energy <= a.evaluation.energy else a

    # ------------------------------------------------------------------------------------------
    def _result(self, out: PhaseOutcome, history, counts, statuses, seconds) -> RelaxResult:
        o = self.options
        X = out.X
        if not np.all(np.isfinite(X)):  # never hand back NaN: fall back to the input
            X = np.array(self.problem_mesh.vertices)
            out = PhaseOutcome(X, self.model.evaluate(X), out.iterations, "diverged")
        Xo = X[:self.mesh.n_vertices]
        mesh = self.mesh.with_vertices(Xo)
        vdef = measures.angle_defect(mesh)
        fplan = measures.face_planarity(mesh, o.plane_method)
        disp = np.linalg.norm(Xo - self.mesh.vertices, axis=1)
        ev = out.evaluation
        converged = self._done(ev)
        # independent check on the output mesh with the shared measures
        interior = np.abs(vdef[mesh.interior_vertex_mask])
        out_def = float(interior.max()) if len(interior) else 0.0
        out_plan = float(fplan.max()) if len(fplan) else 0.0
        out_edge = 0.0
        if self.edge_ids is not None:
            rest = np.array([length for _, length in o.edge_lengths])
            out_edge = float(np.abs(mesh.edge_lengths[self.edge_ids] / rest - 1.0).max())
        if converged and (out_def > o.tol_defect or out_plan > o.tol_planarity or out_edge > o.tol_edge_length):
            converged = False
        n_it = len(history)
        phases = ", ".join(statuses) if statuses else "input already within tolerance"
        measures_txt = (f"max |angle defect| {ev.max_defect:.3g} rad (tol {o.tol_defect:g}), max planarity "
                        f"{ev.max_planarity:.3g} (tol {o.tol_planarity:g}), force {ev.force_residual:.3g} "
                        f"(tol {o.tol_force:g})")
        if self.edge_ids is not None:
            measures_txt += (f", max edge-length error {out_edge:.3g} over {len(self.edge_ids)} kept edges "
                             f"(tol {o.tol_edge_length:g})")
        if converged:
            message = f"converged after {n_it} iterations ({phases}): {measures_txt}"
        else:
            message = f"did not converge after {n_it} iterations ({phases}): {measures_txt}"
            if self.extended is not None:
                message += (f"; the fixed boundary row ({o.boundary}) also asks angle sum 2π at every boundary "
                            "vertex, which this panel could not meet (on the tri-fold with 2 or 4 rows per strip "
                            "most row options stall while --boundary free converges; try free or another "
                            "--row-width)")
            elif o.boundary == "fixed":
                message += ("; a fixed boundary keeps every boundary vertex where the input has it, which may leave "
                            "no developable panel in reach (on the tri-fold with 4 rows per strip it does; "
                            "--boundary free converges there)")
        return RelaxResult(
            mesh=mesh, converged=converged, message=message, method=o.method, iterations=n_it,
            phase_iterations=dict(counts), max_defect=ev.max_defect, mean_defect=ev.mean_defect,
            max_planarity=ev.max_planarity, mean_planarity=ev.mean_planarity, force_residual=ev.force_residual,
            max_displacement=float(disp.max()) if len(disp) else 0.0,
            mean_displacement=float(disp[self.mesh.topology.used_vertex_mask].mean()) if len(disp) else 0.0,
            vertex_defect=vdef, face_planarity=fplan, vertex_displacement=disp, history=tuple(history),
            seconds=float(seconds), options=o, max_edge_length_error=out_edge)


def relax(mesh: PolyMesh, options: RelaxOptions | None = None, *, fixed=None, **overrides) -> RelaxResult:
    """One-shot relaxation: `Relaxer(mesh, options, fixed=fixed, **overrides).solve()`."""
    return Relaxer(mesh, options, fixed=fixed, **overrides).solve()
