"""Which hinges are driven, in which order, and the fold sequence that results.

A *schedule* is an `(S, E)` array of fold fractions: state s wants hinge e at `fraction[s, e]`
times its target angle. Driven hinges are held exactly there; the other hinges only *prefer* it
(the solver moves them as little as the loop-closure constraints allow), so every state is a
rigid fold and the last state, where every fraction is 1, is the target.

Steps fold groups of driven hinges one after another. A free hinge follows the driven hinges
nearest to it: a non-driven crease hinge follows the driven hinges of its own crease row; a ruling
or diagonal in strip k follows the mean of the creases bounding strip k; on a panel without creases
every free hinge follows the mean of the driven fractions.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from fabkit.errors import InputError
from fabkit.mesh import PolyMesh
from fabkit.refold.triangulate import CREASE, EDGE_KINDS, TriangulatedPanel

__all__ = ["FoldSequence", "middle_row_hinges", "resolve_edge_refs", "load_drive_file", "build_schedule",
           "parse_steps"]


@dataclass(frozen=True, eq=False)
class FoldSequence:
    """Fold states from flat to target, with per-state diagnostics (arrays; radians and metres).

    Triangle mesh: `flat_vertices` (n, 3), `tris` (t, 3), `tri_face` (t,) polygon of each triangle,
    `edges` (E, 2) sorted, `edge_kind` (E,) names from `EDGE_KINDS`, `edges_assignment` (E,) FOLD
    letters, `target_angles` (E,), `driven` hinge ids, `fixed_face` polygon id (its first triangle
    `fixed_triangle` is clamped at its flat position: the panel frame).
    Per state s: `fractions` (S, E) schedule, `angles` (S, E), `positions` (S, n, 3), `step` (S,)
    folding step (-1 for the flat state), `residual` (S,) max |rotvec(P_v)| [rad],
    `edge_length_error` (S,) max relative, `corner_mismatch` (S,) [m], `newton_iterations` (S,),
    `converged` (S,), `intersections` (S,) number of triangle pairs passing through each other.
    `target_distance` max vertex distance [m] of the last state to the target aligned on the fixed
    face; `panel_size` [m] (bounding-box diagonal of the flat pattern). `face_data` per triangle
    (`polygon` and the quads' strip/column/middle tags); `polygon_edge` (E,) FLAT's edge id of each
    hinge (-1 for diagonals); `edge_crease` (E,) crease row k (between strips k and k+1) of crease
    hinges, -1 otherwise; `notes` remarks (fallbacks, non-convergence). Only converged states are kept:
    `failed_state` is the first scheduled state Newton could not reach (-1: none, `complete`) and
    `failure` says where (the worst hinge).
    """

    flat_vertices: np.ndarray
    tris: np.ndarray
    tri_face: np.ndarray
    edges: np.ndarray
    edge_kind: np.ndarray
    edges_assignment: np.ndarray
    target_angles: np.ndarray
    driven: np.ndarray
    fixed_face: int
    fixed_triangle: int
    fractions: np.ndarray
    angles: np.ndarray
    positions: np.ndarray
    step: np.ndarray
    residual: np.ndarray
    edge_length_error: np.ndarray
    corner_mismatch: np.ndarray
    newton_iterations: np.ndarray
    converged: np.ndarray
    intersections: np.ndarray
    target_distance: float
    panel_size: float
    face_data: dict = field(default_factory=dict)
    polygon_edge: np.ndarray | None = None
    edge_crease: np.ndarray | None = None
    notes: tuple = ()
    failed_state: int = -1
    failure: str = ""

    @property
    def complete(self) -> bool:
        """Did every scheduled state converge (so the last state is the target)?"""
        return self.failed_state < 0

    @property
    def n_states(self) -> int:
        return len(self.angles)

    def problems(self, target_rtol: float) -> list[str]:
        """The verdicts (empty when the sequence is good): a state that did not converge (naming the
        worst hinge), a last state farther than `target_rtol` x the panel size from the target, faces
        passing through each other."""
        out = [] if self.complete else [self.failure]
        rel = self.target_distance / self.panel_size if self.panel_size > 0 else float("nan")
        if self.complete and not rel <= target_rtol:
            out.append(f"the last state is {self.target_distance:.3g} m from TARGET ({rel:.3g} of the panel size, "
                       f"tolerance {target_rtol:g})")
        bad = np.flatnonzero(self.intersections > 0)
        if len(bad):
            out.append(f"faces pass through each other in {len(bad)} states (first: state {int(bad[0])}, "
                       f"{int(self.intersections[bad[0]])} triangle pairs)")
        return out

    def summary(self) -> dict:
        """Headline numbers (JSON-ready)."""
        return {
            "states": self.n_states,
            "triangles": len(self.tris),
            "hinges": int(np.sum(self.edge_kind != "boundary")),
            "driven_hinges": len(self.driven),
            "fixed_face": self.fixed_face,
            "max_loop_residual_rad": float(np.max(self.residual)),
            "max_edge_length_error_rel": float(np.max(self.edge_length_error)),
            "max_corner_mismatch_m": float(np.max(self.corner_mismatch)),
            "target_distance_m": self.target_distance,
            "target_distance_rel": self.target_distance / self.panel_size if self.panel_size > 0 else float("nan"),
            "panel_size_m": self.panel_size,
            "newton_iterations_max": int(np.max(self.newton_iterations)),
            "newton_iterations_mean": float(np.mean(self.newton_iterations[1:])) if self.n_states > 1 else 0.0,
            "all_converged": bool(self.complete),
            "failed_state": self.failed_state if self.failed_state >= 0 else None,
            "states_with_intersections": int(np.sum(self.intersections > 0)),
        }


def middle_row_hinges(panel: TriangulatedPanel) -> np.ndarray:
    """Crease hinges of the middle column (the paper's driven angles): `panel.middle_hinges`, from the
    panel structure (`fabkit.structure`: the middle-row tags, or the middle row inferred from the
    geometry). Empty when the panel has no crease."""
    return np.asarray(panel.middle_hinges, np.int64)


def resolve_edge_refs(refs, flat: PolyMesh, panel: TriangulatedPanel, source: str) -> np.ndarray:
    """Hinge ids for a list of edge references: ints (edge ids of FLAT's polygon mesh, sorted
    vertex pairs as in `PolyMesh.edges`) or `[u, v]` vertex pairs (any order; diagonals allowed)."""
    if not isinstance(refs, (list, tuple)):
        raise InputError("expected a list of edge ids or [u, v] vertex pairs", source=source)
    n = flat.n_vertices
    tedges = panel.topology.edges
    keys = tedges[:, 0] * n + tedges[:, 1]
    out = []
    for k, ref in enumerate(refs):
        if isinstance(ref, bool) or not isinstance(ref, (int, list, tuple)):
            raise InputError(f"entry {k} ({ref!r}) is neither an edge id nor a [u, v] vertex pair", source=source)
        if isinstance(ref, int):
            if not 0 <= ref < flat.n_edges:
                raise InputError(f"entry {k}: edge {ref} does not exist (FLAT has edges 0..{flat.n_edges - 1})",
                                 source=source)
            u, v = (int(x) for x in flat.edges[ref])
        else:
            if len(ref) != 2 or not all(isinstance(x, int) and not isinstance(x, bool) for x in ref):
                raise InputError(f"entry {k} ({ref!r}) is not a [u, v] pair of vertex ids", source=source)
            u, v = sorted(int(x) for x in ref)
        key = u * n + v
        pos = int(np.searchsorted(keys, key))
        if pos >= len(keys) or keys[pos] != key:
            raise InputError(f"entry {k}: vertices {u} and {v} are not joined by an edge", source=source)
        if panel.edge_kind[pos] == 0:
            raise InputError(f"entry {k}: edge ({u}, {v}) is on the boundary and cannot be folded", source=source)
        out.append(pos)
    return np.unique(np.array(out, np.int64))


def load_drive_file(path: str | os.PathLike, flat: PolyMesh, panel: TriangulatedPanel):
    """Read a drive/schedule JSON file -> (driven hinges, steps as a list of hinge arrays or None).

    Accepted: a list of edge refs (driven, one step); a list of lists (steps in order; driven = all);
    or an object {"drive": [...], "steps": [[...], ...]} (either key optional).
    """
    from fabkit.io.jsonfile import load_json

    source = str(path)
    data = load_json(path, "readable JSON file", missing="file not found")
    drive_refs, step_refs = None, None
    if isinstance(data, dict):
        unknown = set(data) - {"drive", "steps"}
        if unknown:
            raise InputError(f"unknown keys {sorted(unknown)} (expected 'drive' and/or 'steps')", source=source)
        drive_refs, step_refs = data.get("drive"), data.get("steps")
    elif isinstance(data, list) and data and all(isinstance(g, list) and g and isinstance(g[0], list) for g in data):
        step_refs = data
    else:
        drive_refs = data
    steps = None
    if step_refs is not None:
        if not isinstance(step_refs, list) or not step_refs:
            raise InputError("'steps' must be a non-empty list of edge lists", source=source)
        steps = [resolve_edge_refs(g, flat, panel, f"{source} (step {i})") for i, g in enumerate(step_refs)]
    if drive_refs is not None:
        driven = resolve_edge_refs(drive_refs, flat, panel, source)
    elif steps is not None:
        driven = np.unique(np.concatenate(steps))
    else:
        raise InputError("no edges to drive", source=source)
    if len(driven) == 0:
        raise InputError("no edges to drive", source=source)
    return driven, steps


def parse_steps(text: str, panel: TriangulatedPanel, driven: np.ndarray) -> list[np.ndarray]:
    """`"crease0,crease1"` or `"strip0,strip2"` -> groups of driven hinges, in order.

    `creaseK`: driven hinges on crease row K (between strips K and K+1); `stripK`: driven hinges on
    the creases bounding strip K (K-1 and K) not folded by an earlier step. Groups may not be empty.
    """
    groups, used = [], np.zeros(0, np.int64)
    has_rows = np.any(panel.edge_crease >= 0)
    for token in [t.strip() for t in text.split(",") if t.strip()]:
        name = token.rstrip("0123456789")
        num = token[len(name):]
        if name not in ("crease", "strip") or not num:
            raise InputError(f"step '{token}' is not creaseK or stripK", source="--steps")
        if not has_rows:
            raise InputError("named steps need creases (the panel has none); use a JSON schedule file",
                             source="--steps")
        k = int(num)
        rows = [k] if name == "crease" else [k - 1, k]
        g = driven[np.isin(panel.edge_crease[driven], rows)]
        g = np.setdiff1d(g, used)
        if len(g) == 0:
            raise InputError(f"step '{token}' has no driven crease hinges left to fold", source="--steps")
        groups.append(g)
        used = np.union1d(used, g)
    if not groups:
        raise InputError("no steps given", source="--steps")
    return groups


def build_schedule(panel: TriangulatedPanel, driven: np.ndarray,
                   steps: list[np.ndarray] | None, frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Fractions `(S, E)` and the step of each state; S = 1 + n_steps * (frames - 1).

    Every driven hinge must belong to exactly one step. State 0 is flat.
    """
    if frames < 2:
        raise InputError(f"need at least 2 frames (flat and target), got {frames}", source="--frames")
    steps = [np.asarray(driven)] if steps is None else [np.asarray(g, np.int64) for g in steps]
    allg = np.concatenate(steps)
    if len(np.unique(allg)) != len(allg):
        raise InputError("a hinge appears in more than one step", source="--steps")
    left = np.setdiff1d(driven, allg)
    if len(left):
        u, v = panel.topology.edges[left[0]]
        raise InputError(f"{len(left)} driven hinges are in no step (first: edge ({u}, {v}))", source="--steps")
    E = panel.topology.n_edges
    G = len(steps)
    ramp = np.linspace(0.0, 1.0, frames)[1:]
    # per state: fraction of each step
    step_frac = np.zeros((1 + G * (frames - 1), G))
    step_of_state = np.full(len(step_frac), -1, np.int64)
    for g in range(G):
        rows = slice(1 + g * (frames - 1), 1 + (g + 1) * (frames - 1))
        step_frac[rows, :g] = 1.0
        step_frac[rows, g] = ramp
        step_of_state[rows] = g
    F = np.zeros((len(step_frac), E))
    group_of = np.full(E, -1, np.int64)
    for g, grp in enumerate(steps):
        group_of[grp] = g
    driven_mask = group_of >= 0
    F[:, driven_mask] = step_frac[:, group_of[driven_mask]]
    mean_all = F[:, driven_mask].mean(axis=1)
    free = np.flatnonzero(~driven_mask & panel.hinge_mask)
    F[:, free] = mean_all[:, None]
    if np.any(panel.edge_crease >= 0):
        rows_max = int(panel.edge_crease.max())
        row_frac = np.full((len(F), rows_max + 1), np.nan)
        for r in range(rows_max + 1):
            d = driven_mask & (panel.edge_crease == r)
            if d.any():
                row_frac[:, r] = F[:, d].mean(axis=1)
        face_strip = panel.face_strip[panel.tri_face[np.maximum(panel.topology.edge_faces[:, 0], 0)]]
        # candidate crease rows per free hinge: its own row, or the two rows bounding its strip
        r = panel.edge_crease[free]
        cand = np.where((r >= 0)[:, None], np.stack([r, r], axis=1),
                        np.stack([face_strip[free] - 1, face_strip[free]], axis=1))
        ok = (cand >= 0) & (cand <= rows_max)
        ok[ok] &= ~np.isnan(row_frac[0, cand[ok]])
        n_ok = ok.sum(axis=1)
        vals = np.where(ok[None], row_frac[:, np.clip(cand, 0, rows_max)], 0.0)  # (S, free, 2)
        has = n_ok > 0
        F[:, free[has]] = vals[:, has].sum(axis=2) / n_ok[has]
    return F, step_of_state


def edge_kind_names(panel: TriangulatedPanel) -> np.ndarray:
    return np.array(EDGE_KINDS)[panel.edge_kind]
