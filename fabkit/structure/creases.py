"""Crease edges from the geometry of a folded panel, crease chains, and mountain/valley.

What a crease is here: a curve of edges along which the fold angle *jumps* relative to the smooth
bending of the faces beside it. A bare dihedral threshold cannot say that: the facets of a coarse
cylinder bend by 4.5–6.4° per ruling, 1 % vertex noise bends level edges by up to ~8°, and a
crease may fold by anything from a few degrees to nearly 180°. So each interior edge e is compared
with its *parallel neighbours across its two faces* (in a quad, the opposite edge; triangles are
first paired into quads across their longest edge, the diagonal of a triangulated quad):

    jump(e) = |θ_e| − mean(|θ_a|, |θ_b|)        a, b the parallel neighbours (interior ones only)

On a smooth developable strip the parallel neighbours bend like e (jump ≈ 0: the bending changes
slowly across a face), on a crease they bend like the surface beside the crease, not like the
crease (jump ≈ the fold angle). The mean of both sides (not the smaller one) keeps a ruling whose
neighbour on one side happens to bend little (noise, uneven rulings) from looking like a jump; a
crease next to an equal crease one face away still jumps by half its fold.

Noise: vertex noise d tilts a face of width h (area / edge length) by about d / h, so the jump times
h is compared, not the jump: one noise scale then serves long and short faces alike (on a fine
cylinder strip 1 % noise bends the short rulings by ~10° but the long level edges by ~0.3°). The
scale σ_z = 1.4826 · median(jump · h) over the edges with 0 <= jump < `MAX_NOISE_JUMP` (the edges
beside a crease jump down by half its fold, and on a small panel creases may be most of the edges;
0 on exact input). An edge is strong when its jump exceeds `MIN_JUMP` and jump · h exceeds 6 σ_z,
weak above `MIN_JUMP` / 2 and 3 σ_z.

Chains: creases are traced from strong edges (largest jump · h first) through the incident edge that
continues the curve (turning by at most `MAX_TURN`) with the largest jump · h, as long as it is weak
or stronger — hysteresis, so a crease whose fold fades near its end stays one chain. A chain is kept
only when its median edge is strong (a ruling also runs from boundary to boundary, but jumps only by
noise) and both its ends reach the boundary, another kept chain (a junction), or each other (a
closed loop): isolated noisy edges never form such a curve, so they are dropped. Everything above
uses coordinates and comparisons of geometric values only (ties broken by edge midpoint
coordinates), so the result does not depend on vertex or face order.

Mountain/valley: the signed fold angle (FOLD convention, valley +) is unwrapped along each chain
(`numpy.unwrap`), shifted by a whole turn so that its median is in (−180°, 180°], and clipped to
±180°: a crease folded to 177–179.5° whose measured angle flips to −179.9° at one end stays one
assignment.

Narrow panels: where fewer than two interior parallel edges lie across the panel from an edge (strips
one face wide, e.g. a tri-fold with one row of faces per strip), smooth bending cannot be seen, and
the edge is compared with the sides of the faces beside it (the edges that cross it) instead. A
cylinder of three facets is then a tri-fold, which is what its geometry is.

Not handled: a crease that kinks by more than `MAX_TURN` at a vertex is traced as two chains (each
must reach the boundary or a junction).
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from fabkit.measures import dihedral_angles
from fabkit.mesh import PolyMesh

__all__ = ["CreaseDetection", "detect_creases", "chain_edges", "chain_fold_angles", "MIN_JUMP", "MAX_TURN"]

#: A jump of the fold angle below this [rad] never seeds a crease (2°; half of it continues one): round-off
#: on exact input must not decide.
MIN_JUMP = np.radians(2.0)
#: Jumps above this [rad] never count towards the noise scale (10°): on a small panel most edges may
#: be creases, and noise that bends edges by more cannot be told from creases anyway.
MAX_NOISE_JUMP = np.radians(10.0)
#: Strong / weak thresholds in units of the noise scale σ.
STRONG_SIGMA, WEAK_SIGMA = 6.0, 3.0
#: A crease chain turns by at most this much [rad] at one vertex.
MAX_TURN = np.radians(45.0)


@dataclass(frozen=True, eq=False)
class CreaseDetection:
    """Per edge of the mesh: `crease` (E,) bool, `jump` (E,) [rad] (NaN where no neighbour), the
    noise scale `sigma` [rad, on a face of median width], thresholds `strong`/`weak` [rad, the same]
    and the kept `chains` as vertex lists."""

    crease: np.ndarray
    jump: np.ndarray
    sigma: float
    strong: float
    weak: float
    chains: tuple


def _pair_triangles(mesh: PolyMesh) -> tuple[list[list[int]], np.ndarray]:
    """Faces for the analysis: triangles paired into quads across their mutual longest edge.

    Returns (faces, diagonal) where diagonal (E,) marks the mesh edges removed by pairing.
    """
    t = mesh.topology
    E = t.n_edges
    diagonal = np.zeros(E, bool)
    faces = mesh.faces_list()
    tri = np.flatnonzero(t.face_sizes == 3)
    if len(tri) == 0:
        return faces, diagonal
    L = mesh.edge_lengths
    corners = t.face_offsets[tri][:, None] + np.arange(3)
    ce = t.halfedge_edge[corners]                                 # (k, 3) edges of each triangle
    longest = ce[np.arange(len(tri)), np.argmax(L[ce], axis=1)]  # its longest edge
    best_of_face = np.full(t.n_faces, -1, np.int64)
    best_of_face[tri] = longest
    ef = t.edge_faces[longest]
    other = np.where(ef[:, 0] == tri, ef[:, 1], ef[:, 0])
    mutual = (other >= 0) & (best_of_face[np.maximum(other, 0)] == longest) & (tri < other)
    drop = set()
    merged = []
    for f1, f2, e in zip(tri[mutual].tolist(), other[mutual].tolist(), longest[mutual].tolist()):
        a, b = (int(x) for x in t.edges[e])
        p1, p2 = faces[f1], faces[f2]
        # rotate f1 so it runs a -> b (or b -> a), then splice in f2's third vertex
        i = p1.index(a)
        if p1[(i + 1) % 3] != b:
            a, b = b, a
            i = p1.index(a)
        c = p1[(i + 2) % 3]
        d = next(v for v in p2 if v not in (a, b))
        merged.append([b, c, a, d])
        drop.update((f1, f2))
        diagonal[e] = True
    faces = [f for k, f in enumerate(faces) if k not in drop] + merged
    return faces, diagonal


def _neighbour_edges(mesh: PolyMesh, faces: list[list[int]]) -> tuple[np.ndarray, np.ndarray]:
    """Per mesh edge, in the analysis faces beside it: `opposite` (E, 2) the edge that does not touch
    it (the opposite side of a quad; for larger polygons the most anti-parallel such edge), -1 if
    none; `sides` (E, 4) the edges that touch it (a quad's two other sides, per face), -1 if none."""
    t = mesh.topology
    opposite = np.full((t.n_edges, 2), -1, np.int64)
    sides = np.full((t.n_edges, 4), -1, np.int64)
    V = mesh.vertices
    quads = np.array([f for f in faces if len(f) == 4], np.int64).reshape(-1, 4)
    i = np.arange(4)
    cols = [quads[:, (i + k) % 4] for k in range(4)]           # corner i and the three after it
    pairs = [np.stack([cols[0].ravel(), cols[1].ravel()], 1)]
    opp = [np.stack([cols[2].ravel(), cols[3].ravel()], 1)]
    side_a = [np.stack([cols[3].ravel(), cols[0].ravel()], 1)]
    side_b = [np.stack([cols[1].ravel(), cols[2].ravel()], 1)]
    for f in faces:  # larger polygons (rare): the most anti-parallel non-adjacent side
        k = len(f)
        if k < 5:
            continue
        for j in range(k):
            a, b = f[j], f[(j + 1) % k]
            cand = [(f[m], f[(m + 1) % k]) for m in range(k) if m not in (j, (j - 1) % k, (j + 1) % k)]
            d = V[b] - V[a]
            cand.sort(key=lambda uv: float(np.dot(V[uv[1]] - V[uv[0]], d)))
            pairs.append(np.array([[a, b]]))
            opp.append(np.array([cand[0]]))
            side_a.append(np.array([[f[(j - 1) % k], a]]))
            side_b.append(np.array([[b, f[(j + 2) % k]]]))
    e = t.edge_ids(np.concatenate(pairs))
    o, sa, sb = (t.edge_ids(np.concatenate(x)) for x in (opp, side_a, side_b))
    keep = e >= 0
    e, o, sa, sb = e[keep], o[keep], sa[keep], sb[keep]
    order = np.argsort(e, kind="stable")
    es = e[order]
    slot = np.zeros(len(es), np.int64)
    slot[1:] = (es[1:] == es[:-1]).astype(np.int64)          # second face of the same edge -> slot 1
    opposite[es, slot] = o[order]
    sides[es, 2 * slot] = sa[order]
    sides[es, 2 * slot + 1] = sb[order]
    return opposite, sides


def crease_jumps(mesh: PolyMesh, angle: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(jump (E,) [rad], diagonal (E,) bool): see the module docstring. NaN on boundary edges, pairing
    diagonals and edges with no interior neighbour to compare with."""
    t = mesh.topology
    angle = dihedral_angles(mesh) if angle is None else angle
    a = np.abs(angle)
    faces, diagonal = _pair_triangles(mesh)
    opp, sides = _neighbour_edges(mesh, faces)
    interior = ~t.boundary_edge_mask

    def mean_of(nb):
        ok = (nb >= 0) & interior[np.maximum(nb, 0)]
        n = ok.sum(axis=1)
        return np.where(ok, a[np.maximum(nb, 0)], 0.0).sum(axis=1) / np.maximum(n, 1), n

    bg, n = mean_of(opp)
    # parallel run: interior edges one and two faces away across the panel (the second one is the
    # first one's other opposite edge)
    o1 = np.where((opp >= 0) & interior[np.maximum(opp, 0)], opp, -1)
    o2 = np.where(o1 >= 0, opp[np.maximum(o1, 0), 0], -1)
    o2 = np.where((o2 == np.arange(t.n_edges)[:, None]), opp[np.maximum(o1, 0), 1], o2)
    run = (o1 >= 0).sum(axis=1) + ((o2 >= 0) & interior[np.maximum(o2, 0)] & (o1 >= 0)).sum(axis=1)
    side_bg, n_side = mean_of(sides)
    narrow = (run < 2) & (n_side > 0)
    bg = np.where(narrow, side_bg, bg)
    jump = np.where((n > 0) | narrow, a - bg, np.nan)
    jump[t.boundary_edge_mask | diagonal] = np.nan
    return jump, diagonal


def _edge_order(mesh: PolyMesh, score: np.ndarray) -> np.ndarray:
    """Edges by decreasing score, ties by midpoint coordinates (independent of vertex order)."""
    mid = mesh.vertices[mesh.edges].mean(axis=1)
    q = np.round(mid / max(mesh.size, 1e-300) * 1e9)
    return np.lexsort((q[:, 2], q[:, 1], q[:, 0], -np.round(score, 12)))


def detect_creases(mesh: PolyMesh, angle: np.ndarray | None = None) -> CreaseDetection:
    """Crease edges of a folded panel by jump + chain tracing (module docstring)."""
    t = mesh.topology
    E = t.n_edges
    angle = dihedral_angles(mesh) if angle is None else np.asarray(angle, np.float64)
    jump, diagonal = crease_jumps(mesh, angle)
    finite = np.isfinite(jump)
    # vertex noise d tilts a face of width h by d / h: jump x h is noise of the same size on long and
    # short faces, so one noise scale serves every edge direction
    L = np.maximum(mesh.edge_lengths, 1e-300)
    ef = t.edge_faces
    h = (mesh.face_areas[np.maximum(ef[:, 0], 0)] + mesh.face_areas[np.maximum(ef[:, 1], 0)]) / (2 * L)
    z = np.where(finite, jump, 0.0) * h
    # edges beside a crease jump *down* by half its fold, creases jump by their fold: neither is noise
    noise = finite & (jump >= 0) & (jump < MAX_NOISE_JUMP)
    sigma_z = float(1.4826 * np.median(z[noise])) if noise.any() else 0.0
    h_typ = float(np.median(h[finite])) if finite.any() else 1.0
    sigma = sigma_z / h_typ
    strong_edge = finite & (jump > MIN_JUMP) & (z > STRONG_SIGMA * sigma_z)
    # an edge with no interior neighbour to compare with can continue a crease on its own angle
    lone = ~finite & ~t.boundary_edge_mask & ~diagonal
    weak_edge = (finite & (jump > MIN_JUMP / 2) & (z > WEAK_SIGMA * sigma_z)) | (lone & (np.abs(angle) > MIN_JUMP))
    strong = max(STRONG_SIGMA * sigma, MIN_JUMP)
    weak = max(WEAK_SIGMA * sigma, MIN_JUMP / 2)
    score = np.where(finite, z, np.abs(angle) * h)
    score[~weak_edge] = -np.inf
    V = mesh.vertices
    E2 = t.edges
    inc: dict[int, list[int]] = defaultdict(list)
    for e in np.flatnonzero(weak_edge).tolist():
        u, v = E2[e]
        inc[int(u)].append(e)
        inc[int(v)].append(e)
    used = np.zeros(E, bool)
    bnd = t.boundary_vertex_mask
    chains = []

    def walk(start_v: int, via: int) -> list[int]:
        """Vertices from start_v onward, leaving start_v away from edge `via`."""
        path, prev_e, cur = [], via, start_v
        for _ in range(E):
            if bnd[cur] and prev_e != via:
                break
            u, w = E2[prev_e]
            came = V[cur] - V[w if u == cur else u]
            came /= np.linalg.norm(came)
            best, best_s = -1, -np.inf
            for e in inc.get(cur, ()):
                if used[e] or e == prev_e:
                    continue
                x, y = E2[e]
                nxt = y if x == cur else x
                d = V[nxt] - V[cur]
                d /= np.linalg.norm(d)
                if np.arccos(np.clip(came @ d, -1, 1)) > MAX_TURN:
                    continue
                if score[e] > best_s:
                    best, best_s = e, score[e]
            if best < 0:
                break
            used[best] = True
            x, y = E2[best]
            cur = int(y if x == cur else x)
            prev_e = best
            path.append(cur)
            if cur == start_v:
                break
        return path

    for e in _edge_order(mesh, np.where(strong_edge, score, -np.inf)).tolist():
        if not strong_edge[e]:
            break
        if used[e]:
            continue
        used[e] = True
        u, v = (int(x) for x in E2[e])
        fwd = walk(v, e) if not bnd[v] else []
        if fwd and fwd[-1] == u:
            chains.append([u, v] + fwd)       # closed loop
            continue
        back = walk(u, e) if not bnd[u] else []
        chains.append(back[::-1] + [u, v] + fwd)
    def strong_chain(c):
        e = t.edge_ids(np.stack([c[:-1], c[1:]], axis=1))
        return (np.median(np.where(finite[e], jump[e], 0.0)) > MIN_JUMP
                and np.median(np.where(finite[e], z[e], 0.0)) > STRONG_SIGMA * sigma_z)

    chains = [c for c in chains if strong_chain(c)]
    crease = _keep_connected(chains, bnd, E2, t)
    kept = tuple(c for c, k in zip(chains, crease[1]) if k)
    return CreaseDetection(crease=crease[0], jump=jump, sigma=sigma, strong=strong, weak=weak, chains=kept)


def _keep_connected(chains, bnd, edges, t):
    """Keep chains whose ends are boundary vertices, vertices of other kept chains, or each other."""
    keep = [True] * len(chains)
    for _ in range(len(chains) + 1):
        on = defaultdict(int)
        for c, k in zip(chains, keep):
            if k:
                for v in set(c):
                    on[v] += 1
        changed = False
        for i, c in enumerate(chains):
            if not keep[i]:
                continue
            closed = len(c) > 3 and c[0] == c[-1]
            ok = closed or all(bnd[v] or on[v] > 1 for v in (c[0], c[-1]))
            if not ok:
                keep[i] = False
                changed = True
        if not changed:
            break
    mask = np.zeros(t.n_edges, bool)
    for c, k in zip(chains, keep):
        if k:
            mask[t.edge_ids(np.stack([c[:-1], c[1:]], axis=1))] = True
    return mask, keep


def chain_fold_angles(mesh: PolyMesh, chains, angle: np.ndarray) -> np.ndarray:
    """Fold angles (E,) with each chain's angles unwrapped along it, its median shifted into
    (−π, π] and clipped to ±π (module docstring); other edges unchanged."""
    out = np.array(angle, np.float64, copy=True)
    for c in chains:
        e = mesh.topology.edge_ids(np.stack([np.asarray(c[:-1]), np.asarray(c[1:])], axis=1))
        a = np.unwrap(out[e])
        a -= 2 * np.pi * np.round(np.median(a) / (2 * np.pi) - 1e-12)
        out[e] = np.clip(a, -np.pi, np.pi)
    return out


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
