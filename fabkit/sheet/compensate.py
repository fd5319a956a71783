"""Springback-compensated fold states: the programmed (overbent) crease angles per state and the
rigid fold states that hold them, from a design fold sequence (a FOLD with fold states).

The FOLD keeps the design angles; the program drives the compensated states. For every crease
edge and state, programmed = `programmed_angle(spec, design, kappa_g, b)` of its crease row (so
that, released in that state, the crease springs back to the design angle). The other hinges
(rulings, diagonals) then follow the loop-closure constraints: each state is projected onto the
rigid-fold manifold with the crease hinges held at their programmed angles
(`fabkit.refold.RefoldSolver.fold_state`, Newton from the design angles), in the panel frame with the
sequence's clamped triangle fixed. With a rigid material (`none`) the input is returned unchanged.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from fabkit.errors import InputError, ToleranceError
from fabkit.fold import FoldModel
from fabkit.measures import dihedral_angles
from fabkit.sheet.creases import Crease, panel_creases
from fabkit.sheet.spec import SheetSpec, check_bend_radius
from fabkit.sheet.springback import programmed_angle

__all__ = ["CompensatedSequence", "compensate_sequence", "programmed_crease_angles"]


@dataclass(frozen=True, eq=False)
class CompensatedSequence:
    """`model`: the FOLD model whose states are the compensated (programmed) ones (same vertices,
    faces, tags; key frame and design target angles untouched); `design` and `programmed` (S, E)
    fold angles [rad] per state and FOLD edge; `creases` the crease rows; `spec` the sheet."""

    model: FoldModel
    design: np.ndarray
    programmed: np.ndarray
    creases: tuple[Crease, ...]
    spec: SheetSpec

    def state_table(self) -> list[dict]:
        """Per state and crease row: mean design and programmed angle [deg] over the row's edges, and
        the largest overbend (JSON-ready; signs: valley +)."""
        out = []
        for s in range(len(self.design)):
            rows = []
            for c in self.creases:
                d, p = self.design[s, c.edges], self.programmed[s, c.edges]
                rows.append({"crease": c.name, "design_deg": float(np.degrees(d.mean())),
                             "programmed_deg": float(np.degrees(p.mean())),
                             "max_overbend_deg": float(np.degrees(np.abs(p - d).max()))})
            out.append({"state": s, "creases": rows})
        return out

    def summary(self) -> dict:
        return {**self.spec.summary(),
                "creases": [{"crease": c.name, "length_m": c.length, "kappa_g_per_m": c.kappa_g,
                             "panel_width_m": c.panel_width} for c in self.creases],
                "states": self.state_table()}


def _design_angles(model: FoldModel) -> np.ndarray:
    """Fold angles (S, E) in FOLD edge order, measured from each state's coordinates (what the
    uncompensated program follows; stored `edges_foldAngle` may come from another tool)."""
    to_mesh = model.mesh_edge_index
    return np.stack([dihedral_angles(model.frame_mesh(i))[to_mesh] for i in range(model.n_frames)])


def _onto_design_frame(V: np.ndarray, solver, design: np.ndarray) -> np.ndarray:
    """Move a solved state rigidly so its fixed triangle sits where the design state has it (the
    identity for fabkit's own sequences, whose clamped triangle stays flat; a foreign sequence keeps
    its own panel frame)."""
    from scipy.spatial.transform import Rotation

    tri = solver.panel.tris[solver.fixed_triangle]
    a, b = V[tri], design[tri]
    ca, cb = a.mean(0), b.mean(0)
    R, _ = Rotation.align_vectors(b - cb, a - ca)
    return R.apply(V - ca) + cb


def programmed_crease_angles(spec: SheetSpec, design: np.ndarray, creases) -> np.ndarray:
    """Copy of `design` (S, E) with every crease edge replaced by its programmed angle."""
    out = np.array(design, np.float64, copy=True)
    for c in creases:
        for e in c.edges:
            for s in range(out.shape[0]):
                out[s, e] = programmed_angle(spec, float(design[s, e]), c.kappa_g, c.panel_width,
                                             crease=f"{c.name} (state {s})")
    return out


def compensate_sequence(model: FoldModel, spec: SheetSpec, source: str = "SEQ.fold") -> CompensatedSequence:
    """Compensated fold states of `model` (module docstring). Raises `BendRadiusError` when the sheet's
    radius is below the material minimum (naming the first crease), `SpringbackError` when a crease
    cannot reach its design angle, `ToleranceError` when a compensated state has no rigid fold."""
    if model.n_frames == 0:
        raise InputError("has no fold states (no file_frames)", source=source)
    creases = panel_creases(model)
    design = _design_angles(model)
    if spec.rigid:
        return CompensatedSequence(model, design, design.copy(), creases, spec)
    for c in creases:
        check_bend_radius(spec, c.name)
    programmed = programmed_crease_angles(spec, design, creases)

    from fabkit.refold import RefoldSolver

    flat = model.mesh()
    target = model.frame_mesh(model.n_frames - 1)
    fixed = model.file_data.get("fabkit:fixed_triangle")
    solver = RefoldSolver(flat, target, fixed_face=None if fixed is None else int(fixed),
                          flat_name=source, target_name=f"{source} (last state)")
    # the solver's triangle edges are the FOLD's edges, matched by vertex pair
    key = {(int(a), int(b)): i for i, (a, b) in enumerate(np.sort(np.asarray(model.edges_vertices), axis=1))}
    to_fold = np.array([key[(int(a), int(b))] for a, b in solver.panel.edges], np.int64)
    crease_edges = np.concatenate([c.edges for c in creases]) if creases else np.zeros(0, np.int64)
    fold_to_solver = np.full(model.n_edges, -1, np.int64)
    fold_to_solver[to_fold] = np.arange(len(to_fold))
    driven = np.sort(fold_to_solver[crease_edges])
    frames = []
    for s, frame in enumerate(model.frames):
        ref = programmed[s, to_fold]
        if not np.any(np.abs(ref) > 0):
            frames.append(frame)
            continue
        res = solver.fold_state(ref, ref, driven, hold=False)
        if not res.converged:
            raise ToleranceError(f"{source}: compensated state {s} has no rigid fold with the creases held at "
                                 f"their programmed angles (Newton did not converge)")
        V, _ = solver.positions(res.rho)
        V = _onto_design_frame(V, solver, np.asarray(frame.vertices_coords))
        angles = programmed[s].copy()
        angles[to_fold] = res.rho
        angles[crease_edges] = programmed[s, crease_edges]
        data = {**frame.data, "fabkit:compensated": 1}
        frames.append(dataclasses.replace(frame, vertices_coords=V, edges_fold_angle=angles, data=data))
        programmed[s] = angles
    return CompensatedSequence(_sign_changes_unassigned(model, frames).with_frames(frames), design, programmed,
                               creases, spec)


def _sign_changes_unassigned(model: FoldModel, frames) -> FoldModel:
    """`model` with the M/V hinges that the compensated `frames` turn through flat assigned U, the
    refold's rule for a hinge that changes sign during a sequence (`RefoldSolver.assignment`): a
    near-flat ruling (a pleat's fold by ~1e-4 rad) can change sign when the creases are held at
    their programmed angles. The FOLD file keeps its own assignment; a crease that changes sign is
    still refused (`panel_creases` reads the design)."""
    from fabkit.fold import ANGLE_SLACK

    a = np.asarray(model.edges_assignment).copy()
    A = np.array([f.edges_fold_angle for f in frames if f.edges_fold_angle is not None]).reshape(-1, len(a))
    flips = ((a == "V") & np.any(A < -ANGLE_SLACK, axis=0)) | ((a == "M") & np.any(A > ANGLE_SLACK, axis=0))
    if not flips.any():
        return model
    a[flips] = "U"
    return dataclasses.replace(model, edges_assignment=a)
