"""Do the holds fix the panel? Rigid-panel mobility of a fold state with some faces held.

The model is refold's (`fabkit.refold`): triangles are rigid, every interior triangle edge is a
hinge with its fold angle as the variable, and around every interior vertex the hinge rotations
compose to the identity (loop closure). Diagonals of planar quads (bent less than `PLANAR_QUAD_HOLD_ANGLE`) are locked
(the quads are rigid plates), and so are rulings that stay flat in the target (regions the fold
never bends; an elastic sheet can still sag there, which this model does not cover); `locked` hinges (creases already set, a jig) are locked as well.
Holding a face fixes it in space. Two tests, both per fold state:

1. **Crease cut** (combinatorial, exact): cutting a crease row (all its hinges) splits the panel;
   every side must contain a held face. A side held by nothing is a wing whose only link to the
   holds is the crease itself: the rigid-fold coupling across a crease has more than one solution
   (mirroring the wing across the crease gives a second state with the same holds, exactly on
   reflect panels), and every branch meets at the flat state, so nothing decides where that wing
   goes. This test does not depend on the state and is what names "the other wing's crease".
2. **First-order mobility** (numerical): the rank of `A = [C; H]`, C the loop-closure Jacobian (3
   rows per interior vertex, `fabkit.refold.kinematics.loop_closure`), H the hold rows (6 per held
   face: its twist relative to the first held face, the sum of the hinge twists along the face
   tree; translation rows divided by the panel size so A is dimensionless), over the unlocked hinge
   angles. Nullity 0 proves the held panel rigid (first-order rigidity implies rigidity); the null
   space's hinges are the free hinges. In a flat state every hinge axis lies in one plane, A loses
   rank however the panel is held (flat states are the rigid-fold model's bifurcation points), so
   there only the crease-cut test decides (`HoldReport.flat`).

SVD tolerance `RANK_TOL` = 1e-8 on the singular values of A: the states satisfy loop closure to
1e-13 rad (refold's Newton tolerance), which moves A's singular values by at most about
sqrt(rows) * 1e-13 ~ 1e-11 (Weyl); the smallest genuine singular value measured on the demo's
tri-fold is 1.0e-3 at the first state after flat (1/11 of the fold) and grows with the fold, and
it scales roughly with the fold angle, so states folded by less than ~1e-6 rad count as flat
(`FLAT_STATE_ANGLE`).

Crease rows come from the panel's strip tags through `crease_rows` (one narrow function, so a
panel-structure module can replace it). Positions and the face tree are refold's
(`fabkit.refold.geometry`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from fabkit.mesh import MeshTopology
from fabkit.refold.geometry import build_face_tree, vertex_positions
from fabkit.refold.kinematics import build_vertex_loops, loop_closure

__all__ = ["HoldModel", "HoldReport", "SecondState", "crease_rows", "hold_analysis", "holds_along", "second_state",
           "RANK_TOL", "FLAT_STATE_ANGLE", "MOTION_TOL", "PLANAR_DIAGONAL_ANGLE", "PLANAR_QUAD_HOLD_ANGLE"]

#: Singular values of the dimensionless hold matrix at or below this count as zero (module docstring).
RANK_TOL = 1e-8
#: A state whose unlocked hinges are all within this of 0 [rad] is flat: first-order test not conclusive.
FLAT_STATE_ANGLE = 1e-6
#: A hinge moves in a free motion when its component in the orthonormal null space exceeds this.
MOTION_TOL = 1e-6
#: Rulings whose target angle is below this [rad] are locked (flat regions; refold's PLANAR_QUAD_ANGLE).
PLANAR_DIAGONAL_ANGLE = 1e-9
#: A quad diagonal whose target angle is below this [rad] is locked: the quad is a planar plate (relax
#: leaves diagonals bent by ~1e-8 rad at its 1e-8 planarity tolerance; 1e-6 rad over a 0.1 m quad
#: is 0.1 um out of plane, far below any fold).
PLANAR_QUAD_HOLD_ANGLE = 1e-6


def crease_rows(edge_crease: np.ndarray, edge_kind: np.ndarray) -> dict[int, np.ndarray]:
    """Crease row k -> its hinge ids, from refold's per-edge crease row (strip tags). Empty without tags."""
    ec = np.asarray(edge_crease)
    kind = np.asarray(edge_kind)
    crease = (kind == "crease") if kind.dtype.kind in "US" else (kind == 1)
    rows = {}
    for k in np.unique(ec[crease & (ec >= 0)]):
        rows[int(k)] = np.flatnonzero(crease & (ec == k))
    return rows


@dataclass(frozen=True, eq=False)
class HoldModel:
    """The static part of the hold analysis of one triangulated panel (built once, any state).

    `flat_vertices` (n, 3), `tris` (t, 3), `tri_face` polygon of each triangle, `edges` (E, 2) as
    the triangle topology's, `hinges` unlocked hinge ids (the columns of A), `rows` crease rows,
    `panel_size` (m, for the translation rows), `root` the face tree's root triangle.
    """

    flat_vertices: np.ndarray
    tris: np.ndarray
    tri_face: np.ndarray
    topology: MeshTopology
    loops: object
    tree: object
    hinges: np.ndarray
    locked: np.ndarray
    rows: dict
    panel_size: float

    @property
    def edges(self) -> np.ndarray:
        return self.topology.edges

    @classmethod
    def from_sequence(cls, seq, locked=(), *, lock_flat_rulings: bool = True) -> "HoldModel":
        """From a `fabkit.refold.FoldSequence`; `locked` extra hinge ids held at their angle.

        `lock_flat_rulings`: rulings whose target angle is 0 (flat regions, which the fold never
        bends) are locked like the planar quads' diagonals; False keeps every ruling a hinge (a flat
        wing then flaps about every straight line of mesh edges across it)."""
        tris = np.asarray(seq.tris, np.int64)
        V = np.asarray(seq.flat_vertices, np.float64)
        topo = MeshTopology(tris.ravel(), np.arange(0, 3 * len(tris) + 1, 3), len(V))
        if not np.array_equal(topo.edges, np.asarray(seq.edges)):
            raise ValueError("the sequence's edges do not match its triangles")
        kind = np.asarray(seq.edge_kind)
        hinge = kind != "boundary"
        diag = np.flatnonzero(kind == "diagonal")
        lock = set(int(e) for e in locked)
        # each quad planar to well within relax's tolerance is a rigid plate: its diagonal is locked
        lock |= set(diag[np.abs(np.asarray(seq.target_angles)[diag]) <= PLANAR_QUAD_HOLD_ANGLE].tolist())
        if lock_flat_rulings:
            target = np.abs(np.asarray(seq.target_angles))
            lock |= set(np.flatnonzero((kind == "ruling") & (target <= PLANAR_DIAGONAL_ANGLE)).tolist())
        lock_arr = np.array(sorted(lock), np.int64)
        hinges = np.setdiff1d(np.flatnonzero(hinge), lock_arr)
        return cls(flat_vertices=V, tris=tris, tri_face=np.asarray(seq.tri_face, np.int64), topology=topo,
                   loops=build_vertex_loops(topo, V), tree=build_face_tree(topo, V, int(seq.fixed_triangle)),
                   hinges=hinges, locked=lock_arr,
                   rows=crease_rows(seq.edge_crease if seq.edge_crease is not None else np.full(len(kind), -1),
                                    kind),
                   panel_size=float(seq.panel_size))

    def with_locked(self, extra) -> "HoldModel":
        """The same model with more hinges locked (creases set in an earlier phase)."""
        lock = np.union1d(self.locked, np.asarray(list(extra), np.int64))
        return HoldModel(self.flat_vertices, self.tris, self.tri_face, self.topology, self.loops, self.tree,
                         np.setdiff1d(self.hinges, lock), lock, self.rows, self.panel_size)

    def crease_name(self, row: int) -> str:
        pairs = [tuple(int(x) for x in self.edges[e]) for e in self.rows[row][:3]]
        more = ", ..." if len(self.rows[row]) > 3 else ""
        return f"crease {row} (edges {', '.join(map(str, pairs))}{more})"

    def triangles_of(self, faces) -> np.ndarray:
        faces = np.asarray(list(faces), np.int64)
        bad = faces[~np.isin(faces, self.tri_face)]
        if len(bad):
            raise ValueError(f"face {int(bad[0])} is not a face of the panel")
        return np.flatnonzero(np.isin(self.tri_face, faces))


@dataclass(frozen=True)
class SecondState:
    """Another rigid-fold state with the same holds, for an unheld crease `row`: Newton from the wing
    unfolded (the crease at 0) with everything outside the wing fixed. `exact` when its loop
    residual is at Newton's tolerance; `residual` [rad] otherwise says how far it misses;
    `wing_move_m` largest vertex distance from the given state; `crease_deg` (min, max) of the
    crease's angles there."""

    row: int
    exact: bool
    residual: float
    wing_move_m: float
    crease_deg: tuple[float, float]

    def describe(self) -> str:
        lo, hi = self.crease_deg
        where = f"crease {self.row} at {lo:.1f}..{hi:.1f} deg, the wing {self.wing_move_m * 1000:.0f} mm away"
        if self.exact:
            return f"a second state with the same holds: {where} (loop residual {self.residual:.1g} rad)"
        return f"the nearest other state found: {where}, missing loop closure by {self.residual:.2g} rad"


@dataclass(frozen=True)
class HoldReport:
    """Verdict for one state: `ok` iff no crease is unheld and (unless `flat`) nullity is 0.

    `unheld_creases` crease rows with a side held by nothing; `free_creases` crease rows with a hinge
    in a first-order free motion; `free_hinges` those hinge ids; `rank`/`nullity`/`columns` of A;
    `sigma_min` the smallest singular value above the tolerance (how firmly held), `sigma_zero` the
    largest one counted as zero; `problems` one line each, naming the crease.
    """

    ok: bool
    held_faces: tuple[int, ...]
    unheld_creases: tuple[int, ...]
    free_creases: tuple[int, ...]
    free_hinges: tuple[int, ...]
    rank: int
    nullity: int
    columns: int
    sigma_min: float
    sigma_zero: float
    flat: bool
    problems: tuple[str, ...]
    second_states: tuple[SecondState, ...] = ()

    def to_json(self) -> dict:
        return {"ok": self.ok, "held_faces": list(self.held_faces), "unheld_creases": list(self.unheld_creases),
                "free_creases": list(self.free_creases), "free_hinges": list(self.free_hinges), "rank": self.rank,
                "nullity": self.nullity, "columns": self.columns, "sigma_min": self.sigma_min,
                "sigma_zero": self.sigma_zero, "flat": self.flat, "problems": list(self.problems),
                "second_states": [{"crease": x.row, "exact": x.exact, "residual_rad": x.residual,
                                   "wing_move_m": x.wing_move_m, "crease_deg": list(x.crease_deg)}
                                  for x in self.second_states]}


def unheld_creases(model: HoldModel, held_tris: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """Crease rows (not locked) for which cutting the row leaves a part with no held triangle,
    with that part's polygon ids."""
    t = model.topology
    inner = t.interior_edges
    held = np.zeros(len(model.tris), bool)
    held[held_tris] = True
    out = []
    for row, hinges in sorted(model.rows.items()):
        if np.all(np.isin(hinges, model.locked)):
            continue  # the crease is set: it moves as one piece with its neighbours
        keep = inner[~np.isin(inner, hinges)]
        a, b = t.edge_faces[keep, 0], t.edge_faces[keep, 1]
        g = sp.coo_matrix((np.ones(len(keep)), (a, b)), shape=(len(held), len(held)))
        n, label = connected_components(g, directed=False)
        if n < 2:
            continue
        for c in range(n):
            part = label == c
            if not held[part].any():
                out.append((row, np.unique(model.tri_face[part])))
                break
    return out


def _twist_rows(model: HoldModel, V: np.ndarray, tri: int) -> np.ndarray:
    """(6, E) twist of triangle `tri` relative to the tree root per unit hinge rate: angular rows,
    then translation rows (point velocity at the origin) divided by the panel size."""
    tree = model.tree
    J = np.zeros((6, len(model.edges)))
    f = int(tri)
    while tree.parent[f] >= 0:
        e = tree.parent_edge[f]
        lo, hi = model.edges[e]
        d = V[hi] - V[lo]
        w = tree.sign[f] * d / np.linalg.norm(d)
        J[:3, e] += w
        J[3:, e] += np.cross(V[lo], w) / model.panel_size
        f = tree.parent[f]
    return J


def hold_matrix(model: HoldModel, rho: np.ndarray, held_tris: np.ndarray, V: np.ndarray | None = None) -> np.ndarray:
    """The dense matrix A = [loop closure; holds] over `model.hinges` at hinge angles rho."""
    rho = np.asarray(rho, np.float64)
    if V is None:
        V = vertex_positions(model.tree, model.flat_vertices, rho)
    _, omega = loop_closure(model.loops, rho)
    nv, k = model.loops.edge.shape
    E = len(model.edges)
    C = np.zeros((3 * nv, E))
    live = model.loops.edge >= 0
    vi, ki = np.nonzero(live)
    for c in range(3):
        np.add.at(C, (3 * vi + c, model.loops.edge[vi, ki]), omega[vi, ki, c])
    rows = [C]
    held_tris = np.asarray(held_tris, np.int64)
    ref = _twist_rows(model, V, held_tris[0])
    for t in held_tris[1:]:
        rows.append(_twist_rows(model, V, t) - ref)
    return np.vstack(rows)[:, model.hinges]


def second_state(model: HoldModel, rho, row: int, wing_faces) -> SecondState:
    """Look for another state of the unheld wing `wing_faces` beyond crease `row` with everything else
    (so every held face) where it is: refold's minimum-norm Newton over the crease's and the wing's
    hinges, started with the crease unfolded. A converged result is a certificate that the holds
    do not fix the wing."""
    from fabkit.refold.kinematics import JacobianPattern, MinNormSolver, project_to_constraints

    rho = np.asarray(rho, np.float64)
    wing = np.flatnonzero(np.isin(model.tri_face, np.asarray(wing_faces)))
    ef = model.topology.edge_faces
    inside = np.flatnonzero(np.isin(ef[:, 0], wing) & np.isin(ef[:, 1], wing))
    free = np.union1d(np.intersect1d(inside, model.hinges), model.rows[row])
    guess = rho.copy()
    guess[model.rows[row]] = 0.0
    res = project_to_constraints(model.loops, guess, rho, JacobianPattern(model.loops, free), MinNormSolver("direct"),
                                 tol=1e-13, max_iter=60)
    V0 = vertex_positions(model.tree, model.flat_vertices, rho)
    V1 = vertex_positions(model.tree, model.flat_vertices, res.rho)
    ang = np.degrees(res.rho[model.rows[row]])
    return SecondState(row=int(row), exact=bool(res.converged), residual=float(res.residual),
                       wing_move_m=float(np.linalg.norm(V1 - V0, axis=1).max()),
                       crease_deg=(float(ang.min()), float(ang.max())))


def hold_analysis(model: HoldModel, rho, held_faces, *, tol: float = RANK_TOL,
                  find_second_states: bool = False) -> HoldReport:
    """Do the faces `held_faces` (polygon ids: clamp, each gripper, any jig) fix the panel at hinge
    angles `rho` (E,)? See the module docstring for both tests. `find_second_states`: for every
    unheld crease also look for the other state of its wing (`second_state`) and name it."""
    held_faces = tuple(sorted(set(int(f) for f in held_faces)))
    if not held_faces:
        raise ValueError("no held faces: something must hold the panel")
    rho = np.asarray(rho, np.float64)
    held_tris = model.triangles_of(held_faces)
    problems = []
    cut = unheld_creases(model, held_tris)
    seconds = []
    for row, faces in cut:
        msg = (f"{model.crease_name(row)} is folded by nothing held: faces "
               f"{faces[:6].tolist()}{' ...' if len(faces) > 6 else ''} beyond it hold no clamp, gripper or jig")
        if find_second_states:
            seconds.append(second_state(model, rho, row, faces))
            if seconds[-1].wing_move_m > 1e-6:
                msg += f"; {seconds[-1].describe()}"
        problems.append(msg)
    A = hold_matrix(model, rho, held_tris)
    sv, N = _null_space(A, tol)
    rank = int(np.sum(sv > tol))
    nullity = A.shape[1] - rank
    moving = model.hinges[np.linalg.norm(N, axis=1) > MOTION_TOL] if nullity else np.zeros(0, np.int64)
    free_rows = tuple(r for r, h in sorted(model.rows.items()) if np.isin(h, moving).any())
    flat = bool(np.all(np.abs(rho[model.hinges]) <= FLAT_STATE_ANGLE)) if len(model.hinges) else True
    if nullity and not flat:
        named = ", ".join(model.crease_name(r) for r in free_rows) or f"{len(moving)} rulings"
        problems.append(f"the held panel can still move ({nullity} free motion{'s' if nullity > 1 else ''}, "
                        f"smallest singular value {sv[rank] if rank < len(sv) else 0.0:.2g} <= {tol:g}): "
                        f"{named} free")
    sigma_min = float(sv[rank - 1]) if rank else 0.0
    sigma_zero = float(sv[rank]) if rank < len(sv) else 0.0
    return HoldReport(ok=not problems, held_faces=held_faces, unheld_creases=tuple(r for r, _ in cut),
                      free_creases=free_rows, free_hinges=tuple(int(e) for e in moving), rank=rank,
                      nullity=int(nullity), columns=int(A.shape[1]), sigma_min=sigma_min, sigma_zero=sigma_zero,
                      flat=flat, problems=tuple(problems), second_states=tuple(seconds))


def _null_space(A: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Singular values (padded with zeros to the column count) and an orthonormal null-space basis."""
    if A.shape[1] == 0:
        return np.zeros(0), np.zeros((0, 0))
    # A is tall (rows: loop closures and holds): the thin SVD has the same singular values and, with
    # at least as many rows as columns, all of V; only a wide A needs the full one. The full U of a
    # tall A (rows x rows) was most of a check's time.
    _, s, vt = np.linalg.svd(A, full_matrices=A.shape[0] < A.shape[1])
    sv = np.zeros(A.shape[1])
    sv[:len(s)] = s
    rank = int(np.sum(sv > tol))
    return sv, vt[rank:].T


def holds_along(model: HoldModel, angles, held_faces, *, between: int = 1, tol: float = RANK_TOL):
    """Hold reports at every state of `angles` (S, E) and at `between` points inside every step.

    Between two states the hinge angles are interpolated linearly and put back onto the loop-closure
    manifold by refold's minimum-norm Newton correction (`project_to_constraints` with nothing
    driven), the motion refold's states sample. `held_faces`: one set for all states, or one per
    state (the step s -> s+1 uses the holds of s+1's set that both share). Returns a list of
    `(fractional state, HoldReport)`.
    """
    from fabkit.refold.kinematics import JacobianPattern, MinNormSolver, project_to_constraints

    angles = np.asarray(angles, np.float64)
    S = len(angles)
    per_state = [tuple(h) for h in held_faces] if held_faces and not np.isscalar(next(iter(held_faces))) \
        else [tuple(held_faces)] * S
    if len(per_state) != S:
        raise ValueError(f"{len(per_state)} hold sets for {S} states")
    out = []
    pattern = JacobianPattern(model.loops, model.hinges)
    solver = MinNormSolver("direct")
    for s in range(S):
        out.append((float(s), hold_analysis(model, angles[s], per_state[s], tol=tol)))
        if s + 1 < S:
            both = sorted(set(per_state[s]) & set(per_state[s + 1]))
            for j in range(1, between + 1):
                t = j / (between + 1)
                guess = (1 - t) * angles[s] + t * angles[s + 1]
                res = project_to_constraints(model.loops, guess, guess, pattern, solver, tol=1e-13, max_iter=30)
                rho = res.rho if res.converged else guess
                out.append((s + t, hold_analysis(model, rho, both or per_state[s + 1], tol=tol)))
    return out

