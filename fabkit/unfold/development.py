"""`Development`: a flat pattern plus the numbers that say how isometric it is."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fabkit.mesh import PolyMesh
from fabkit.unfold import metrics
from fabkit.unfold.springs import face_diagonals

__all__ = ["Development", "measure_development"]


def _ro(a) -> np.ndarray:
    a = np.array(a)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Development:
    """A planar development of a panel and its error metrics (metres; arrays read-only).

    uv: (n, 2) coordinates in the panel's vertex order, faces counter-clockwise (front side +z).
    edges / diagonals: (E, 2) mesh edges and (D, 2) face diagonals (`diagonal_faces`: their face).
    *_reference: the lengths the development aims at (3D lengths, or the target lengths).
    *_deviation: signed l2D - reference [m]; *_relative_deviation: the same divided by the reference.
    mean/max_*: the paper's two metrics over edges and diagonals together, of the absolute values.
    face_area_change: (A2D - A3D) / A3D per face. flipped_faces: ids of faces turned over (must be
    empty). outline_self_overlaps: the cut outline crosses itself (shapely).
    method: "isometric" | "conformal" | "authalic"; iterations / converged / message: the solver's
    account (iterations 0 when the layout was already exact); seed_face: where the layout started.
    """

    method: str
    uv: np.ndarray
    edges: np.ndarray
    edge_reference: np.ndarray
    edge_deviation: np.ndarray
    edge_relative_deviation: np.ndarray
    diagonals: np.ndarray
    diagonal_faces: np.ndarray
    diagonal_reference: np.ndarray
    diagonal_deviation: np.ndarray
    diagonal_relative_deviation: np.ndarray
    mean_relative_deviation: float
    max_relative_deviation: float
    mean_absolute_deviation: float
    max_absolute_deviation: float
    face_area_change: np.ndarray
    flipped_faces: np.ndarray
    outline_self_overlaps: bool
    seed_face: int = -1
    iterations: int = 0
    converged: bool = True
    message: str = ""
    details: dict = field(default_factory=dict)

    @property
    def n_flipped(self) -> int:
        return int(len(self.flipped_faces))

    @property
    def spring_relative_deviation(self) -> np.ndarray:
        """Relative deviation of edges then diagonals (the order of `spring_pairs`)."""
        return np.concatenate([self.edge_relative_deviation, self.diagonal_relative_deviation])

    def mesh(self, panel: PolyMesh) -> PolyMesh:
        """The flat pattern as a mesh: `panel`'s faces, vertex order and data, z = 0."""
        return panel.with_vertices(np.column_stack([self.uv, np.zeros(len(self.uv))]))

    def summary(self) -> dict:
        """Headline numbers for reports (JSON-ready)."""
        return {
            "method": self.method,
            "vertices": int(len(self.uv)),
            "edges": int(len(self.edges)),
            "diagonals": int(len(self.diagonals)),
            "mean_relative_deviation": self.mean_relative_deviation,
            "max_relative_deviation": self.max_relative_deviation,
            "mean_absolute_deviation_m": self.mean_absolute_deviation,
            "max_absolute_deviation_m": self.max_absolute_deviation,
            "max_abs_face_area_change": float(np.max(np.abs(self.face_area_change))) if len(self.face_area_change) else 0.0,
            "flipped_faces": self.n_flipped,
            "outline_self_overlaps": bool(self.outline_self_overlaps),
            "seed_face": int(self.seed_face),
            "iterations": int(self.iterations),
            "converged": bool(self.converged),
            "message": self.message,
            **self.details,
        }


def measure_development(mesh: PolyMesh, uv: np.ndarray, *, method: str,
                        edge_reference: np.ndarray | None = None,
                        diagonal_reference: np.ndarray | None = None, **info) -> Development:
    """Measure `uv` against the 3D lengths of `mesh` (or the given reference lengths)."""
    uv = np.asarray(uv, dtype=np.float64)
    E = mesh.edges
    D, Df = face_diagonals(mesh)
    if edge_reference is None:
        edge_reference = mesh.edge_lengths
    if diagonal_reference is None:
        diagonal_reference = metrics.spring_lengths(mesh.vertices, D)
    le = metrics.spring_lengths(uv, E)
    ld = metrics.spring_lengths(uv, D)
    de, dd = le - edge_reference, ld - diagonal_reference
    re, rd = de / edge_reference, dd / diagonal_reference
    rel = np.abs(np.concatenate([re, rd]))
    ab = np.abs(np.concatenate([de, dd]))
    return Development(
        method=method, uv=_ro(uv), edges=_ro(E),
        edge_reference=_ro(edge_reference), edge_deviation=_ro(de), edge_relative_deviation=_ro(re),
        diagonals=_ro(D), diagonal_faces=_ro(Df), diagonal_reference=_ro(diagonal_reference),
        diagonal_deviation=_ro(dd), diagonal_relative_deviation=_ro(rd),
        mean_relative_deviation=float(rel.mean()), max_relative_deviation=float(rel.max()),
        mean_absolute_deviation=float(ab.mean()), max_absolute_deviation=float(ab.max()),
        face_area_change=_ro(metrics.face_area_change(mesh, uv)),
        flipped_faces=_ro(metrics.flipped_faces(mesh, uv)),
        outline_self_overlaps=metrics.outline_self_overlaps(mesh, uv),
        **info,
    )
