"""Refold: the sequence of rigid fold states that takes a flat pattern to its 3D target (paper §3.6).

`RefoldSolver(flat, target)` sets up once (triangulation, vertex loops, face tree, Jacobian
pattern, target angles); `solver.solve(...)` runs a schedule. `refold(flat, target, **options)`
does both. The maths is in `kinematics` (loop closure, Newton projection) and `geometry`
(positions from angles); `intersect` checks that faces do not pass through each other.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from fabkit.errors import InputError
from fabkit.measures import dihedral_angles
from fabkit.mesh import PolyMesh
from fabkit.refold.geometry import build_face_tree, corner_mismatch, face_transforms, vertex_positions
from fabkit.refold.intersect import intersecting_pairs, neighbour_keys
from fabkit.refold.kinematics import (SOLVERS, JacobianPattern, MinNormSolver, NewtonResult, build_vertex_loops,
                                      loop_closure, project_to_constraints)
from fabkit.refold.sequence import (FoldSequence, build_schedule, edge_kind_names, middle_row_hinges,
                                    parse_steps)
from fabkit.refold.triangulate import BOUNDARY, CREASE, DIAGONAL, RULING, TriangulatedPanel, triangulate_panel
from fabkit.refold.validate import NotAFoldError, check_flat, check_is_fold, check_pair
from fabkit.structure import FLAT_ANGLE, PanelStructure, pair_structure

__all__ = ["RefoldSolver", "refold", "FoldSequence", "NotAFoldError", "SOLVERS", "DEFAULT_LENGTH_RTOL"]

#: Largest relative edge-length difference between TARGET and FLAT accepted as "a fold of FLAT".
DEFAULT_LENGTH_RTOL = 1e-6
#: Newton stops when every vertex's loop-closure residual is below this [rad]. Positions are built along a
#: spanning tree, so residuals add up: on the 2,500-vertex bench panel 1e-12 left edge lengths 3.5e-10
#: relative (acceptance 1e-9), 1e-13 leaves 4e-11 for 0.4 more Newton-chord steps per state.
DEFAULT_TOL = 1e-13
#: Quads count as planar when every diagonal's target angle is below this [rad]; their diagonals are then
#: held at their scheduled angles (~0) instead of solved for.
PLANAR_QUAD_ANGLE = 1e-9


def wrap_angles(rho: np.ndarray) -> np.ndarray:
    """Angles in [-pi, pi] (a hinge turned by a whole turn is the same state; FOLD allows +-180 deg);
    angles already inside are returned bit for bit."""
    rho = np.asarray(rho, np.float64)
    return np.where(np.abs(rho) > np.pi, (rho + np.pi) % (2 * np.pi) - np.pi, rho)


class RefoldSolver:
    """Set up once for a FLAT/TARGET pair, then solve fold states for any schedule.

    flat: the crease pattern (z = 0, faces CCW from +z, tags strip/column/middle optional);
    target: the same panel folded (same vertices and faces). structure: the panel structure (default
    `fabkit.structure.pair_structure(flat, target)`: tags of either, the rest inferred from TARGET's
    geometry). fixed_face: polygon clamped at its flat position (default: the structure's clamp face,
    the middle-row face of the middle strip).
    length_rtol: refuse (NotAFoldError) when an edge length differs by more (relative).
    solver: "direct" (sparse factorisation), "lsmr" (sparse iterative) or "dense" (pinv baseline).
    tol: loop-closure residual [rad] Newton must reach; chord: reuse a state's factorisation while
    it contracts (False: factorise at every Newton step).
    hold_planar_quads: when every quad of TARGET is planar (diagonal angles <= PLANAR_QUAD_ANGLE), hold
    the diagonal hinges at their scheduled angles, so the quads stay planar in every state and Newton
    solves for the quad edges only (a 6,912 x 4,702 system instead of 6,912 x 7,103 on the bench panel:
    2.5x less time). A state where that has no solution is solved with the diagonals free (noted).
    """

    def __init__(self, flat: PolyMesh, target: PolyMesh, *, fixed_face: int | None = None,
                 diagonal: str = "short", length_rtol: float = DEFAULT_LENGTH_RTOL, solver: str = "direct",
                 tol: float = DEFAULT_TOL, max_iter: int = 30, chord: bool = True, hold_planar_quads: bool = True,
                 flat_name: str = "FLAT", target_name: str = "TARGET", structure: PanelStructure | None = None):
        if solver not in SOLVERS:
            raise ValueError(f"unknown solver {solver!r} ({', '.join(SOLVERS)})")
        check_pair(flat, target, flat_name, target_name)
        self.flat, self.target = flat, target
        self.structure = pair_structure(flat, target) if structure is None else structure
        self.panel: TriangulatedPanel = triangulate_panel(flat, diagonal, self.structure)
        check_flat(flat, self.panel.tris, flat_name)
        self.flat_vertices = np.array(flat.vertices)
        self.max_length_mismatch = check_is_fold(self.panel.topology, self.flat_vertices, np.asarray(target.vertices),
                                                 length_rtol, target_name)
        self.tol, self.max_iter = float(tol), int(max_iter)
        self.linear_solver = MinNormSolver(solver)
        self.chord = bool(chord)
        self.panel_size = flat.size
        self.loops = build_vertex_loops(self.panel.topology, self.flat_vertices)
        self.fixed_face = self._pick_fixed_face(fixed_face, flat_name)
        self.fixed_triangle = int(np.flatnonzero(self.panel.tri_face == self.fixed_face)[0])
        try:
            self.tree = build_face_tree(self.panel.topology, self.flat_vertices, self.fixed_triangle)
        except ValueError as exc:
            raise InputError(str(exc), source=flat_name) from None
        tmesh = PolyMesh(target.vertices, topology=self.panel.topology, validate=False)
        self.target_angles = dihedral_angles(tmesh)
        self.target_angles[~self.panel.hinge_mask] = 0.0
        self.flat_lengths = np.linalg.norm(self.flat_vertices[self.panel.edges[:, 1]]
                                           - self.flat_vertices[self.panel.edges[:, 0]], axis=1)
        self.hinges = np.flatnonzero(self.panel.hinge_mask)
        diagonals = np.flatnonzero(self.panel.edge_kind == DIAGONAL)
        planar = len(diagonals) > 0 and float(np.abs(self.target_angles[diagonals]).max()) <= PLANAR_QUAD_ANGLE
        self.held = diagonals if (hold_planar_quads and planar) else np.zeros(0, np.int64)
        self._patterns: dict[bytes, JacobianPattern] = {}
        self.neighbour_keys = neighbour_keys(self.panel.tris)  # triangle pairs that may touch (interpenetration check)

    # ---- set-up helpers --------------------------------------------------------------------
    def _pick_fixed_face(self, fixed_face: int | None, flat_name: str) -> int:
        F = self.flat.n_faces
        if fixed_face is not None:
            if not 0 <= int(fixed_face) < F:
                raise InputError(f"fixed face {fixed_face} does not exist (faces 0..{F - 1})", source="--fixed-face")
            return int(fixed_face)
        return int(self.structure.clamp_face)

    def driven_hinges(self, drive="middle-row") -> tuple[np.ndarray, list[str]]:
        """Hinge ids for `drive` ("middle-row", "all" or an array of hinge ids) and notes."""
        notes = []
        if isinstance(drive, str):
            if drive == "middle-row":
                d = middle_row_hinges(self.panel)
                if len(d) == 0:
                    raise InputError("the panel has no creases to drive: none tagged (face_data 'strip') and none "
                                     "found in TARGET's geometry; use a drive file", source="--drive")
                if self.structure.source.get("middle_row") == "inferred":
                    notes.append(f"driving the {len(d)} middle-column crease hinges found in TARGET's geometry "
                                 f"(creases {self.structure.source['creases']}, middle row inferred)")
                return d, notes
            if drive == "all":
                d = np.flatnonzero(self.panel.edge_kind == CREASE)
                if len(d) == 0:
                    raise InputError("the panel has no crease hinges to drive", source="--drive")
                return d, notes
            raise InputError(f"unknown drive {drive!r} (middle-row, all or a JSON file)", source="--drive")
        d = np.unique(np.asarray(drive, np.int64))
        if len(d) == 0 or d.min() < 0 or d.max() >= len(self.panel.edge_kind) or \
                np.any(self.panel.edge_kind[d] == BOUNDARY):
            raise InputError("driven edges must be interior hinge ids", source="--drive")
        return d, notes

    def pattern(self, driven: np.ndarray) -> JacobianPattern:
        key = np.asarray(driven, np.int64).tobytes()
        if key not in self._patterns:
            free = np.setdiff1d(self.hinges, driven)
            self._patterns[key] = JacobianPattern(self.loops, free)
        return self._patterns[key]

    # ---- one state -----------------------------------------------------------------------------
    def fold_state(self, rho_ref: np.ndarray, rho_start: np.ndarray, driven: np.ndarray,
                   hold: bool = True) -> NewtonResult:
        """Project the reference angles onto the rigid-fold manifold (driven hinges held at rho_ref;
        with `hold`, also the diagonals of planar quads, `self.held`)."""
        fixed = np.union1d(driven, self.held) if hold and len(self.held) else driven
        return project_to_constraints(self.loops, rho_start, rho_ref, self.pattern(fixed), self.linear_solver,
                                      tol=self.tol, max_iter=self.max_iter, chord=self.chord)

    def _advance(self, rho_prev, ref_prev, ref_next, driven):
        """Solve the next state: Newton from the reference angles (so the state depends on its fraction
        only, and the target state is the target); if the planar quads cannot stay planar, free their
        diagonals; if that fails too, continue from the previous state. -> (result, iterations, note)."""
        res = self.fold_state(ref_next, ref_next, driven)
        if res.converged:
            return res, res.iterations, None
        its = res.iterations
        if len(self.held):
            res = self.fold_state(ref_next, ref_next, driven, hold=False)
            its += res.iterations
            if res.converged:
                return res, its, "the quads could not stay planar; their diagonals were solved for"
        again = self.fold_state(ref_next, rho_prev + (ref_next - ref_prev), driven, hold=False)
        return again, its + again.iterations, ("Newton from the reference angles failed; continued from the "
                                               "previous state instead") if again.converged else None
    def positions(self, rho: np.ndarray):
        """(vertex positions (n, 3), face transforms) for hinge angles rho, in the panel frame."""
        tr = face_transforms(self.tree, rho)
        return vertex_positions(self.tree, self.flat_vertices, rho, tr), tr

    def diagnostics(self, rho: np.ndarray, V: np.ndarray, transforms) -> dict:
        r, _ = loop_closure(self.loops, rho, jacobian=False)
        E = self.panel.edges
        L = np.linalg.norm(V[E[:, 1]] - V[E[:, 0]], axis=1)
        return {
            "residual": float(np.linalg.norm(r, axis=1).max(initial=0.0)),
            "edge_length_error": float(np.max(np.abs(L - self.flat_lengths) / self.flat_lengths)),
            "corner_mismatch": corner_mismatch(self.panel.topology, self.flat_vertices, V, transforms),
        }

    def target_distance(self, V: np.ndarray) -> float:
        """Max distance [m] of V to the target after aligning the target's fixed face onto V's."""
        face = self.flat.face(self.fixed_face)
        T = np.asarray(self.target.vertices)
        a, b = V[face], T[face]
        ca, cb = a.mean(0), b.mean(0)
        R, _ = Rotation.align_vectors(a - ca, b - cb)
        aligned = R.apply(T - cb) + ca
        used = self.flat.topology.used_vertex_mask
        return float(np.linalg.norm(aligned[used] - V[used], axis=1).max())

    # ---- a whole schedule -------------------------------------------------------------------------
    def solve(self, fractions: np.ndarray, driven: np.ndarray, step_of_state: np.ndarray | None = None,
              check_intersections: bool = True, progress=None, notes=()) -> FoldSequence:
        """Fold states for a schedule of fractions (S, E); state 0 must be all zeros (flat)."""
        fractions = np.asarray(fractions, np.float64)
        S, E = fractions.shape
        if np.any(fractions[0] != 0.0):
            raise ValueError("the first state of a schedule must be flat (all fractions 0)")
        driven = np.asarray(driven, np.int64)
        ref = fractions * self.target_angles[None, :]
        angles = np.zeros((S, E))
        positions = np.zeros((S,) + self.flat_vertices.shape)
        resid = np.zeros(S)
        elen = np.zeros(S)
        cmis = np.zeros(S)
        its = np.zeros(S, np.int64)
        conv = np.ones(S, bool)
        inter = np.zeros(S, np.int64)
        rho = np.zeros(E)
        failed, failure = -1, ""
        for s in range(S):
            if s > 0:
                res, n_it, fallback = self._advance(angles[s - 1], ref[s - 1], ref[s], driven)
                if fallback:
                    notes = tuple(notes) + (f"state {s}: {fallback}",)
                if not res.converged:
                    failed, failure = s, self.describe_failure(res.rho, ref[s], s, S)
                    notes = tuple(notes) + (failure,)
                    keep = s  # only the converged states are kept
                    angles, positions, resid, elen, cmis, its, conv, inter = (
                        x[:keep] for x in (angles, positions, resid, elen, cmis, its, conv, inter))
                    fractions = fractions[:keep]
                    if step_of_state is not None:
                        step_of_state = step_of_state[:keep]
                    break
                rho = wrap_angles(res.rho)
                its[s] = n_it
                conv[s] = res.converged
            angles[s] = rho
            V, tr = self.positions(rho)
            positions[s] = V
            d = self.diagnostics(rho, V, tr)
            resid[s], elen[s], cmis[s] = d["residual"], d["edge_length_error"], d["corner_mismatch"]
            if check_intersections:
                inter[s] = len(intersecting_pairs(V, self.panel.tris, tol=1e-9 * self.panel_size,
                                                    neighbours=self.neighbour_keys))
            if progress is not None:
                progress(1)
        step = np.asarray(step_of_state if step_of_state is not None else
                          np.where(np.arange(len(angles)) == 0, -1, 0), np.int64)
        return FoldSequence(
            flat_vertices=self.flat_vertices, tris=self.panel.tris, tri_face=self.panel.tri_face,
            edges=np.array(self.panel.edges), edge_kind=edge_kind_names(self.panel),
            edges_assignment=self.assignment(angles), target_angles=self.target_angles, driven=driven,
            fixed_face=self.fixed_face, fixed_triangle=self.fixed_triangle, fractions=fractions, angles=angles,
            positions=positions, step=step, residual=resid, edge_length_error=elen, corner_mismatch=cmis,
            newton_iterations=its, converged=conv, intersections=inter,
            target_distance=self.target_distance(positions[-1]) if failed < 0 else float("nan"),
            panel_size=self.panel_size, face_data=self.triangle_face_data(),
            polygon_edge=np.array(self.panel.edge_poly_edge), edge_crease=np.array(self.panel.edge_crease),
            notes=tuple(notes), failed_state=failed, failure=failure)

    def describe_failure(self, rho: np.ndarray, rho_ref: np.ndarray, state: int, n_states: int) -> str:
        """One sentence on a state Newton could not reach: the vertex whose loop stays most open and,
        around it, the hinge farthest from its scheduled angle (the worst hinge)."""
        r, _ = loop_closure(self.loops, np.nan_to_num(rho, nan=0.0, posinf=0.0, neginf=0.0), jacobian=False)
        norm = np.linalg.norm(r, axis=1) if len(r) else np.zeros(0)
        where = ""
        if len(norm):
            k = int(np.argmax(np.nan_to_num(norm, nan=np.inf)))
            around = self.loops.edge[k][self.loops.edge[k] >= 0]
            dev = np.abs(np.nan_to_num(rho[around] - rho_ref[around], nan=np.inf))
            h = int(around[int(np.argmax(dev))])
            u, v = (int(x) for x in self.panel.edges[h])
            kind = edge_kind_names(self.panel)[h]
            where = (f" at vertex {int(self.loops.vertices[k])} (loop residual {norm[k]:.3g} rad); worst hinge "
                     f"({u}, {v}), a {kind}, at {np.degrees(rho[h]):.4g} deg where the schedule asks "
                     f"{np.degrees(rho_ref[h]):.4g} deg")
        return (f"Newton did not converge at state {state} of {n_states - 1}{where}; states 0..{state - 1} are kept, "
                "later states were not computed")

    def assignment(self, angles: np.ndarray) -> np.ndarray:
        """FOLD letters: B, J for diagonals, M/V by the target's sign (F when flat, U when a hinge
        changes sign during the sequence)."""
        k = self.panel.edge_kind
        t = self.target_angles
        out = np.full(len(k), "F", dtype="<U1")
        out[(t > FLAT_ANGLE) & ((k == CREASE) | (k == RULING))] = "V"
        out[(t < -FLAT_ANGLE) & ((k == CREASE) | (k == RULING))] = "M"
        slack = 1e-9
        flips = ((out == "V") & np.any(angles < -slack, axis=0)) | ((out == "M") & np.any(angles > slack, axis=0))
        out[flips] = "U"
        out[k == DIAGONAL] = "J"
        out[k == BOUNDARY] = "B"
        return out

    def triangle_face_data(self) -> dict:
        """Per triangle: its polygon and the structure's strip/column/middle tags (tagged or inferred),
        so the FOLD file carries the structure the toolpath needs."""
        fd = {"polygon": self.panel.tri_face.copy()}
        for name, arr in self.structure.face_data().items():
            fd[name] = np.asarray(arr)[self.panel.tri_face]
        return fd


def refold(flat: PolyMesh, target: PolyMesh, *, frames: int = 20, drive="middle-row", steps=None,
           fixed_face: int | None = None, diagonal: str = "short", length_rtol: float = DEFAULT_LENGTH_RTOL,
           solver: str = "direct", tol: float = DEFAULT_TOL, check_intersections: bool = True,
           progress=None) -> FoldSequence:
    """One-shot refold: `frames` states per step from flat (0) to target (1).

    drive: "middle-row" (paper default), "all" (every crease hinge) or an array of hinge ids.
    steps: None (one step), a string like "crease0,crease1", or a list of hinge-id arrays.
    """
    solver_ = RefoldSolver(flat, target, fixed_face=fixed_face, diagonal=diagonal, length_rtol=length_rtol,
                           solver=solver, tol=tol)
    driven, notes = solver_.driven_hinges(drive)
    if isinstance(steps, str):
        steps = parse_steps(steps, solver_.panel, driven)
    F, step_of_state = build_schedule(solver_.panel, driven, steps, int(frames))
    return solver_.solve(F, driven, step_of_state, check_intersections=check_intersections, progress=progress,
                         notes=notes)
