"""The check tests the folding panel against the cell and itself, naming the pair: a wing swept
through the bench and a wing through the other wing fail; blends are planned with a margin."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from refold_panels import letter_fold_pair, straight_crease_pair

from fabkit.refold import refold
from fabkit.refold.export import to_fold_model
from robot.blends import blend_margin_violations
from robot.cell import load_cell
from sim.check_panel_collisions import check_panel_collisions_of_fold

ROOT = Path(__file__).resolve().parent.parent
DEG = np.pi / 180


@pytest.fixture(scope="module")
def cell():
    return load_cell(ROOT / "cells" / "ur5e_bench.toml")


def _fold_model(flat, target, frames):
    middle = int(np.flatnonzero(np.asarray(flat.face_data["strip"]) == np.asarray(flat.face_data["strip"]).max() // 2)[0])
    seq = refold(flat, target, frames=frames, drive="all", fixed_face=middle)
    return seq, to_fold_model(seq)


def test_a_wing_swept_through_the_bench_fails_naming_the_pair(cell):
    seq, model = _fold_model(*straight_crease_pair(-150 * DEG, nx=4, ny=2, size=0.8), 5)
    states = np.concatenate([[0.0, 0.0], np.arange(seq.n_states, dtype=float), [seq.n_states - 1.0]])
    res = check_panel_collisions_of_fold(model, cell, states, (seq.fixed_face,))
    assert not res.ok
    bench = [p for p in res.problems if p.pair[1] == "bench"]
    assert bench and all(p.kind == "panel_collision" for p in bench)
    assert all(p.subject == f"{p.pair[0]} × bench" and "mm deep" in p.detail for p in bench)
    # the first contact lies between two fold states and belongs to the move that reaches it
    first = min((c for c in res.record["contacts"] if c["pair"][1] == "bench"), key=lambda c: c["state"])
    assert first["state"] != round(first["state"])
    assert min(p.waypoint for p in bench) == 2 + int(np.ceil(first["state"]))


def test_a_wing_through_the_other_wing_fails_naming_the_pair(cell):
    seq, model = _fold_model(*letter_fold_pair(175 * DEG), 8)
    res = check_panel_collisions_of_fold(model, cell, np.arange(seq.n_states, dtype=float), (seq.fixed_face,))
    selfs = [c for c in res.record["contacts"] if c["kind"] == "self"]
    assert selfs and not res.ok
    strip = np.asarray(seq.face_data["strip"])
    polys = np.asarray(seq.face_data["polygon"])
    for c in selfs:  # the two outer flaps, never the middle strip
        a, b = (int(n.split("_")[1]) for n in c["pair"])
        assert {int(strip[np.flatnonzero(polys == a)[0]]), int(strip[np.flatnonzero(polys == b)[0]])} == {0, 2}
    assert any("the panel against itself" in p.detail for p in res.problems)


def test_a_clean_fold_passes(cell):
    seq, model = _fold_model(*straight_crease_pair(60 * DEG, nx=4, ny=2, size=0.4), 5)
    res = check_panel_collisions_of_fold(model, cell, np.arange(seq.n_states, dtype=float), (seq.fixed_face,))
    assert res.ok, [p.detail for p in res.problems]
    assert res.record["samples"] > seq.n_states


def test_planned_blends_keep_a_margin(tmp_path):
    import fabkit.pipeline as fk

    folds = fk.refold(fk.unfold(fk.relax(fk.generate("trifold", resolution=6))), frames=4)
    prog = fk.plan(folds, ROOT / "cells" / "ur5e_bench.toml", workdir=tmp_path)
    tp = prog.toolpath
    r = np.array([w.r for w in tp.waypoints])
    assert r.max() > 0 and len(blend_margin_violations(tp.poses[:, :3], r)) == 0
