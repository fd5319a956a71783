"""Options and result of a relaxation (small frozen dataclasses, JSON-friendly)."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
import math
from typing import TYPE_CHECKING, Mapping, Sequence

from fabkit.errors import InputError, ToleranceError

if TYPE_CHECKING:  # numpy and the mesh are imported on use: `fabkit relax --help` reads the defaults here
    import numpy as np

    from fabkit.mesh import PolyMesh

METHODS = ("dr", "newton", "lbfgs")
BOUNDARIES = ("free", "fixed", "row-in-plane", "row-out", "row-in")


@dataclass(frozen=True)
class RelaxOptions:
    """How to relax. Tolerances are the stopping criteria; every one must hold to count as converged.

    method: "dr" dynamic relaxation with kinetic damping (paper §2.2), "newton" minimum-norm
        Gauss–Newton from the start, "lbfgs" scipy L-BFGS on the same energy.
    tol_defect [rad]: max |2π − Σθ| at interior vertices. tol_planarity: max plane distance of a face
        vertex / mean edge length of the face. tol_force: max |∇E| · L per vertex (dimensionless).
    boundary: "free" (planarity + boundary developability force, §2.5), "fixed", or an extra row of
        fixed boundary faces "row-in-plane" | "row-out" | "row-in" (Fig. 9), `row_width` times the
        mean boundary edge long; the row is removed from the output.
    fixed: vertex ids held fixed (singularity points, §3.2), added to mesh.vertex_data["fixed"].
    stage: developability first until max defect <= stage_defect, then both (§2.7).
    closeness: weight pulling toward the input positions (penalty in DR/L-BFGS, null-space pull in
        the Gauss–Newton steps, so a converged result is the nearby constraint-satisfying shape).
    planarity_weight w_p, plane_method "cross" | "covariance" (§2.4).
    damping: nominal viscous damping of DR velocities per step, in [0, 1) (§2.6).
    finish: hand over to Gauss–Newton (dr, lbfgs) once both measures are below `finish_below` or
        progress stalls. max_iter bounds DR / L-BFGS iterations, newton_max_iter the Newton steps.
    max_seconds: optional wall-clock budget (None: unlimited).
    fallback: when the chosen route misses the tolerances, try the other one (Gauss–Newton from the
        input after DR / L-BFGS; DR + finish after Newton) and keep the better result.
    edge_lengths: edges whose lengths the relaxation keeps, as `(edge_ids, lengths)` or a mapping
        edge id -> length [m] (edge ids index `mesh.edges`); stored as a tuple of (id, length) pairs.
        Each adds the residual r_e = (|x_u − x_v| − L_e) / L_e with weight `edge_length_weight`;
        converged also needs max |r_e| <= `tol_edge_length`. Lets neighbouring panels keep their
        shared boundary edges (fabkit.panels).
    crease_fairness: weight w of the crease-fairing phase (default 10; 0: off). Among the panels that
        meet the tolerances, the one closest to the input with the smoothest crease curves (third
        differences, weight scaled with the crease resolution) is sought (fabkit.relax.fairing). Removes
        the noise a least-squares relaxation leaves in the creases and so in the fold angles; creases
        come from face_data "strip" or, untagged, are inferred (fabkit.structure), and stop at corners
        turning by more than 30°. An input already within tolerance is left as it is.
    """

    method: str = "dr"
    tol_defect: float = 1e-8
    tol_planarity: float = 1e-8
    tol_force: float = 1e-6
    max_iter: int = 5000
    newton_max_iter: int = 100
    boundary: str = "free"
    row_width: float = 1.0
    fixed: tuple[int, ...] = ()
    stage: bool = False
    stage_defect: float = 1e-3
    closeness: float = 0.0
    planarity_weight: float = 1.0
    plane_method: str = "cross"
    damping: float = 0.0
    finish: bool = True
    finish_below: float = 1e-2
    max_seconds: float | None = None
    fallback: bool = True
    edge_lengths: tuple = ()
    edge_length_weight: float = 1.0
    tol_edge_length: float = 1e-8
    crease_fairness: float = 10.0

    def __post_init__(self):
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        if self.boundary not in BOUNDARIES:
            raise ValueError(f"boundary must be one of {', '.join(BOUNDARIES)}, got {self.boundary!r}")
        if self.plane_method not in ("cross", "covariance"):
            raise ValueError(f"plane_method must be cross or covariance, got {self.plane_method!r}")
        for name in ("tol_defect", "tol_planarity", "tol_force"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v}")
        for name in ("closeness", "planarity_weight", "stage_defect", "finish_below", "crease_fairness"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a non-negative number, got {v}")
        if not (0 <= self.damping < 1):
            raise ValueError(f"damping must be in [0, 1), got {self.damping}")
        if not (math.isfinite(self.row_width) and self.row_width > 0):
            raise ValueError(f"row_width must be positive, got {self.row_width}")
        if self.max_seconds is not None and not (math.isfinite(self.max_seconds) and self.max_seconds > 0):
            raise ValueError(f"max_seconds must be a positive number of seconds, got {self.max_seconds}")
        if int(self.max_iter) < 0 or int(self.newton_max_iter) < 0:
            raise ValueError("iteration limits must be >= 0")
        object.__setattr__(self, "fixed", tuple(int(i) for i in self.fixed))
        if not (math.isfinite(self.edge_length_weight) and self.edge_length_weight > 0):
            raise ValueError(f"edge_length_weight must be a positive number, got {self.edge_length_weight}")
        if not (math.isfinite(self.tol_edge_length) and self.tol_edge_length > 0):
            raise ValueError(f"tol_edge_length must be a positive number, got {self.tol_edge_length}")
        object.__setattr__(self, "edge_lengths", normalize_edge_lengths(self.edge_lengths))

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class IterationRecord:
    """One line of the convergence history."""

    phase: str            # "dr", "dr-stage1", "lbfgs", "newton", "fair"
    iteration: int        # running count over all phases
    max_defect: float
    mean_defect: float
    max_planarity: float
    mean_planarity: float
    kinetic_energy: float  # DR only (0 elsewhere)
    energy: float
    max_edge_length: float = 0.0  # max |r_e| over kept edges (0 when none are kept)


@dataclass(frozen=True)
class RelaxResult:
    """Outcome of a relaxation. `mesh` has the input's vertex order, faces and data.

    `converged` is False when any tolerance was missed; `message` says which and why. `mesh` is then
    the lowest-energy finite state reached (never NaN); call `raise_if_not_converged()` to turn that
    into a `ToleranceError`.
    """

    mesh: PolyMesh
    converged: bool
    message: str
    method: str
    iterations: int
    phase_iterations: dict
    max_defect: float
    mean_defect: float
    max_planarity: float
    mean_planarity: float
    force_residual: float
    max_displacement: float
    mean_displacement: float
    vertex_defect: np.ndarray       # (n,) rad, NaN off interior vertices (of the output mesh)
    face_planarity: np.ndarray      # (m,)
    vertex_displacement: np.ndarray  # (n,) m
    history: tuple[IterationRecord, ...] = field(default_factory=tuple)
    seconds: float = 0.0
    options: RelaxOptions | None = None
    max_edge_length_error: float = 0.0  # max |(|x_u − x_v| − L_e) / L_e| over the kept edges (0: none)

    def raise_if_not_converged(self) -> "RelaxResult":
        if not self.converged:
            raise ToleranceError(self.message)
        return self

    def to_report(self, per_element: bool = True) -> dict:
        """JSON-ready dict: options, outcome, final measures, history (and per-vertex/face values)."""
        out = {
            "converged": self.converged,
            "message": self.message,
            "method": self.method,
            "iterations": self.iterations,
            "phase_iterations": dict(self.phase_iterations),
            "seconds": self.seconds,
            "options": self.options.to_dict() if self.options else None,
            "final": {
                "max_abs_angle_defect_rad": self.max_defect,
                "mean_abs_angle_defect_rad": self.mean_defect,
                "max_planarity": self.max_planarity,
                "mean_planarity": self.mean_planarity,
                "force_residual": self.force_residual,
                "max_displacement_m": self.max_displacement,
                "mean_displacement_m": self.mean_displacement,
                "max_edge_length_error": self.max_edge_length_error,
            },
            "history": [asdict(h) for h in self.history],
        }
        if per_element:
            out["final"]["vertex_angle_defect_rad"] = self.vertex_defect
            out["final"]["face_planarity"] = self.face_planarity
            out["final"]["vertex_displacement_m"] = self.vertex_displacement
        return out


def normalize_edge_lengths(spec) -> tuple[tuple[int, float], ...]:
    """`(edge_ids, lengths)` or {edge id: length} -> sorted ((id, length), ...); InputError when malformed.

    Ids must be distinct non-negative integers, lengths finite and > 0 (the range of the ids is
    checked against the mesh by the Relaxer).
    """
    if spec is None:
        return ()
    if not isinstance(spec, Mapping):
        spec = tuple(spec)
        if len(spec) == 0:
            return ()
    import numpy as np

    if isinstance(spec, Mapping):
        ids, lengths = list(spec.keys()), list(spec.values())
    else:
        if len(spec) == 2 and np.ndim(spec[0]) == 1 and np.ndim(spec[1]) == 1:
            ids, lengths = spec
        elif all(np.ndim(p) == 1 and len(p) == 2 for p in spec):  # already ((id, length), ...)
            ids, lengths = [p[0] for p in spec], [p[1] for p in spec]
        else:
            raise InputError("edge_lengths must be (edge_ids, lengths) or a mapping edge id -> length")
    try:
        ids_f = np.asarray(ids, dtype=np.float64).reshape(-1)
        lengths = np.asarray(lengths, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputError("edge_lengths must hold numbers (edge ids and lengths)") from None
    if len(ids_f) != len(lengths):
        raise InputError(f"edge_lengths has {len(ids_f)} edge ids but {len(lengths)} lengths")
    if len(ids_f) and not np.all(np.isfinite(ids_f) & (ids_f == np.round(ids_f)) & (ids_f >= 0)):
        raise InputError("edge_lengths: edge ids must be non-negative integers")
    ids = ids_f.astype(np.int64)
    bad = np.flatnonzero(~(np.isfinite(lengths) & (lengths > 0)))
    if len(bad):
        raise InputError(f"edge_lengths: length of edge {int(ids[bad[0]])} is {lengths[bad[0]]}, "
                         "expected a finite positive number")
    order = np.argsort(ids, kind="stable")
    if np.any(np.diff(ids[order]) == 0):  # (not np.unique: it loads numpy.ma, 20 ms of a no-op relax)
        raise InputError("edge_lengths: an edge id is given twice")
    return tuple((int(ids[i]), float(lengths[i])) for i in order)


def fixed_mask_from(mesh: PolyMesh, fixed: Sequence[int] | np.ndarray | None) -> np.ndarray:
    """Boolean (n,) mask of fixed vertices: `fixed` (ids or a mask) OR mesh.vertex_data["fixed"]."""
    import numpy as np

    n = mesh.n_vertices
    mask = np.zeros(n, dtype=bool)
    if "fixed" in mesh.vertex_data:
        mask |= np.asarray(mesh.vertex_data["fixed"]).astype(bool).reshape(n)
    if fixed is None:
        return mask
    arr = np.asarray(fixed)
    if arr.size == 0:
        return mask
    if arr.dtype == bool:
        if arr.shape != (n,):
            raise ValueError(f"fixed mask has shape {arr.shape}, expected ({n},)")
        return mask | arr
    ids = arr.astype(np.int64).ravel()
    bad = ids[(ids < 0) | (ids >= n)]
    if len(bad):
        raise ValueError(f"fixed vertex {int(bad[0])} does not exist (vertices are 0..{n - 1})")
    mask[ids] = True
    return mask
