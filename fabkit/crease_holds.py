"""What folds each crease: the holds on either side of every crease row.

Cutting a crease row (all its hinges) splits the rigid panel into parts (`fabkit.holds`' crease
cut). A crease is folded by something held when every part carries a hold (the clamp, an arm's
grip, a jig): the holds on the two sides turn the parts against each other about the crease. A
part without a hold is a wing nothing decides the position of (docs/holds.md). `crease_sides`
gives the parts, `crease_holds` puts named holds on them; `fabkit check` records the result per
run of moves with one set of holds (CHECK.json `holds.creases`), and report.html prints it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

__all__ = ["CreaseHolds", "crease_sides", "crease_holds"]


@dataclass(frozen=True)
class CreaseHolds:
    """Crease row `crease` (`edges` hinges): `sides` the parts the cut leaves, each `(faces, holds)`
    with `holds` the labels of the holds on it ("clamp face 5", "arm a face 11"); `held` iff every
    side has one; `set` iff the crease is locked (set in an earlier phase: not cut)."""

    crease: int
    edges: int
    sides: tuple[tuple[tuple[int, ...], tuple[str, ...]], ...]
    held: bool
    set: bool = False

    def to_json(self) -> dict:
        return {"crease": self.crease, "edges": self.edges, "held": self.held, "set": self.set,
                "sides": [{"faces": list(f), "holds": list(h)} for f, h in self.sides]}


def crease_sides(model) -> dict[int, tuple[tuple[int, ...], ...]]:
    """Crease row -> the parts (polygon ids, sorted; parts ordered by their smallest face) the
    panel falls into when the row's hinges are cut, for a `fabkit.holds.HoldModel`; a row whose cut
    leaves the panel in one piece (a crease ending inside the panel) maps to that one part."""
    t = model.topology
    inner = t.interior_edges
    out = {}
    for row, hinges in sorted(model.rows.items()):
        keep = inner[~np.isin(inner, hinges)]
        a, b = t.edge_faces[keep, 0], t.edge_faces[keep, 1]
        n_tris = len(model.tris)
        g = sp.coo_matrix((np.ones(len(keep)), (a, b)), shape=(n_tris, n_tris))
        n, label = connected_components(g, directed=False)
        parts = [tuple(int(f) for f in np.unique(model.tri_face[label == c])) for c in range(n)]
        out[int(row)] = tuple(sorted(parts, key=lambda p: p[0]))
    return out


def crease_holds(model, holds, sides: dict | None = None) -> tuple[CreaseHolds, ...]:
    """Per crease row of `model`, the holds `[(label, face), ...]` on each side of its cut;
    `sides` from `crease_sides` (computed when None)."""
    sides = crease_sides(model) if sides is None else sides
    out = []
    for row, parts in sides.items():
        hinges = model.rows[row]
        locked = bool(np.all(np.isin(hinges, model.locked)))
        labelled = []
        for part in parts:
            on = set(part)
            labelled.append((part, tuple(f"{label} face {f}" for label, f in holds if f in on)))
        held = locked or all(h for _, h in labelled)
        out.append(CreaseHolds(int(row), int(len(hinges)), tuple(labelled), held, locked))
    return tuple(out)
