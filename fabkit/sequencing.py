"""Fold plans in which every crease is folded by something held: phases, clamps, grips, regrips.

A plan is a list of phases over one refold sequence (`fabkit.refold` schedules with steps). A
phase folds some crease rows; in it the clamp (and any jig) holds faces fixed, each arm holds one
face, creases folded in earlier phases keep their angles and creases not yet folded stay flat.
Neither is assumed to hold itself: a folded crease is not locked in the hold model (a scored
crease is a hinge), and a wing lying still is not held by its weight, so the strip beyond every
crease the phase does not fold is held by a jig (flat, or where the strip lies folded) or an arm. Every state of every phase and the motion
between states must pass `fabkit.holds` with the phase's held faces, the clamped faces must stay
where they are (they are fixed in the world: refold's states are in the main clamp's frame, so the
other clamped faces must not move), and set creases must keep their angles. Two ways are tried:

- **together**: one phase, the clamp on its strip and one arm on every other strip; needs as many
  arms as strips beyond the clamp's (two for a tri-fold);
- **one crease at a time** (regrip): a phase per crease row, outward from the clamp; an arm grips the
  strip beyond the crease it folds, and every strip beyond another crease (still flat, or folded
  in an earlier phase) is held too: by a jig (`jig=True`) or by the other arm ("one holds while
  the other folds"). Curved creases couple:
  folding one bends the strip between and moves the next, so a flat-held neighbour is moved, and
  the phase fails naming it.

Plans are scored by (phases, regrips, jig holds); the planner's reachability, clearance and cycle
time come on top of this later. Strips, crease rows and the middle row come from the panel
structure (`fabkit.structure`: tags where the panel has them, else inferred from the target), so an
untagged panel is planned like a tagged one.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fabkit.errors import InputError
from fabkit.holds import HoldModel, holds_along
from fabkit.placement import choose_clamp_face
from fabkit.refold import RefoldSolver
from fabkit.refold.sequence import build_schedule

__all__ = ["Phase", "FoldPlan", "plan_fold_sequence", "fold_plans", "CLAMP_MOTION_TOL", "SET_ANGLE_TOL"]

#: A clamped face may move this much [m] during a phase (round-off of refold's states).
CLAMP_MOTION_TOL = 1e-6
#: A set crease may change its angle this much [rad] during a later phase.
SET_ANGLE_TOL = 1e-6


@dataclass(frozen=True)
class Phase:
    """One phase: crease rows folded, faces clamped (clamp and jigs), `grips` ((arm, face), ...),
    `states` (first, last) state indices of the plan's sequence, `set_creases` locked rows, per-state
    and between-state hold reports `holds` ((fractional state, HoldReport), ...), `clamp_motion_m`
    how far a clamped face moves, `problems`."""

    creases: tuple[int, ...]
    clamped_faces: tuple[int, ...]
    grips: tuple[tuple[int, int], ...]
    states: tuple[int, int]
    set_creases: tuple[int, ...]
    jig_faces: tuple[int, ...] = ()
    holds: tuple = ()
    clamp_motion_m: float = 0.0
    problems: tuple[str, ...] = ()

    @property
    def held_faces(self) -> tuple[int, ...]:
        return tuple(sorted(set(self.clamped_faces) | {f for _, f in self.grips}))

    @property
    def ok(self) -> bool:
        return not self.problems


@dataclass(frozen=True, eq=False)
class FoldPlan:
    """A fold plan: `strategy` ("together" | "one crease at a time"), `arms`, `phases`, `sequence`
    (the `FoldSequence` all phases index), `regrips` arm grip changes between phases, `score`
    (phases, regrips, jig holds; lower is better), `ok` iff every phase is, `problems`."""

    strategy: str
    arms: int
    phases: tuple[Phase, ...]
    sequence: object
    regrips: int
    score: tuple
    problems: tuple[str, ...] = field(default_factory=tuple)

    @property
    def ok(self) -> bool:
        return not self.problems

    def held_per_state(self) -> list[tuple[int, ...]]:
        """Held faces (clamp, jigs, grips) in each state of the sequence (the later phase at a boundary)."""
        if self.sequence is None:
            return []
        out = [()] * self.sequence.n_states
        for ph in self.phases:
            for s in range(ph.states[0], ph.states[1] + 1):
                out[s] = ph.held_faces
        return out

    def to_json(self) -> dict:
        return {"strategy": self.strategy, "arms": self.arms, "ok": self.ok, "regrips": self.regrips,
                "score": list(self.score), "problems": list(self.problems),
                "phases": [{"creases": list(p.creases), "clamped_faces": list(p.clamped_faces),
                            "jig_faces": list(p.jig_faces), "grips": {str(a): f for a, f in p.grips},
                            "states": list(p.states), "set_creases": list(p.set_creases),
                            "clamp_motion_m": p.clamp_motion_m, "problems": list(p.problems)}
                           for p in self.phases]}


def _crease_rows(panel) -> dict:
    """{crease row k: hinge ids} of refold's triangulated panel (rows from `fabkit.structure`)."""
    return {int(k): np.flatnonzero((panel.edge_kind == 1) & (panel.edge_crease == k))
            for k in np.unique(panel.edge_crease[panel.edge_crease >= 0])}


def _face_in_strip(flat, strip: np.ndarray, k: int, choose) -> int:
    """`choose(faces)` if given and it picks one, else the strip's middle-row face nearest the panel's
    centroid (any face without tags), ties by coordinates: independent of vertex and face order."""
    faces = np.flatnonzero(strip == k)
    if choose is not None:
        f = choose(faces)
        if f is not None:
            return int(f)
    return choose_clamp_face(flat, strip=k)


def _verify(plan_phases, seq, model: HoldModel, rows: dict, between: int) -> list[Phase]:
    out = []
    for ph in plan_phases:
        a, b = ph.states
        problems = list(ph.problems)   # set creases are hinges, not locked: what holds them is in the held faces
        reports = holds_along(model, seq.angles[a:b + 1], ph.held_faces, between=between)
        reports = tuple((a + s, r) for s, r in reports)
        bad = [(s, r) for s, r in reports if not r.ok]
        if bad:
            s, r = bad[0]
            problems.append(f"state {s:g}: {r.problems[0]}")
        motion = 0.0
        for f in ph.clamped_faces:
            verts = np.unique(seq.tris[seq.tri_face == f])
            P = seq.positions[a:b + 1][:, verts]
            moved = float(np.linalg.norm(P - P[:1], axis=2).max())
            motion = max(motion, moved)
            if moved > CLAMP_MOTION_TOL:
                who = "jig" if f in ph.jig_faces else "clamp"
                problems.append(f"the {who} on face {f} would have to move "
                                f"{moved * 1000:.1f} mm while "
                                f"{', '.join(f'crease {r}' for r in ph.creases)} folds (the creases are coupled)")
        for r in ph.set_creases:
            change = float(np.abs(seq.angles[a:b + 1][:, rows[r]] - seq.angles[a][rows[r]]).max())
            if change > SET_ANGLE_TOL:
                problems.append(f"crease {r}, set in an earlier phase, would have to move {np.degrees(change):.2f} deg")
        diag = model.locked[np.asarray(seq.edge_kind)[model.locked] == "diagonal"]
        bend = float(np.abs(seq.angles[a:b + 1][:, diag]).max()) if len(diag) else 0.0
        if bend > SET_ANGLE_TOL:
            problems.append(f"the quads would have to bend along their diagonals by up to {np.degrees(bend):.2f} deg "
                            "(no fold of rigid quads does this)")
        if not np.all(seq.converged[a:b + 1]):
            problems.append("refold found no rigid fold state for this phase")
        out.append(Phase(ph.creases, ph.clamped_faces, ph.grips, ph.states, ph.set_creases, ph.jig_faces,
                         reports, motion, tuple(problems)))
    return out


def fold_plans(flat, target, *, arms: int = 1, clamp_face: int | None = None, frames: int = 12, jig: bool = True,
               choose_face=None, cup_radius: float | None = None, between: int = 1,
               first_ok: bool = False) -> list[FoldPlan]:
    """Every plan strategy that fits `arms` (module docstring), verified, best score first.
    `first_ok`: stop at the first plan that holds (strategies are tried best score first).
    `cup_radius` [m]: grip and jig faces are where the cup's disc fits on a planar region of the strip
    in every state (`fabkit.grip_footprint`, best-ranked region); a strip with none fails the plan.

    `choose_face(faces) -> face or None`: picks the grip/jig face among a strip's faces (e.g. the best
    cup region from `fabkit.grip_footprint`); default the strip's middle-row face.
    """
    if arms not in (1, 2):
        raise ValueError(f"arms must be 1 or 2, got {arms}")
    from fabkit.structure import pair_structure

    structure = pair_structure(flat, target)  # strips and middle row: tagged, or inferred from the target
    flat = structure.with_tags(flat)           # as tags 0..k-1, which the face choices below read
    if clamp_face is None:
        clamp_face = choose_clamp_face(flat)   # order-independent (refold's default takes the first tagged)
    solver = RefoldSolver(flat, target, fixed_face=clamp_face, structure=structure)
    strip, rows = np.asarray(solver.structure.strip, np.int64), _crease_rows(solver.panel)
    if not rows:
        raise InputError("the panel has no crease rows to fold", source="FLAT")
    clamp = solver.fixed_face
    cs = int(strip[clamp])
    driven, _ = solver.driven_hinges("middle-row")  # the middle row's creases, tagged or inferred (as refold)
    pick = {k: _face_in_strip(flat, strip, k, choose_face) for k in np.unique(strip)}
    cup_problems: list[str] = []
    if cup_radius is not None:
        pick, cup_problems = _cup_picks(solver, flat, strip, driven, frames, cup_radius, pick)
    plans = []
    others = [int(k) for k in np.unique(strip) if k != cs]
    # together: every strip beyond the clamp's held by an arm
    if len(others) <= arms:
        F, st = build_schedule(solver.panel, driven, None, frames)
        seq = solver.solve(F, driven, st)
        ph = Phase(tuple(sorted(rows)), (clamp,), tuple((a, pick[k]) for a, k in enumerate(others)),
                   (0, seq.n_states - 1), ())
        plans.append(_plan("together", arms, [ph], seq, solver, rows, between))
        if first_ok and plans[-1].ok and not cup_problems:
            return plans
    # one crease at a time, outward from the clamp
    order = sorted(rows, key=lambda r: (min(abs(r - cs), abs(r + 1 - cs)), r))
    steps = [driven[np.isin(driven, rows[r])] for r in order]
    if all(len(g) for g in steps) and (jig or arms == 2 or len(order) == 1):
        F, st = build_schedule(solver.panel, driven, steps, frames)
        seq = solver.solve(F, driven, st)
        phases, done = [], []
        for g, r in enumerate(order):
            s_idx = np.flatnonzero(seq.step == g)
            if len(s_idx) == 0:
                break
            first = int(s_idx[0]) - 1
            beyond = r + 1 if cs <= r else r              # the strip on the far side of crease r
            other_rows = [q for q in order if q != r]      # still flat, or folded in an earlier phase
            hold = sorted({(q + 1 if cs <= q else q) for q in other_rows})
            grips = [(0, pick[beyond])]
            jigs = []
            for k in hold:
                if arms == 2 and len(grips) < 2:
                    grips.append((1, pick[k]))
                else:
                    jigs.append(pick[k])
            phases.append(Phase((r,), tuple([clamp] + jigs), tuple(grips), (first, int(s_idx[-1])), tuple(done),
                                tuple(jigs)))
            done.append(r)
        plans.append(_plan("one crease at a time", arms, phases, seq, solver, rows, between))
    if cup_problems:
        plans = [FoldPlan(p.strategy, p.arms, p.phases, p.sequence, p.regrips, p.score,
                          p.problems + tuple(cup_problems)) for p in plans]
    if not plans:
        need = len(others)
        plans.append(FoldPlan("none", arms, (), None, 0, (0, 0, 0),
                              (f"{len(rows)} creases and {arms} arm{'s' if arms > 1 else ''} without a jig: folding "
                               f"them together needs {need} arms, one at a time needs a jig or a second arm to "
                               "hold the strips still flat",)))
    plans.sort(key=lambda p: (not p.ok, p.score))
    return plans


def _cup_picks(solver, flat, strip, driven, frames, cup_radius, pick):
    """Grip face per strip from the cup footprint on the all-together fold states."""
    from fabkit.grip_footprint import grip_candidates

    F, st = build_schedule(solver.panel, driven, None, frames)
    seq = solver.solve(F, driven, st, check_intersections=False)
    out, problems = dict(pick), []
    for k in pick:
        faces = np.flatnonzero(strip == k)
        cands = grip_candidates(seq, cup_radius, faces=faces)
        good = [c for c in cands if c.ok and c.face in faces]
        if good:
            out[k] = good[0].face
        else:
            why = cands[0].problem if cands else "no face"
            problems.append(f"strip {k} has no face region for the {2000 * cup_radius:.0f} mm cup: {why}")
    return out, problems


def _plan(strategy, arms, phases, seq, solver, rows, between) -> FoldPlan:
    model = HoldModel.from_sequence(seq)
    phases = _verify(phases, seq, model, rows, between)
    regrips = 0
    for p, q in zip(phases, phases[1:]):
        a, b = dict(p.grips), dict(q.grips)
        regrips += sum(1 for arm in b if a.get(arm) != b[arm])
    jigs = sum(len(p.jig_faces) for p in phases)
    problems = tuple(f"phase {i} ({', '.join(f'crease {r}' for r in p.creases)}): {msg}"
                     for i, p in enumerate(phases) for msg in p.problems)
    if seq.n_states < 1 + len(phases) or not np.all(seq.converged):
        problems += ("refold did not reach the target along this schedule",)
    return FoldPlan(strategy, arms, tuple(phases), seq, regrips, (len(phases), regrips, jigs), problems)


def plan_fold_sequence(flat, target, *, arms: int = 1, **options) -> FoldPlan:
    """The best verified plan for `arms` (see `fold_plans`); when none holds every crease, the best
    failing one (its `problems` say why)."""
    return fold_plans(flat, target, arms=arms, first_ok=True, **options)[0]
