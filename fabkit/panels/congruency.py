"""Edge congruency between neighbouring panels' developments and the merge into target lengths (§3.4–3.5).

Two panels that share a boundary edge on the surface are cut separately and joined again; for
the joint to close, the edge must have the same length in both flat patterns. The incongruency of
a shared edge is |l_a − l_b| / mean(l_a, l_b) of its developed (2D) lengths. Merging sets both
panels' target length for that edge to the mean, so the next development absorbs the gap or
overlap into the panels themselves (paper §3.5).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Congruency", "measure_congruency", "merged_targets"]


@dataclass(frozen=True)
class Congruency:
    """Per shared edge: the two panels, their edge ids, developed lengths and relative mismatch."""

    pairs: np.ndarray        # (k, 4) int: panel_a, edge_a, panel_b, edge_b
    length_a: np.ndarray     # (k,) developed length in panel a [m]
    length_b: np.ndarray     # (k,)
    relative: np.ndarray     # (k,) |l_a - l_b| / mean

    @property
    def max_relative(self) -> float:
        return float(self.relative.max()) if len(self.relative) else 0.0

    @property
    def mean_relative(self) -> float:
        return float(self.relative.mean()) if len(self.relative) else 0.0

    def per_panel_max(self, n_panels: int) -> np.ndarray:
        """Worst incongruency over each panel's shared edges."""
        out = np.zeros(n_panels)
        np.maximum.at(out, self.pairs[:, 0], self.relative)
        np.maximum.at(out, self.pairs[:, 2], self.relative)
        return out


def _edge_lengths_2d(uv: np.ndarray, edges: np.ndarray) -> np.ndarray:
    return np.linalg.norm(uv[edges[:, 1]] - uv[edges[:, 0]], axis=1)


def measure_congruency(shared_edges, edges_per_panel, uv_per_panel) -> Congruency:
    """Compare developed lengths of every shared edge (`edges_per_panel[p]` = mesh.edges of panel p)."""
    pairs = np.asarray(shared_edges, dtype=np.int64).reshape(-1, 4)
    la = np.empty(len(pairs))
    lb = np.empty(len(pairs))
    lengths = [_edge_lengths_2d(np.asarray(uv), np.asarray(E)) for uv, E in zip(uv_per_panel, edges_per_panel)]
    for i, (pa, ea, pb, eb) in enumerate(pairs):
        la[i] = lengths[pa][ea]
        lb[i] = lengths[pb][eb]
    rel = np.abs(la - lb) / (0.5 * (la + lb))
    return Congruency(pairs=pairs, length_a=la, length_b=lb, relative=rel)


def merged_targets(congruency: Congruency, n_panels: int) -> list[dict[int, float]]:
    """Target lengths per panel {edge id: length}: both sides of a shared edge get the mean."""
    targets: list[dict[int, float]] = [dict() for _ in range(n_panels)]
    mean = 0.5 * (congruency.length_a + congruency.length_b)
    for (pa, ea, pb, eb), m in zip(congruency.pairs.tolist(), mean.tolist()):
        targets[pa][ea] = m
        targets[pb][eb] = m
    return targets
