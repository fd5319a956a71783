"""Which edges are creases, and mountain or valley (FOLD assignments), from the folded 3D panel.

Crease edges are the interior edges between faces of different `face_data["strip"]` when the
panel carries strip tags (the contract in docs/CONTRACTS.md); otherwise the interior edges whose
3D dihedral angle exceeds a threshold. Mountain/valley comes from the sign of
`fabkit.measures.dihedral_angles` (FOLD convention: valley positive). A crease that is flat in the
given geometry (a tagged crease on a flat sheet) cannot be told apart and is "U" (unassigned).
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from fabkit.measures import dihedral_angles
from fabkit.mesh import PolyMesh

__all__ = ["CreaseAssignment", "crease_assignment", "chain_edges", "DEFAULT_CREASE_ANGLE"]

#: Untagged panels: an interior edge folded by more than this [rad] is a crease (5°).
DEFAULT_CREASE_ANGLE = np.radians(5.0)
#: A crease folded by less than this [rad] counts as flat: mountain/valley unknown ("U").
FLAT_ANGLE = 1e-9


@dataclass(frozen=True)
class CreaseAssignment:
    """Per edge (mesh.edges order): `edges_assignment` in B (boundary), M, V, F (flat, not a crease),
    U (crease of unknown sense); `edges_fold_angle` [rad, valley +]; `source` says how creases were found."""

    edges_assignment: np.ndarray
    edges_fold_angle: np.ndarray
    source: str

    def edges_with(self, kind: str) -> np.ndarray:
        return np.flatnonzero(self.edges_assignment == kind)

    def counts(self) -> dict:
        return {k: int(np.sum(self.edges_assignment == k)) for k in "BMVFU"}


def crease_assignment(mesh: PolyMesh, angle_threshold: float = DEFAULT_CREASE_ANGLE) -> CreaseAssignment:
    """Crease edges and their mountain/valley sense from the folded panel `mesh` (see module doc)."""
    t = mesh.topology
    angle = dihedral_angles(mesh)
    inner = ~t.boundary_edge_mask
    if "strip" in mesh.face_data:
        strip = np.asarray(mesh.face_data["strip"])
        crease = inner.copy()
        crease[inner] = strip[t.edge_faces[inner, 0]] != strip[t.edge_faces[inner, 1]]
        source = "face_data strip tags"
    else:
        crease = inner & (np.abs(angle) > angle_threshold)
        source = f"dihedral angle above {np.degrees(angle_threshold):.3g} degrees"
    a = np.full(len(angle), "F", dtype="<U1")
    a[~inner] = "B"
    a[crease & (angle > FLAT_ANGLE)] = "V"
    a[crease & (angle < -FLAT_ANGLE)] = "M"
    a[crease & (np.abs(angle) <= FLAT_ANGLE)] = "U"
    return CreaseAssignment(edges_assignment=a, edges_fold_angle=angle, source=source)


def chain_edges(edges: np.ndarray) -> list[list[int]]:
    """Join edges (k, 2) into vertex chains: open chains run between vertices not of degree 2,
    closed loops come back to their start. Every edge is used exactly once."""
    adj: dict[int, list[tuple[int, int]]] = defaultdict(list)
    for i, (a, b) in enumerate(np.asarray(edges).tolist()):
        adj[a].append((b, i))
        adj[b].append((a, i))
    used = [False] * len(edges)
    chains = []
    starts = sorted(v for v in adj if len(adj[v]) != 2) + sorted(adj)
    for s in starts:
        for nb, ei in adj[s]:
            if used[ei]:
                continue
            chain, e, cur = [s], ei, nb
            for _ in range(len(edges)):  # bounded walk
                used[e] = True
                chain.append(cur)
                if len(adj[cur]) != 2:
                    break
                nxt = [(w, j) for w, j in adj[cur] if not used[j]]
                if not nxt:
                    break
                cur, e = nxt[0][0], nxt[0][1]
            chains.append(chain)
    return chains
