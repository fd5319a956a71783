"""The regrip alternatives (`robot.regrip_choice`): the split order and the score, on made-up
alternatives with known cycle times and clearances (no planner, no check)."""
from types import SimpleNamespace

import numpy as np
import pytest

from robot.planner import PlanningError
from robot.regrip_choice import (CYCLE_TIE_S, REGRIP_CHECKS, Alternative, choose_alternative, pick_alternative,
                                 regrip_splits)


def _frames(turns_deg):
    """Face frames whose z axis turns by `turns_deg` from the first state (about x)."""
    F = np.repeat(np.eye(4)[None], len(turns_deg), axis=0)
    for s, t in enumerate(np.radians(turns_deg)):
        c, n = np.cos(t), np.sin(t)
        F[s, :3, :3] = [[1, 0, 0], [0, c, -n], [0, n, c]]
    return SimpleNamespace(of_face=lambda face: F, n_states=len(F))


@pytest.mark.parametrize("turns,want", [
    ([0.0, 43.8, 87.5, 131.2, 149.6], [2, 3]),      # the one-crease 175 deg panel's grip face
    ([0.0, 30.0, 60.0, 100.0, 175.0], [3, 2]),      # nearest 90 deg first, then the next nearest
    ([0.0, 60.0, 120.0, 175.0], [1, 2]),            # 30 deg off either way: the earlier state first
])
def test_splits_nearest_a_quarter_turn_first_then_the_next(turns, want):
    assert regrip_splits(_frames(turns), 7) == want
    assert regrip_splits(_frames(turns), 7, tried=9) == want + [s for s in range(1, len(turns) - 1) if s not in want]


def _result(cycle, phases=2):
    tp = SimpleNamespace(extra={"phases": [{}] * phases} if phases > 1 else {}, sha256=f"{cycle}-{phases}")
    return SimpleNamespace(cycle_time=cycle, toolpath=tp)


def _alt(name, cycle, phases=2, clearance=None, problem=None, checked=True):
    return Alternative(label=name, face=len(name), plan=None, result=_result(cycle, phases), problem=problem,
                       clearance=clearance, checked=checked)


def test_the_score_fewer_phases_then_cycle_time_then_the_larger_least_clearance():
    fast, slow = _alt("fast", 78.2), _alt("slow", 80.9)
    assert choose_alternative([slow, fast]) is fast
    three = _alt("three phases", 60.0, phases=3)
    assert choose_alternative([three, slow]) is slow                           # fewer phases first
    near = _alt("near", 78.2 + 0.8 * CYCLE_TIE_S, clearance=0.025)
    close = _alt("close", 78.2, clearance=0.012)
    assert choose_alternative([close, near]) is near                           # tied on time: more clearance
    assert choose_alternative([close, _alt("far", 78.2 + 0.8 * CYCLE_TIE_S)]).label == "far"  # none measured: largest
    assert choose_alternative([_alt("a", 79.0), _alt("b", 79.0)]).label == "a"  # then the order given
    assert choose_alternative([close, _alt("late", 78.2 + 2 * CYCLE_TIE_S, clearance=0.03)]) is close
    assert choose_alternative([]) is None


def _pick(spec, checks=REGRIP_CHECKS):
    """pick_alternative over alternatives [(name, cycle, passes or 'plan fails')] with a fake check ->
    (chosen name, names checked in order, tried)."""
    asked = []

    def plan_of(name, cycle, verdict):
        def plan():
            if verdict == "plan fails":
                raise PlanningError(3, "fold", 1, "unreachable", "no joint solution")
            return SimpleNamespace(**vars(_result(cycle)), name=name, passes=verdict)
        return plan

    def accept(res):
        asked.append(res.name)
        return None if res.passes else f"check: {res.name} meets the panel"

    alts = [Alternative(label=n, face=k, plan=plan_of(n, c, v)) for k, (n, c, v) in enumerate(spec)]
    best, tried = pick_alternative(alts, accept=accept, clearance_of=lambda res: None, checks=checks)
    return (best.label if best else None), asked, tried


def test_alternatives_are_checked_in_score_order_and_those_that_cannot_win_are_not():
    best, asked, tried = _pick([("a", 82.9, True), ("b", 79.6, False), ("c", 78.2, True), ("d", 78.5, True),
                                ("e", 77.0, "plan fails"), ("f", 80.0, True)])
    assert best == "c"                         # the fastest that passes, not the first listed that passes
    assert asked == ["c", "d"]                 # d is within the tie window of c; b, f and a are slower
    text = {t.split(" ")[0].rstrip(":"): t for _, t in tried}
    assert set(text) == {"a", "b", "d", "e", "f"}
    assert "passed the check, not chosen: c scores better" in text["d"]
    assert "not checked: it cannot beat c" in text["a"] and "cycle 82.9 s" in text["a"]
    assert "no joint solution" in text["e"]
    assert [t.split(" ")[0].rstrip(":") for _, t in tried] == ["a", "b", "d", "e", "f"]   # in the alternatives' order


def test_the_check_budget_bounds_the_checks_and_nothing_that_fails_is_chosen():
    best, asked, tried = _pick([(n, 70.0 + k, False) for k, n in enumerate("abcdefgh")], checks=3)
    assert best is None and asked == ["a", "b", "c"]
    assert sum("not checked (the first 3 in score order were)" in t for _, t in tried) == 5
    assert all("meets the panel" in t for _, t in tried[:3])
