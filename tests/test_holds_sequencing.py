"""Fold plans in which every crease is folded by something held (verified by the holds analysis)."""
from __future__ import annotations

import numpy as np
import pytest
from holds_panels import letter_pair, reflect_two_crease_pair, trifold_pair

from fabkit.errors import InputError
from fabkit.holds import HoldModel, hold_analysis
from fabkit.mesh import PolyMesh
from fabkit.sequencing import fold_plans, plan_fold_sequence


def _middle(flat):
    mid = np.flatnonzero(np.asarray(flat.face_data["middle"]) != 0)
    return {int(np.asarray(flat.face_data["strip"])[f]): int(f) for f in mid}


@pytest.fixture(scope="module")
def trifold_two_arms():
    flat, target = trifold_pair()
    return plan_fold_sequence(flat, target, arms=2, frames=4)


def test_trifold_two_arms_one_per_wing(trifold_two_arms):
    flat, _ = trifold_pair()
    plan = trifold_two_arms
    assert plan.ok and plan.strategy == "together" and plan.regrips == 0
    (ph,) = plan.phases
    mids = _middle(flat)
    assert ph.clamped_faces == (mids[1],) and dict(ph.grips) == {0: mids[0], 1: mids[2]}
    assert ph.creases == (0, 1) and ph.states == (0, plan.sequence.n_states - 1)
    assert all(r.ok for _, r in ph.holds) and len(ph.holds) == 2 * plan.sequence.n_states - 1
    assert plan.held_per_state() == [ph.held_faces] * plan.sequence.n_states


@pytest.mark.slow
def test_trifold_one_arm_has_no_plan_that_holds_every_crease():
    """The tri-fold's curved creases are coupled: folding one crease while the other wing is held
    flat bends the middle strip and moves the held wing, so one arm (with a jig) cannot do it."""
    flat, target = trifold_pair()
    plans = fold_plans(flat, target, arms=1, frames=4)
    assert [p.strategy for p in plans] == ["one crease at a time"]
    assert not plans[0].ok
    assert any("would have to move" in p and "coupled" in p for p in plans[0].problems)
    none = plan_fold_sequence(flat, target, arms=1, frames=4, jig=False)
    assert not none.ok and "needs 2 arms" in none.problems[0] and none.phases == ()


def test_demo_program_in_plan_form_is_refused(trifold_two_arms):
    """The demo's program (clamp + one grip on one outer strip, both creases folding) names crease 0."""
    flat, _ = trifold_pair()
    plan = trifold_two_arms
    model = HoldModel.from_sequence(plan.sequence)
    mids = _middle(flat)
    r = hold_analysis(model, plan.sequence.angles[2], [mids[1], mids[2]])
    assert not r.ok and r.unheld_creases == (0,)


def test_straight_creases_one_arm_regrip_with_a_jig():
    flat, target = letter_pair(120.0)
    plan = plan_fold_sequence(flat, target, arms=1, frames=4)
    assert plan.ok and plan.strategy == "one crease at a time"
    p0, p1 = plan.phases
    assert p0.creases == (0,) and p1.creases == (1,) and p1.set_creases == (0,)
    # a jig holds the strip beyond the other crease in each phase: flat in phase 0, folded in phase 1
    # (a folded crease is a hinge, not locked)
    strip = np.asarray(flat.face_data["strip"])
    assert len(p0.jig_faces) == 1 and len(p1.jig_faces) == 1
    assert int(strip[p0.jig_faces[0]]) == int(strip[dict(p1.grips)[0]])
    assert int(strip[p1.jig_faces[0]]) == int(strip[dict(p0.grips)[0]])
    assert dict(p0.grips)[0] != dict(p1.grips)[0] and plan.regrips == 1
    assert p0.states[1] == p1.states[0]
    assert plan.score == (2, 1, 2)
    # two arms: together, no regrip, scores better
    two = plan_fold_sequence(flat, target, arms=2, frames=4)
    assert two.ok and two.strategy == "together" and two.score < plan.score


@pytest.mark.slow
def test_reflect_two_creases():
    flat, target = reflect_two_crease_pair()
    assert plan_fold_sequence(flat, target, arms=2, frames=3).ok
    seq1 = plan_fold_sequence(flat, target, arms=1, frames=3)
    assert not seq1.ok and any("set in an earlier phase" in p or "coupled" in p for p in seq1.problems)


def _untagged_permuted(mesh, vperm, fperm):
    """`mesh` without tags, its vertices renumbered by `vperm` (new id of old vertex v: vperm[v])
    and its faces in the order `fperm`."""
    V = np.empty_like(mesh.vertices)
    V[vperm] = mesh.vertices
    return PolyMesh(V, [[int(vperm[v]) for v in mesh.faces_list()[f]] for f in fperm])


def test_untagged_permuted_panels_get_the_tagged_plan(trifold_two_arms):
    """Strips, crease rows and the middle row come from `fabkit.structure`: a plain panel (no tags,
    vertices and faces shuffled) gets the tagged panel's plan, face for face."""
    flat, target = trifold_pair()
    rng = np.random.default_rng(7)
    vperm, fperm = rng.permutation(flat.n_vertices), rng.permutation(flat.n_faces)
    plan = plan_fold_sequence(_untagged_permuted(flat, vperm, fperm), _untagged_permuted(target, vperm, fperm),
                              arms=2, frames=4)
    assert plan.ok and plan.strategy == trifold_two_arms.strategy == "together"
    (ours,), (tagged,) = plan.phases, trifold_two_arms.phases
    assert [int(fperm[f]) for f in ours.clamped_faces] == list(tagged.clamped_faces)
    assert sorted(int(fperm[f]) for _, f in ours.grips) == sorted(f for _, f in tagged.grips)
    assert ours.creases == tagged.creases


def test_refuses_panels_without_creases_and_bad_arms():
    flat, target = letter_pair(120.0)
    plain = PolyMesh(flat.vertices, flat.faces_list())
    with pytest.raises(InputError, match="no crease rows"):
        plan_fold_sequence(plain, plain)  # flat onto flat: nothing to fold, no crease to find
    with pytest.raises(ValueError, match="arms"):
        plan_fold_sequence(flat, target, arms=3)


def test_cup_footprint_picks_the_grip_regions(trifold_two_arms):
    """With the 70 mm cup the grips go to faces under the disc of each outer strip's planar region."""
    flat, target = trifold_pair()
    plan = plan_fold_sequence(flat, target, arms=2, frames=4, cup_radius=0.035)
    assert plan.ok
    strip = np.asarray(flat.face_data["strip"])
    grips = dict(plan.phases[0].grips)
    assert {int(strip[grips[0]]), int(strip[grips[1]])} == {0, 2}
    huge = plan_fold_sequence(flat, target, arms=2, frames=4, cup_radius=0.2)
    assert not huge.ok and any("no face region for the 400 mm cup" in p for p in huge.problems)


def test_permuted_faces_give_the_same_plan():
    flat, target = letter_pair(120.0)
    rng = np.random.default_rng(5)
    order = rng.permutation(flat.n_faces)
    fd = {k: np.asarray(v)[order] for k, v in flat.face_data.items()}
    faces = [flat.face(int(f)).tolist() for f in order]
    pf, pt = PolyMesh(flat.vertices, faces, face_data=fd), PolyMesh(target.vertices, faces, face_data=fd)
    a = plan_fold_sequence(flat, target, arms=1, frames=3)
    b = plan_fold_sequence(pf, pt, arms=1, frames=3)
    assert a.ok and b.ok and len(a.phases) == len(b.phases)
    for pa, pb in zip(a.phases, b.phases):
        assert pa.creases == pb.creases
        assert [int(order[f]) for f in pb.clamped_faces] == list(pa.clamped_faces)
        assert [(arm, int(order[f])) for arm, f in pb.grips] == list(pa.grips)
