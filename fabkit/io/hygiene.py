"""Input hygiene on raw polygon soups, before a `PolyMesh` is built: weld, re-merge quads, orient.

Designers' meshes come unwelded (one vertex copy per face, as many exporters write them),
triangulated (Rhino's and Blender's exporters split quads) and with faces wound either way. Each
step here is explicit, reported and returns its index map, so no stage renumbers silently:

- `weld`: vertices closer than a tolerance become one (scipy's KD-tree finds the pairs; clusters by
  connected components). The kept vertex of a cluster is its lowest original id and the welded ids
  keep the original order, so a mesh with nothing to weld is returned unchanged.
- `merge_triangle_pairs`: two triangles sharing an edge become the quad they were split from when
  the four corners are coplanar (to a relative tolerance, in every given fold state) and the quad is
  convex. On a folded panel only the split quads pass (the faces either side of a ruling or crease
  are bent against each other). Where a triangle has several candidates (a flat region, a flat
  pattern) the one with the largest smallest corner angle wins (the quad it was split from, on
  near-rectangular grids), greedily, so every triangle joins at most one quad.
- `orient`: faces wound against their neighbours are flipped so every interior edge is run in
  opposite directions by its two faces (breadth-first over each connected piece). The front side is
  the one faces are counter-clockwise around: a flat piece is turned to face +z, a curved one keeps
  the winding of the larger share of its area. A non-orientable piece (a Moebius strip) is refused.

Written by hand: trimesh merges vertices and fixes winding but only on triangles and it reorders;
these keep polygons and ids.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabkit.errors import MeshError

__all__ = ["weld", "merge_triangle_pairs", "orient", "WeldResult", "MergeResult", "OrientResult",
           "DEFAULT_WELD_RTOL", "DEFAULT_PLANAR_RTOL"]

#: vertices closer than this share of the bounding-box diagonal are the same vertex
DEFAULT_WELD_RTOL = 1e-7
#: a triangle pair is a flat quad when the corners are off their plane by less than this share of the
#: pair's diagonal (a relaxed panel's faces are planar to ~1e-10)
DEFAULT_PLANAR_RTOL = 1e-7


@dataclass(frozen=True)
class WeldResult:
    """`vertices` (m, 3) welded; `faces` re-indexed; `index_map[i]` = new id of old vertex i;
    `kept[j]` = old id that new vertex j came from; `merged` = how many vertices were removed."""

    vertices: np.ndarray
    faces: list
    index_map: np.ndarray
    kept: np.ndarray
    merged: int
    tolerance: float


@dataclass(frozen=True)
class MergeResult:
    """`faces` after merging; `face_map[k]` = the old face ids that form new face k; `merged` pairs."""

    faces: list
    face_map: tuple
    merged: int


@dataclass(frozen=True)
class OrientResult:
    """`faces` consistently wound, front as documented; `flipped` = ids of the faces reversed."""

    faces: list
    flipped: np.ndarray


def _size(V: np.ndarray) -> float:
    return float(np.linalg.norm(np.ptp(V, axis=0))) if len(V) else 0.0


def weld(vertices: np.ndarray, faces: list, rtol: float = DEFAULT_WELD_RTOL) -> WeldResult:
    """Merge vertices within `rtol * size` of each other (see module docstring). Faces that would
    repeat a vertex after welding raise `MeshError` (the tolerance is larger than the mesh's detail)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    V = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    n = len(V)
    tol = rtol * _size(V)
    pairs = cKDTree(V).query_pairs(tol, output_type="ndarray") if n and tol > 0 else np.zeros((0, 2), int)
    if len(pairs) == 0:
        same = np.arange(n)
        return WeldResult(V, [list(f) for f in faces], same, same, 0, tol)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    first = np.full(label.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, label, np.arange(n))
    kept = np.unique(first)                       # representatives, in original order
    index_map = np.searchsorted(kept, first)[label]  # old id -> new id
    out_faces = []
    for k, f in enumerate(faces):
        g = [int(index_map[i]) for i in f]
        if len(set(g)) != len(g):
            raise MeshError(f"face {k} collapses when vertices within {tol:.3g} m are welded "
                            "(its corners are closer than the weld tolerance)")
        out_faces.append(g)
    return WeldResult(V[kept], out_faces, index_map, kept, n - len(kept), tol)


def _tri_pair_quad(a: list, b: list) -> list | None:
    """The quad of triangles `a`, `b` sharing one edge (wound like `a`), or None."""
    shared = set(a) & set(b)
    if len(shared) != 2:
        return None
    for i in range(3):
        u, v = a[i], a[(i + 1) % 3]
        if {u, v} == shared:
            apex_b = next(x for x in b if x not in shared)
            return [u, apex_b, v, a[(i + 2) % 3]]  # a = (u, v, w), b = (v, u, x) -> u, x, v, w
    return None


def merge_triangle_pairs(vertices: np.ndarray, faces: list, rtol: float = DEFAULT_PLANAR_RTOL,
                         geometry: list[np.ndarray] | None = None) -> MergeResult:
    """Merge coplanar, convex triangle pairs back into quads (see module docstring).

    `geometry`: extra vertex positions (fold states) in which the pair must be planar too, so a
    flat crease pattern with a folded frame merges only the pairs that stay flat when folded.
    Meshes with no triangles come back unchanged.
    """
    V = np.asarray(vertices, dtype=np.float64)
    tris = [k for k, f in enumerate(faces) if len(f) == 3]
    if len(tris) < 2:
        return MergeResult([list(f) for f in faces], tuple((k,) for k in range(len(faces))), 0)
    states = [V] + [np.asarray(g, dtype=np.float64) for g in (geometry or [])]
    side_of: dict[tuple[int, int], list[int]] = {}
    for k in tris:
        f = faces[k]
        for i in range(3):
            side_of.setdefault(tuple(sorted((f[i], f[(i + 1) % 3]))), []).append(k)
    candidates = []
    for (u, v), ks in side_of.items():
        if len(ks) != 2:
            continue
        a, b = faces[ks[0]], faces[ks[1]]
        quad = _tri_pair_quad(list(a), list(b))
        if quad is None or not _flat_convex(states, quad, rtol):
            continue
        candidates.append([0, -_min_corner_angle(V[quad]), min(ks), max(ks), quad])
    per_triangle: dict[int, int] = {}
    for c in candidates:
        per_triangle[c[2]] = per_triangle.get(c[2], 0) + 1
        per_triangle[c[3]] = per_triangle.get(c[3], 0) + 1
    for c in candidates:  # pairs with no rival first, then the squarest quads
        c[0] = int(per_triangle[c[2]] > 1 or per_triangle[c[3]] > 1)
    candidates.sort(key=lambda c: (c[0], c[1], c[2], c[3]))
    used: set[int] = set()
    quad_at: dict[int, tuple[list, int]] = {}
    for _, _, ka, kb, quad in candidates:
        if ka in used or kb in used:
            continue
        used.update((ka, kb))
        quad_at[ka] = (quad, kb)
    out, fmap = [], []
    skip = {kb for _, kb in quad_at.values()}
    for k, f in enumerate(faces):
        if k in skip:
            continue
        if k in quad_at:
            q, kb = quad_at[k]
            out.append(_wind_like(q, faces[k]))
            fmap.append((k, kb))
        else:
            out.append(list(f))
            fmap.append((k,))
    return MergeResult(out, tuple(fmap), len(quad_at))


def _min_corner_angle(P: np.ndarray) -> float:
    """Smallest interior corner angle (rad) of a polygon's corners."""
    worst = np.pi
    for i in range(len(P)):
        a, b = P[i - 1] - P[i], P[(i + 1) % len(P)] - P[i]
        c = np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))
        worst = min(worst, float(np.arccos(np.clip(c, -1.0, 1.0))))
    return worst


def _wind_like(quad: list, tri: list) -> list:
    """`quad` reversed if needed so it runs along `tri`'s sides in `tri`'s direction."""
    pos = {v: i for i, v in enumerate(quad)}
    for i in range(3):
        u, v = tri[i], tri[(i + 1) % 3]
        if u in pos and v in pos and (pos[u] + 1) % 4 == pos[v]:
            return quad
    return quad[::-1]


def _flat_convex(states: list[np.ndarray], quad: list, rtol: float) -> bool:
    for V in states:
        P = V[quad]
        c = P.mean(axis=0)
        n = np.cross(P[2] - P[0], P[3] - P[1])
        nn = np.linalg.norm(n)
        scale = max(np.linalg.norm(P[2] - P[0]), np.linalg.norm(P[3] - P[1]))
        if nn <= 1e-300 or scale <= 0:
            return False
        n /= nn
        if np.max(np.abs((P - c) @ n)) > rtol * scale:
            return False
        turns = [np.dot(np.cross(P[(i + 1) % 4] - P[i], P[(i + 2) % 4] - P[(i + 1) % 4]), n) for i in range(4)]
        if not (all(t > 0 for t in turns) or all(t < 0 for t in turns)):
            return False
    return True


def orient(vertices: np.ndarray, faces: list) -> OrientResult:
    """Wind every face consistently with its neighbours, front side as documented (module docstring).

    Raises `MeshError` for a non-orientable piece or an edge shared by more than two faces.
    """
    V = np.asarray(vertices, dtype=np.float64)
    F = len(faces)
    by_edge: dict[tuple[int, int], list[tuple[int, bool]]] = {}
    for k, f in enumerate(faces):
        for i in range(len(f)):
            u, v = f[i], f[(i + 1) % len(f)]
            by_edge.setdefault((min(u, v), max(u, v)), []).append((k, u < v))
    for (u, v), fs in by_edge.items():
        if len(fs) > 2:
            raise MeshError(f"edge ({u}, {v}) is shared by {len(fs)} faces {sorted(k for k, _ in fs)} "
                            "(non-manifold: an edge may border at most 2 faces)")
    nbrs: list[list[tuple[int, bool]]] = [[] for _ in range(F)]
    for fs in by_edge.values():
        if len(fs) == 2:
            (a, da), (b, db) = fs
            nbrs[a].append((b, da == db))  # same direction: the two must differ in flip state
            nbrs[b].append((a, da == db))
    flip = np.full(F, -1, dtype=np.int8)
    pieces = []
    for seed in range(F):
        if flip[seed] >= 0:
            continue
        flip[seed] = 0
        piece, queue = [seed], [seed]
        while queue:
            k = queue.pop()
            for j, differ in nbrs[k]:
                want = flip[k] ^ int(differ)
                if flip[j] < 0:
                    flip[j] = want
                    piece.append(j)
                    queue.append(j)
                elif flip[j] != want:
                    raise MeshError(f"faces {min(k, j)} and {max(k, j)} cannot be wound consistently: the surface "
                                    "is not orientable (a Moebius-like strip has no front side)")
        pieces.append(piece)
    for piece in pieces:
        normal = np.zeros(3)
        area_kept = area_flipped = 0.0
        for k in piece:
            P = V[faces[k]]
            a = 0.5 * np.cross(P, np.roll(P, -1, axis=0)).sum(axis=0)
            a = -a if flip[k] else a
            normal += a
            if flip[k]:
                area_flipped += np.linalg.norm(a)
            else:
                area_kept += np.linalg.norm(a)
        zs = V[np.concatenate([np.asarray(faces[k]) for k in piece]), 2]  # repeats do not change the range
        flat = np.ptp(zs) <= 1e-12 * max(_size(V), 1e-300)
        turn = normal[2] < 0 if flat else area_flipped > area_kept
        if turn:
            flip[piece] ^= 1
    flipped = np.flatnonzero(flip == 1)
    out = [list(f)[::-1] if flip[k] else list(f) for k, f in enumerate(faces)]
    return OrientResult(out, flipped)
