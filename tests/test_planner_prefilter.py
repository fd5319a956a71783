"""The planner's bounds skip only branches that cannot win: the reach bound those that cannot plan
and cannot be the failure that got farthest, the travel bound those whose least possible cost
exceeds the best found. With them the toolpaths and the refusals are exactly those of propagating
every branch in order (PATH.json byte for byte, the same PlanningError text)."""
from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from fabkit.frames import middle_row_frames
from fold_fixtures import folded_grid_model
from robot import planner
from robot.cell import parse_cell
from robot.toolpath import PlanningError, plan_toolpath

CELLS = Path(__file__).resolve().parent.parent / "cells"


def _cell(name: str, fixture=None):
    data = tomllib.loads((CELLS / name).read_text())
    if fixture is not None:  # moved, turned as the cell turns it
        data["fixture"]["pose"] = [*fixture, *data["fixture"]["pose"][3:]]
    return parse_cell(data, name)


def _outcome(cell, frames, **kw) -> str:
    try:
        res = plan_toolpath(cell, frames, **kw)
    except PlanningError as exc:
        return f"refused: {exc}"
    return json.dumps(res.toolpath.to_json(), sort_keys=True)


@pytest.fixture(scope="module")
def frames():
    return middle_row_frames(folded_grid_model(n_states=5, angles=[math.radians(60)] * 2, triangulate=True))


# the bench cell's fixture (0.75, -0.25, 1.1) where the grid fold plans, and moved up or out to where
# the fold states, the release or the retract leave the UR5e's reach on some or all branches
CASES = [("ur10e_fold_table.toml", None, "planned"),
         ("ur5e_bench.toml", [0.75, -0.1, 1.3], "planned"),
         ("ur5e_bench.toml", [0.9, -0.1, 1.1], "discontinuous"),
         ("ur5e_bench.toml", [0.9, -0.45, 1.1], "(retract, fold state 4): unreachable"),
         ("ur5e_bench.toml", [1.0, -0.1, 1.1], "(release, fold state 4): unreachable"),
         ("ur5e_bench.toml", [1.0, -0.25, 1.3], "(fold, fold state 2): unreachable")]


@pytest.mark.parametrize("name,fixture,outcome", CASES)
def test_the_reach_bound_changes_no_toolpath_and_no_refusal(name, fixture, outcome, frames, monkeypatch):
    cell = _cell(name, fixture)
    face = int(frames.faces[-1])
    F = frames.of_face(face)
    calls = []
    propagate = planner._propagate

    def counted(*a, **k):
        calls.append(1)
        return propagate(*a, **k)

    monkeypatch.setattr(planner, "_propagate", counted)
    fast = _outcome(cell, F, grip_face=face)
    n_fast = len(calls)
    # every branch propagated in the order of the starts, as without the bound
    monkeypatch.setattr(planner, "reach_bound", lambda model, chain, *a: len(chain))
    monkeypatch.setattr(planner, "travel_bound", lambda *a: -np.inf)
    calls.clear()
    every = _outcome(cell, F, grip_face=face)
    assert fast == every
    assert outcome in fast[:160] or (outcome == "planned" and not fast.startswith("refused"))
    assert n_fast <= len(calls)
    if "unreachable" in outcome:  # the refusal took one propagation where every branch took one each
        assert n_fast == 1 < len(calls)
    if outcome == "planned":  # branches that cannot beat the best were not propagated
        assert n_fast < len(calls)
