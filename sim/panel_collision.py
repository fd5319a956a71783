"""Does the folding panel hit the fixture, the table, the obstacles or itself? In every fold state
and between states.

The panel moves as the arm check sees it (`sim.panel.PanelModel`: one thin convex prism per face,
posed rigidly per state, interpolated between states linearly in position and normalised-linearly
in rotation). Between two states the motion is sampled so that no face corner moves more than
`step_m` between samples.

- **Panel vs cell** (MuJoCo): the obstacles as static geoms, the faces as mocap bodies, and one
  explicit contact pair per (face, obstacle): MuJoCo never pairs static and mocap bodies on its
  own, explicit pairs it always tests. The depth is MuJoCo's penetration of the face's prism (sheet
  thickness included) into the obstacle. The clamped face against the obstacle carrying the clamp
  touches by design and is not paired.
- **Panel vs itself** (exact triangles): every face's triangles posed with their face, the
  separating-axis test of `fabkit.refold.intersect` on triangles that share no vertex (neighbours
  always touch). The depth of an intersecting pair is how far the shallower of the two triangles
  pokes through the other's plane (on the side it pokes out less): the distance one would have to
  push it back. Sheet thickness is not modelled here (two faces lying on each other do not count).

Collision depths are in metres; a problem names the pair (`face_12`, `fold_table`) and the first
fractional state where it happens, with the worst depth over the run.
"""
from __future__ import annotations

from dataclasses import dataclass

import sim.gl_backend  # noqa: F401  (MUJOCO_GL before mujoco loads)
import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from fabkit.refold.intersect import neighbour_keys, triangles_intersect
from sim.model import add_primitive

__all__ = ["PanelContact", "PanelCollisionReport", "PanelCollider", "check_panel_collisions", "collider_for_sequence",
           "sample_states", "STEP_M"]

#: Largest face-corner travel between two samples of the motion between states (m).
STEP_M = 0.005
#: Self-contacts shallower than this (m) are touching, not intersecting (round-off of the poses).
TOUCH_TOL = 1e-6


@dataclass(frozen=True)
class PanelContact:
    """One colliding pair: `kind` "obstacle" | "self", `pair` names, `state` the first fractional
    fold state of the run, `last_state`, `depth_m` the worst penetration over the run."""

    kind: str
    pair: tuple[str, str]
    state: float
    last_state: float
    depth_m: float

    def describe(self) -> str:
        where = f"state {self.state:g}" if self.state == self.last_state else \
            f"states {self.state:g}-{self.last_state:g}"
        return f"{where}: collision: {self.pair[0]} x {self.pair[1]}, {self.depth_m * 1000:.1f} mm deep"


@dataclass(frozen=True)
class PanelCollisionReport:
    """`ok` iff no contacts; `samples` fractional states tested; `contacts` worst first per kind."""

    ok: bool
    contacts: tuple[PanelContact, ...]
    samples: int
    states: int

    @property
    def problems(self) -> tuple[str, ...]:
        return tuple(c.describe() for c in self.contacts)


def _tri_local(pieces, tris: np.ndarray, tri_face: np.ndarray) -> np.ndarray:
    """Corner coordinates (T, 3, 3) of every triangle in its face's piece frame."""
    out = np.zeros((len(tris), 3, 3))
    for t, (tri, f) in enumerate(zip(tris, tri_face)):
        ids = pieces.faces[f]
        out[t] = pieces.local_polygons[f][np.searchsorted(ids, tri)]
    return out


class PanelCollider:
    """Set up once for a panel and a cell, then test any fractional state (`contacts_at`).

    `panel`: `sim.panel.PanelModel`; `tris` (T, 3) vertex ids and `tri_face` (T,) piece index of
    each triangle (a panel's faces triangulated; for a FOLD sequence, its triangles and polygon map);
    `obstacles`: `robot.cell.Shape`s in world; `exempt`: (piece index, obstacle name) pairs that
    touch by design (the clamped face on the clamp).
    """

    def __init__(self, panel, tris, tri_face, obstacles, exempt=()):
        self.panel = panel
        self.tris = np.asarray(tris, np.int64)
        self.tri_face = np.asarray(tri_face, np.int64)
        self.local = _tri_local(panel.pieces, self.tris, self.tri_face)
        self.neighbours = neighbour_keys(self.tris)
        self.names = [f"face_{i}" for i in (panel.face_ids or range(len(panel.pieces)))]
        exempt = {(int(f), str(o)) for f, o in exempt}
        spec = mujoco.MjSpec()
        spec.modelname = "panel_collision"
        world = spec.worldbody
        self.obstacle_names = [ob.name for ob in obstacles]
        for ob in obstacles:
            add_primitive(world, ob.name, ob, contype=0, conaffinity=0)
        for f, verts in enumerate(panel.pieces.local_vertices):
            spec.add_mesh(name=f"m{f}", uservert=np.asarray(verts, float).ravel().tolist())
            body = world.add_body(name=f"b{f}", mocap=True)
            body.add_geom(name=self.names[f], type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"m{f}", contype=0,
                          conaffinity=0)
            for ob in obstacles:
                if (f, ob.name) not in exempt:
                    spec.add_pair(geomname1=self.names[f], geomname2=ob.name)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        gnames = [mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(self.model.ngeom)]
        self.geom_names = gnames

    def triangles_at(self, s: float) -> np.ndarray:
        """World triangles (T, 3, 3) at fractional state s."""
        pos, quat = self.panel.poses_at(s)
        R = Rotation.from_quat(quat[:, [1, 2, 3, 0]]).as_matrix()[self.tri_face]
        return np.einsum("tij,tkj->tki", R, self.local) + pos[self.tri_face][:, None, :]

    def obstacle_contacts_at(self, s: float) -> dict:
        """{(face, obstacle): depth} of the colliding face/obstacle pairs at fractional state s."""
        pos, quat = self.panel.poses_at(s)
        d = self.data
        d.mocap_pos[:] = pos
        d.mocap_quat[:] = quat
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_collision(self.model, d)
        n = d.ncon
        worst: dict = {}
        if n == 0:
            return worst
        dist = d.contact.dist[:n]
        geom = d.contact.geom[:n]
        for k in np.flatnonzero(dist < 0):
            a, b = self.geom_names[geom[k, 0]], self.geom_names[geom[k, 1]]
            key = (a, b) if a.startswith("face_") else (b, a)
            worst[key] = max(worst.get(key, 0.0), -float(dist[k]))
        return worst

    def _rigid_pairs(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Mask of triangle pairs whose faces keep their relative pose (1e-9 m) in every state."""
        P, Q = self.panel.pos, self.panel.quat                     # (S, F, 3), (S, F, 4)
        R = Rotation.from_quat(Q.reshape(-1, 4)[:, [1, 2, 3, 0]]).as_matrix().reshape(P.shape[:2] + (3, 3))
        fa, fb = self.tri_face[i], self.tri_face[j]
        uniq, inv = np.unique(np.stack([fa, fb], 1), axis=0, return_inverse=True)
        a, b = uniq[:, 0], uniq[:, 1]
        rel_R = np.einsum("sfji,sfjk->sfik", R[:, a], R[:, b])       # R_a^T R_b per state
        rel_t = np.einsum("sfji,sfj->sfi", R[:, a], P[:, b] - P[:, a])
        size = max(float(np.abs(P).max()), 1.0)
        same = (np.abs(rel_R - rel_R[:1]).max(axis=(0, 2, 3)) <= 1e-9) & \
               (np.abs(rel_t - rel_t[:1]).max(axis=(0, 2)) <= 1e-9 * size)
        return same[inv.ravel()]

    def self_contacts(self, samples) -> list[dict]:
        """Per sample, {(face, face): depth} of intersecting triangles of different faces: bounding
        boxes over every pair of triangles sharing no vertex, then the separating-axis test; pairs
        of faces that keep their relative pose in every state are tested in the first sample only
        (they meet in every sample or in none). Memory and time grow with the square of the
        triangle count (0.1 GB at ~2,000 triangles)."""
        samples = np.asarray(samples, np.float64)
        T = len(self.tris)
        out = [dict() for _ in samples]
        if not hasattr(self, "_pairs"):
            i, j = np.triu_indices(T, 1)
            keep = ~np.isin(i * T + j, self.neighbours) & (self.tri_face[i] != self.tri_face[j])
            i, j = i[keep], j[keep]
            rigid = self._rigid_pairs(i, j)
            self._pairs = (i, j, i[~rigid], j[~rigid])
        i, j, mi, mj = self._pairs
        W = np.stack([self.triangles_at(s) for s in samples])          # (n, T, 3, 3)
        lo, hi = W.min(axis=2), W.max(axis=2)
        found = []
        for k, (a, b) in enumerate([(i, j)] + [(mi, mj)] * (len(samples) - 1)):
            box = np.all((lo[k, a] <= hi[k, b] + TOUCH_TOL) & (lo[k, b] <= hi[k, a] + TOUCH_TOL), axis=1)
            a, b = a[box], b[box]
            hit = triangles_intersect(W[k, a], W[k, b], TOUCH_TOL)
            found += [(k, x, y) for x, y in zip(a[hit], b[hit])]
        tri_sets = W
        for k, a, b in found:
            depth = _poke_depth(tri_sets[k][a], tri_sets[k][b])
            if depth <= TOUCH_TOL:
                continue
            fa, fb = sorted((int(self.tri_face[a]), int(self.tri_face[b])))
            key = (self.names[fa], self.names[fb])
            out[k][key] = max(out[k].get(key, 0.0), depth)
        return out


def _poke_depth(A: np.ndarray, B: np.ndarray) -> float:
    """How far the shallower of two intersecting triangles pokes through the other's plane (m)."""
    def through(P, Q):
        n = np.cross(Q[1] - Q[0], Q[2] - Q[0])
        n /= np.linalg.norm(n)
        d = (P - Q[0]) @ n
        return min(max(d.max(), 0.0), max(-d.min(), 0.0))
    return float(min(through(A, B), through(B, A)))


def sample_states(panel, step_m: float = STEP_M) -> np.ndarray:
    """Fractional states: every state and enough points between so no face corner moves more than
    `step_m` between samples (from the pieces' corner travel)."""
    S = panel.n_states
    out = [0.0]
    if S == 1:
        return np.array(out)
    corners = [np.asarray(v) for v in panel.pieces.local_vertices]
    rad = max(float(np.linalg.norm(c, axis=1).max()) for c in corners)
    for k in range(S - 1):
        dp = np.linalg.norm(panel.pos[k + 1] - panel.pos[k], axis=1)
        q0, q1 = panel.quat[k], panel.quat[k + 1]
        ang = 2 * np.arccos(np.clip(np.abs(np.sum(q0 * q1, axis=1)), 0, 1))
        travel = float((dp + ang * rad).max())
        n = max(1, int(np.ceil(travel / step_m)))
        out += list(k + np.arange(1, n + 1) / n)
    return np.array(out)


def check_panel_collisions(collider: PanelCollider, step_m: float = STEP_M) -> PanelCollisionReport:
    """Test every state and the motion between (module docstring); runs of one pair over
    consecutive samples are one contact with the worst depth."""
    samples = sample_states(collider.panel, step_m)
    selfs = collider.self_contacts(samples)
    runs: dict = {}
    done = []
    for s, self_hits in zip(samples, selfs):
        seen = set()
        hits = [("obstacle", k, v) for k, v in collider.obstacle_contacts_at(float(s)).items()]
        hits += [("self", k, v) for k, v in self_hits.items()]
        for kind, pair, depth in hits:
            key = (kind, pair)
            seen.add(key)
            if key in runs:
                st, _, dmax = runs[key]
                runs[key] = (st, float(s), max(dmax, depth))
            else:
                runs[key] = (float(s), float(s), depth)
        for key in [k for k in runs if k not in seen]:
            st, last, dmax = runs.pop(key)
            done.append(PanelContact(key[0], key[1], st, last, dmax))
    done += [PanelContact(k[0], k[1], st, last, dmax) for k, (st, last, dmax) in runs.items()]
    done.sort(key=lambda c: (c.state, -c.depth_m, c.pair))
    return PanelCollisionReport(ok=not done, contacts=tuple(done), samples=len(samples), states=collider.panel.n_states)


def collider_for_sequence(seq, fixture, obstacles, *, clamp_obstacle: str = "", thickness: float | None = None,
                          resting_faces=()):
    """A `PanelCollider` for a `fabkit.refold.FoldSequence` placed by `fixture` (panel frame -> world):
    one piece per polygon (the distinct vertices of its triangles), the sequence's triangles for the
    self test, and the clamped (fixed) face, and `resting_faces` (polygon ids: faces that never move,
    lying on the clamp with it), exempt against `clamp_obstacle`."""
    from sim.panel import DEFAULT_THICKNESS, panel_model

    tri_face = np.asarray(seq.tri_face, np.int64)
    ids = np.unique(tri_face)
    faces = [np.unique(np.asarray(seq.tris)[tri_face == f]) for f in ids]
    panel = panel_model(seq.flat_vertices, faces, seq.positions, fixture,
                        thickness=DEFAULT_THICKNESS if thickness is None else thickness, face_ids=ids)
    piece = np.searchsorted(ids, tri_face)
    rest = {int(seq.fixed_face)} | {int(f) for f in resting_faces}
    exempt = [(int(np.searchsorted(ids, f)), clamp_obstacle) for f in sorted(rest) if f in set(ids.tolist())] \
        if clamp_obstacle else []
    return PanelCollider(panel, seq.tris, piece, obstacles, exempt)
