"""Planar development (unfolding) of a panel, with the paper's error metrics (§2.8, §3.3).

`develop(mesh, method="isometric")` returns a `Development`: 2D coordinates in the panel's vertex
order plus the length deviation of every edge and face diagonal, area change, flips and outline
overlap. Methods (paper Fig. 10):

- "isometric" (default): spring energy between 3D and 2D lengths over edges and face diagonals
  (a quad's two diagonals weigh 1/2 each, `springs.spring_weights`), from the exact incremental layout, refined by sparse Gauss-Newton (`isometric.py`);
- "conformal": least-squares conformal maps, best-scaled (`conformal.py`);
- "authalic": area-preserving with a weak conformal term (`authalic.py`).

`target_lengths` replaces the 3D lengths (the multi-panel merge step of §3.5): shape (E,) for the
mesh edges (each face's diagonals are then scaled by the mean target/3D ratio of its edges) or
(E + D,) for edges and diagonals in `spring_pairs` order. Only the isometric method uses them.
"""
from __future__ import annotations

import numpy as np

from fabkit.errors import InputError, MeshError, ToleranceError
from fabkit.mesh import PolyMesh
from fabkit.unfold.authalic import authalic_layout
from fabkit.unfold.conformal import best_scale, conformal_layout, far_boundary_pair
from fabkit.unfold.development import Development, measure_development
from fabkit.unfold.isometric import refine_isometric
from fabkit.unfold.layout import incremental_layout
from fabkit.unfold.metrics import spring_lengths
from fabkit.unfold.placement import place_on_sheet
from fabkit.unfold.springs import face_diagonals, spring_pairs, spring_weights

__all__ = ["METHODS", "DEFAULT_NORM", "Development", "develop", "spring_pairs", "reference_lengths"]

METHODS = ("isometric", "conformal", "authalic")
#: Exponent of the isometric spring energy: 2 = the paper's least-squares spring energy.
DEFAULT_NORM = 2.0


def reference_lengths(mesh: PolyMesh, target_lengths=None) -> tuple[np.ndarray, np.ndarray]:
    """`(pairs (S, 2), rest (S,))`: the springs and the lengths the development aims at."""
    pairs, E = spring_pairs(mesh)
    rest = spring_lengths(mesh.vertices, pairs)
    if target_lengths is None:
        return pairs, rest
    t = np.asarray(target_lengths, dtype=np.float64)
    S = len(pairs)
    if t.ndim != 1 or len(t) not in (E, S):
        raise InputError(f"target lengths need {E} entries (one per edge) or {S} (edges then diagonals), "
                         f"got shape {t.shape}", source="target_lengths")
    bad = np.flatnonzero(~np.isfinite(t) | (t <= 0))
    if len(bad):
        raise InputError(f"target length {int(bad[0])} is {t[bad[0]]}; lengths must be finite and positive",
                         source="target_lengths")
    if len(t) == S:
        return pairs, t.copy()
    out = rest.copy()
    out[:E] = t
    if S > E:
        topo = mesh.topology
        ratio = t / rest[:E]
        he_ratio = ratio[topo.halfedge_edge]
        face_ratio = np.add.reduceat(he_ratio, topo.face_offsets[:-1]) / topo.face_sizes
        _, dface = face_diagonals(mesh)
        out[E:] = rest[E:] * face_ratio[dface]
    return pairs, out


def _check_panel(mesh: PolyMesh) -> None:
    if not mesh.boundary_loops:
        raise MeshError("the mesh is closed (no boundary); a closed surface cannot be unfolded without cuts")
    if not np.all(np.isfinite(mesh.vertices[mesh.topology.used_vertex_mask])):
        raise MeshError("the mesh has non-finite vertex coordinates")
    small = mesh.edge_lengths <= 1e-12 * max(mesh.size, 1e-300)
    if np.any(small):
        e = int(np.flatnonzero(small)[0])
        raise MeshError(f"edge {e} {tuple(int(v) for v in mesh.edges[e])} has zero length")
    flat = mesh.face_areas <= 1e-12 * mesh.size ** 2
    if np.any(flat):
        f = int(np.flatnonzero(flat)[0])
        raise MeshError(f"face {f} has zero area (vertices {mesh.face(f).tolist()})")


def _isometric(mesh: PolyMesh, pairs, rest, seed_face, max_iterations, norm):
    layout = incremental_layout(mesh, seed_face)
    weights = spring_weights(mesh)
    uv, info = refine_isometric(mesh, layout.uv, pairs, rest, layout.anchor, max_iterations=max_iterations,
                                norm=norm, weights=weights)
    info = {**info, "start": "incremental layout", "seed_face": layout.seed_face}
    dev = measure_development(mesh, uv, method="isometric")
    if dev.n_flipped == 0 and not dev.outline_self_overlaps:
        return uv, info
    # The layout folded over itself (strongly non-developable input): start again from the
    # conformal map, which does not flip on a disk, and keep whichever result is better.
    tris, _ = mesh.triangulate()
    start = conformal_layout(mesh, tris)  # pins p at the origin and q on +x
    start *= best_scale(start, pairs, rest)
    p, q = far_boundary_pair(mesh)
    uv2, info2 = refine_isometric(mesh, start, pairs, rest, (p, q), max_iterations=max_iterations, norm=norm,
                                  weights=weights)
    dev2 = measure_development(mesh, uv2, method="isometric")
    if (dev2.n_flipped, dev2.outline_self_overlaps) < (dev.n_flipped, dev.outline_self_overlaps):
        return uv2, {**info2, "start": "conformal map (the incremental start flipped)", "seed_face": -1}
    return uv, info


def develop(mesh: PolyMesh, method: str = "isometric", target_lengths=None, *, seed_face: int | None = None,
            place: bool = True, max_iterations: int = 100, norm: float = DEFAULT_NORM) -> Development:
    """Unfold `mesh` into the plane and measure the result (see the module docstring).

    norm: exponent p of the isometric spring energy sum |relative deviation|^p; 2 (default) is the
    paper's least-squares spring energy; p > 2 lowers the maximum deviation at the cost of a
    slightly larger mean (on exactly developable input every p gives the same exact result).
    place: move the result rigidly so its smallest bounding rectangle is axis-aligned (long side
    along x) with its corner at the origin (`placement.place_on_sheet`); otherwise the seed face's
    first edge lies on +x from 0.
    Raises `MeshError` for meshes that cannot be unfolded (closed, several pieces, zero-length edges),
    `InputError` for bad target lengths, exponent or method, and `ToleranceError` when a solver
    breaks down (non-finite numbers, a singular system); a solver that merely runs out of
    iterations returns with `converged=False`.
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r} (choose {', '.join(METHODS)})", source="method")
    if not (np.isfinite(norm) and norm >= 2):
        raise InputError(f"the spring energy exponent must be a number >= 2, got {norm}", source="norm")
    _check_panel(mesh)
    pairs, rest = reference_lengths(mesh, target_lengths)
    if target_lengths is not None and method != "isometric":
        raise InputError("target lengths are only used by the isometric method", source="method")
    try:
        return _develop(mesh, method, pairs, rest, seed_face, place, max_iterations, float(norm))
    except FloatingPointError as exc:
        raise ToleranceError(f"{method} development failed: {exc}") from None


def _develop(mesh, method, pairs, rest, seed_face, place, max_iterations, norm) -> Development:
    details: dict = {}
    if method == "isometric":
        uv, info = _isometric(mesh, pairs, rest, seed_face, max_iterations, norm)
        details["norm"] = norm
        seed = info.pop("seed_face")
        details["start"] = info.pop("start")
        details["initial_max_relative_deviation"] = info.pop("initial_max_relative_deviation", None)
        info.pop("energy", None)
    else:
        tris, _ = mesh.triangulate()
        seed = -1
        if method == "conformal":
            uv = conformal_layout(mesh, tris)
            s = best_scale(uv, pairs, rest)
            uv = uv * s
            details["scale"] = s
            info = {"iterations": 1, "converged": True, "message": "linear least squares (sparse direct solve)"}
        else:
            uv, info = authalic_layout(mesh, tris, max_iterations=max_iterations)
            info.pop("energy", None)
    if place:
        uv = place_on_sheet(uv, mesh.topology.used_vertex_mask)
    E = mesh.n_edges
    return measure_development(mesh, uv, method=method, edge_reference=rest[:E], diagonal_reference=rest[E:],
                               seed_face=seed, details=details, **info)
