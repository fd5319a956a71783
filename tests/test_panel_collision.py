"""The folding panel against the table, the fixture, the obstacles and itself, in and between states."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from refold_panels import letter_fold_pair, straight_crease_pair

from fabkit.placement import place_on_clamp
from fabkit.refold import refold
from robot.cell import Shape, load_cell
from sim.panel_collision import check_panel_collisions, collider_for_sequence, sample_states

ROOT = Path(__file__).resolve().parent.parent
DEG = np.pi / 180


@pytest.fixture(scope="module")
def cell():
    return load_cell(ROOT / "cells" / "ur5e_bench.toml")


def _on_clamp(cell, angle, size=0.8):
    flat, target = straight_crease_pair(angle, nx=4, ny=2, size=size)
    seq = refold(flat, target, frames=5, drive="all")
    fx = place_on_clamp(flat.vertices, flat.face(seq.fixed_face), cell.clamp.pose, flat.vertices.mean(0))
    return seq, collider_for_sequence(seq, fx, cell.obstacles, clamp_obstacle=cell.clamp.obstacle)


def test_a_wing_folding_down_through_the_bench_is_named(cell):
    """A 0.4 m wing folded 150 deg down (mountain) about a crease 0.30 m above the bench top."""
    seq, col = _on_clamp(cell, -150 * DEG)
    r = check_panel_collisions(col)
    assert not r.ok
    bench = [c for c in r.contacts if c.pair[1] == "bench"]
    assert bench and all(c.kind == "obstacle" for c in bench)
    # the tip of the 0.4 m wing reaches 0.10 m below the bench top (at 90 deg): depth 0.1 m less
    # what the prism's half thickness and the tip's position within the face allow
    worst = max(c.depth_m for c in bench)
    assert 0.05 < worst <= 0.1 + 1e-3
    # the bench is entered between states 1 (37.5 deg) and 2 (75 deg): the tip reaches the top at 48.6 deg
    first = min(c.state for c in bench)
    assert 1.0 < first < 2.0 and first != round(first)
    assert any("x bench" in p and "mm deep" in p for p in r.problems)


def test_a_clean_fold_passes_and_the_clamped_face_may_sit_on_its_post(cell):
    seq, col = _on_clamp(cell, 60 * DEG)
    r = check_panel_collisions(col)
    assert r.ok, r.problems
    assert r.samples > seq.n_states                        # the motion between states is sampled
    # without the exemption the clamped face touches the post it sits on
    strict = collider_for_sequence(seq, _fixture(cell, seq), cell.obstacles)
    hits = check_panel_collisions(strict).contacts
    assert {c.pair for c in hits} == {(f"face_{seq.fixed_face}", "fixture_post")}


def _fixture(cell, seq):
    flat_v = seq.flat_vertices
    ring = np.unique(seq.tris[seq.tri_face == seq.fixed_face])
    # the polygon ring of the fixed face in order (a quad: its triangles' vertices around the centroid)
    c = flat_v[ring].mean(0)
    order = np.argsort(np.arctan2(flat_v[ring, 1] - c[1], flat_v[ring, 0] - c[0]))
    return place_on_clamp(flat_v, ring[order], cell.clamp.pose, flat_v.mean(0))


def test_wing_through_wing_is_named_with_depth():
    """Letter fold: both flaps folded 175 deg over the middle cross each other (refold sees it too)."""
    flat, target = letter_fold_pair(175 * DEG)
    middle = int(np.flatnonzero(np.asarray(flat.face_data["strip"]) == 1)[0])
    seq = refold(flat, target, frames=8, drive="all", fixed_face=middle)   # both flaps fold over the middle
    assert seq.intersections[-1] > 0
    fx = np.eye(4)
    fx[2, 3] = 2.0                      # high above everything: only the panel against itself
    r = check_panel_collisions(collider_for_sequence(seq, fx, ()))
    assert not r.ok and {c.kind for c in r.contacts} == {"self"}
    strip = np.asarray(seq.face_data["strip"])
    polys = np.asarray(seq.face_data["polygon"])
    for c in r.contacts:
        a, b = (int(n.split("_")[1]) for n in c.pair)
        assert {strip[polys == a][0], strip[polys == b][0]} == {0, 2}   # one flap against the other
        assert c.depth_m > 0.01
    # the flaps meet between states (before refold's first intersecting state)
    first_state = int(np.flatnonzero(seq.intersections > 0)[0])
    assert min(c.state for c in r.contacts) < first_state


def test_letter_fold_at_120_deg_is_clean():
    flat, target = letter_fold_pair(120 * DEG)
    seq = refold(flat, target, frames=5, drive="all")
    fx = np.eye(4)
    fx[2, 3] = 2.0
    assert check_panel_collisions(collider_for_sequence(seq, fx, ())).ok


def test_samples_bound_the_corner_travel(cell):
    seq, col = _on_clamp(cell, 60 * DEG)
    s = sample_states(col.panel, step_m=0.002)
    assert s[0] == 0 and s[-1] == seq.n_states - 1 and np.all(np.diff(s) > 0)
    assert set(range(seq.n_states)) <= set(np.round(s, 12))
    T = np.stack([col.triangles_at(x) for x in s])
    step = np.linalg.norm(np.diff(T, axis=0), axis=-1).max()
    assert step <= 0.002 * 1.05


def test_an_obstacle_box_in_the_way():
    flat, target = letter_fold_pair(120 * DEG)
    seq = refold(flat, target, frames=5, drive="all")
    box = Shape(name="jig_block", kind="box", pose=np.eye(4), size=(0.05, 0.05, 0.05))
    r = check_panel_collisions(collider_for_sequence(seq, np.eye(4), (box,)))
    assert not r.ok and r.contacts[0].pair[1] == "jig_block" and r.contacts[0].state == 0.0
