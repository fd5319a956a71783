"""Which regrip program in phases a one-arm cell runs: the alternatives, their order, their score.

When no single grip passes the check, `robot.phased_planner.with_regrip` compares regrip programs
(`robot.phased_planner.plan_phases`): a regrip per fold step when the FOLD file folds step by step,
and the same-crease regrips. A same-crease regrip folds one face on the front side to an inner
fold state (the split), releases it, and finishes on the back side. Its alternatives
(`same_crease_alternatives`) are every combination of:

- a face of `regrip_faces`: faces that move and hold the panel with the clamp, farthest travel
  first (at most `REGRIP_FACES`);
- a split of `regrip_splits`: the inner states with the grip face's turn from flat nearest a
  quarter turn first, then the next nearest (at most `REGRIP_SPLITS`);
- an approach/retract distance of `REGRIP_APPROACHES` (times the given one).

At most `REGRIP_PLANNED` alternatives are planned, in that order (face, then split, then
approach). Planning one costs about 0.1 s of CPU and checking one 0.5-3 s, so every alternative
is planned and the checks are spent in the order of the score. That order is known before the
check:

1. fewer phases;
2. shorter cycle time. Cycle times within `CYCLE_TIE_S` of the fastest count as equal;
3. the larger least clearance: the check's smallest distance from the arm or tool to the cell's
   obstacles, which it measures out to 20 mm beyond the cell's clearance (`sim.model`; nothing that
   close counts as the largest). Distances to the panel beyond the clearance are not measured, so
   between passing programs this compares the obstacles only;
4. then the shorter cycle time, then the alternatives' order.

The first alternative in score order that passes the check is the best on 1 and 2. The ones tied
with it on cycle time are checked too, for 3. The rest cannot win and are not checked. So the
choice is the one a check of every alternative would make, with at most `REGRIP_CHECKS` checks
(`sim.grip_search.MAX_CHECKS["regrip"]`). `tried` names every alternative compared: its score,
and why it was not chosen.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["Alternative", "choose_alternative", "pick_alternative", "regrip_faces", "regrip_splits",
           "same_crease_alternatives", "REGRIP_FACES", "REGRIP_SPLITS", "REGRIP_APPROACHES", "REGRIP_PLANNED",
           "REGRIP_CHECKS", "CYCLE_TIE_S"]

#: Faces a same-crease regrip tries. On the UR5e bench, for the shuffled one-crease 175 deg panel,
#: only the third face passes: folding the first two past a quarter turn brings the wrist within
#: 7.7-9.0 mm of the clamped strip across the crease.
REGRIP_FACES = 3
#: Split states tried per face: the nearest a quarter turn and the next nearest. On the one-crease
#: 175 deg panels (5 states), the turns are 44, 88 and 131 deg. At 44 deg every back phase met the
#: panel on both one-arm cells.
REGRIP_SPLITS = 2
#: Approach/retract distances tried, as factors of the given one. A wing folded past a quarter turn
#: leans over the arm. A long retract from it swings the elbow into the clamped strip: on the UR5e
#: bench at 131 deg, 0.9x came within 5.2 mm, and 0.6x brought the cup within 8.9 mm of its face.
REGRIP_APPROACHES = (1.0, 0.8)
#: Alternatives planned at most (faces x splits x approaches).
REGRIP_PLANNED = REGRIP_FACES * REGRIP_SPLITS * len(REGRIP_APPROACHES)
#: Alternatives checked at most per plan, in score order. The one-crease 175 deg panel needs 1 on the
#: UR5e bench and 6 on the UR10e fold table (five faster alternatives fail first); each check of a
#: program in phases costs 0.5-3 s of CPU.
REGRIP_CHECKS = 8
#: Cycle times closer than this [s] count as equal; the least clearance decides between them.
CYCLE_TIE_S = 0.5


def regrip_splits(frames, face: int, tried: int = REGRIP_SPLITS) -> list[int]:
    """Inner fold states at which a same-crease regrip of `face` may change side, best first: the
    grip face's normal nearest a quarter turn from the flat state first (the wing stands up: its
    back is open to the arm, and the front grip has not closed it over the cup yet), then the next
    nearest, ties to the earlier state; at most `tried`."""
    F = frames.of_face(face)
    z = F[:, :3, 2]
    turn = np.degrees(np.arccos(np.clip(z @ z[0], -1.0, 1.0)))
    inner = np.arange(1, len(F) - 1)
    order = inner[np.argsort(np.round(np.abs(turn[inner] - 90.0), 9), kind="stable")]
    return [int(s) for s in order[:tried]]


def regrip_faces(fold_model, clamped_faces, count: int = REGRIP_FACES, min_travel: float = 1e-4,
                 tested: int = 6, footprint=None) -> list[int]:
    """Faces (polygon ids) a same-crease regrip grips, best first, at most `count`: faces that move
    (their centroid travels more than `min_travel` [m] over the fold states), farthest travel
    first (the most leverage, and on a bent strip the flattest surroundings toward its free end),
    ties by the final centroid's coordinates (never by face or vertex order), each with the holds
    proven (`fabkit.holds`) in every state with the clamped faces and that face held (the first
    `tested` faces are tried: a panel that one grip cannot hold gets none). With `footprint`
    (`robot.grip_choice.cup_order`) only faces whose cup fits: the check refuses the others, and
    each regrip alternative costs a plan and a check."""
    from fabkit.frames import face_groups, fold_positions
    from fabkit.hold_model_fold import hold_model_from_fold
    from fabkit.holds import holds_along

    g = face_groups(fold_model.faces_vertices, fold_model.faces_data)
    P = fold_positions(fold_model)
    C = np.stack([P[:, v].mean(axis=1) for v in g.vertices], axis=1)          # (S, faces, 3)
    travel = np.linalg.norm(C - C[:1], axis=2).max(axis=0)
    clamped = {int(f) for f in clamped_faces}
    keys = [(-round(float(t), 9), *np.round(C[-1, i], 9).tolist()) for i, t in enumerate(travel)]
    order = [i for i in sorted(range(len(travel)), key=lambda i: keys[i])
             if travel[i] > min_travel and int(g.ids[i]) not in clamped]
    if footprint is not None:   # a regrip on a face the cup does not fit is refused by the check
        order = [i for i in order if footprint(int(g.ids[i])) is None]
    model, angles = hold_model_from_fold(fold_model)
    if len(P) == len(angles) + 1:        # a flat key frame put first (fabkit.frames.fold_positions)
        angles = np.vstack([np.zeros_like(angles[:1]), angles])
    out = []
    for i in order[:tested]:
        held = tuple(sorted(clamped | {int(g.ids[i])}))
        if all(rep.ok for _, rep in holds_along(model, angles, held, between=0)):
            out.append(int(g.ids[i]))
            if len(out) == count:
                break
    return out


@dataclass(frozen=True)
class Alternative:
    """One regrip program to compare: `label` (how `tried` names it), `face` (the first phase's),
    the `plan()` that plans it (-> `robot.planner.PlanResult`, raises `PlanningError`), and once
    planned and checked: `result`, `problem` (None: passed), `clearance` (the check's least
    clearance [m]; None: nothing within its measuring window), `checked`."""

    label: str
    face: int
    plan: object
    result: object = None
    problem: str | None = None
    clearance: float | None = None
    checked: bool = False

    @property
    def phases(self) -> int:
        return len(self.result.toolpath.extra.get("phases", ())) or 1

    @property
    def cycle_time(self) -> float:
        return float(self.result.cycle_time)

    def score_text(self) -> str:
        c = "beyond the check's window" if self.clearance is None else f"{self.clearance * 1e3:.1f} mm"
        return (f"{self.phases} phases, cycle {self.cycle_time:.1f} s"
                + (f", least clearance {c}" if self.checked and self.problem is None else ""))


def _clear(a: Alternative) -> float:
    return math.inf if a.clearance is None else float(a.clearance)


def choose_alternative(passing: list[Alternative]) -> Alternative | None:
    """The best of the alternatives that passed the check, by the score (module docstring): fewer
    phases, then the shorter cycle time with those within `CYCLE_TIE_S` of the fastest equal, then
    the larger least clearance, then the shorter cycle time, then the first listed."""
    if not passing:
        return None
    fewest = min(a.phases for a in passing)
    pool = [a for a in passing if a.phases == fewest]
    fastest = min(a.cycle_time for a in pool)
    tied = [(k, a) for k, a in enumerate(pool) if a.cycle_time <= fastest + CYCLE_TIE_S]
    return min(tied, key=lambda ka: (-_clear(ka[1]), ka[1].cycle_time, ka[0]))[1]


def pick_alternative(alternatives, *, accept, clearance_of=None, checks: int = REGRIP_CHECKS):
    """Plan every alternative (`Alternative`), check them in score order with `accept(PlanResult)
    -> problem or None` (at most `checks` checks) and choose by the score (module docstring) ->
    (the chosen `Alternative` or None, tried [(face, text)] naming every other alternative with
    its score and why it was not chosen). `clearance_of(PlanResult)`: the least clearance its
    check measured [m] (None: none within the window, or not known)."""
    from robot.planner import PlanningError

    planned, tried = [], []
    for k, alt in enumerate(alternatives):
        try:
            planned.append((k, replace(alt, result=alt.plan())))
        except PlanningError as exc:
            tried.append((k, alt.face, f"{alt.label}: {exc}"))
    ranked = sorted(planned, key=lambda ka: (ka[1].phases, ka[1].cycle_time, ka[0]))
    done, first, spent = [], None, 0
    for k, alt in ranked:
        if first is not None and (alt.phases > first.phases or alt.cycle_time > first.cycle_time + CYCLE_TIE_S):
            done.append((k, alt))        # cannot beat the first that passed: not checked
            continue
        if spent >= checks:
            done.append((k, replace(alt, problem=f"not checked (the first {checks} in score order were)")))
            continue
        spent += 1
        problem = accept(alt.result)
        clearance = clearance_of(alt.result) if clearance_of is not None and problem is None else None
        alt = replace(alt, problem=problem, clearance=clearance, checked=True)
        done.append((k, alt))
        if problem is None and first is None:
            first = alt
    best = choose_alternative([a for _, a in sorted(done, key=lambda ka: ka[0]) if a.checked and a.problem is None])
    for k, alt in done:
        if alt is best:
            continue
        if alt.problem is not None:
            why = alt.problem
        elif alt.checked:
            why = f"passed the check, not chosen: {best.label} scores better ({best.score_text()})"
        else:
            why = f"not checked: it cannot beat {best.label} ({best.score_text()})"
        tried.append((k, alt.face, f"{alt.label} ({alt.score_text()}): {why}"))
    return best, [(f, t) for _, f, t in sorted(tried, key=lambda x: x[0])]


def same_crease_alternatives(cell, frames_of, faces, *, options, source: dict | None = None, clamped_faces=(),
                             placement: dict | None = None, back_standoff: float | None = None) -> list[Alternative]:
    """The same-crease regrips of `faces` (`regrip_faces`; `frames_of(face)` its
    `fabkit.frames.FaceFrames`), in order (module docstring), at most `REGRIP_PLANNED`: front
    0..k then back k..last at each of `regrip_splits`, at each of `REGRIP_APPROACHES`; the back
    side at `back_standoff` (default `options.grip_standoff`)."""
    from robot.phased_planner import PhaseSpec, plan_phases

    standoffs = {"front": options.grip_standoff,
                 "back": options.grip_standoff if back_standoff is None else float(back_standoff)}
    out = []
    for face in faces:
        frames = frames_of(face)
        last = frames.n_states - 1
        for k in regrip_splits(frames, face):
            specs = (PhaseSpec(face, "front", 0, k), PhaseSpec(face, "back", k, last))
            for factor in REGRIP_APPROACHES:
                opt = replace(options, approach_distance=options.approach_distance * factor)
                label = f"regrip front->back at fold state {k}, face {face}, approach {opt.approach_distance * 1e3:.0f} mm"

                def plan(frames=frames, specs=specs, opt=opt, face=face):
                    return plan_phases(cell, frames, specs, options=opt, source={**(source or {}), "grip_face": face},
                                       clamped_faces=clamped_faces, placement=placement, standoffs=standoffs)

                out.append(Alternative(label=label, face=int(face), plan=plan))
    return out[:REGRIP_PLANNED]
