"""Blend radii with a margin: neighbouring radii <= 90 % of their segment (UR skips overlapping blends)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robot.blends import BLEND_FRACTION, blend_margin_violations, cap_blend_radii
from robot.motion import blend_radii

ROOT = Path(__file__).resolve().parent.parent


def _demo_like_fold_moves():
    """A fold move like the demo's: equal 1.8 mm steps, blend_max 5 mm, so every inner radius is half
    the segment and each pair of neighbours adds up to exactly the segment length."""
    t = np.arange(22) * 0.0018
    P = np.column_stack([t, 0.5 * t, 0.0 * t]) / np.sqrt(1.25)
    stops = np.zeros(len(P), bool)
    return P, blend_radii(P, stops, 0.005)


def test_the_planner_radii_add_up_to_the_segment():
    P, r = _demo_like_fold_moves()
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    exact = np.isclose(r[:-1] + r[1:], seg, rtol=1e-9)
    assert exact.sum() == 19                      # every segment but the first and the last
    assert len(blend_margin_violations(P, r)) == 19  # the end segments have one radius 0


def test_capped_radii_keep_the_margin_and_stay_largest():
    P, r = _demo_like_fold_moves()
    c = cap_blend_radii(P, r)
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    assert len(blend_margin_violations(P, c)) == 0
    assert np.all(c <= r + 1e-15) and np.all(c[1:-1] > 0)
    assert np.all(c[:-1] + c[1:] <= BLEND_FRACTION * seg * (1 + 1e-12))
    # the equal-step inner radii come out at exactly 45 % of the segment
    np.testing.assert_allclose(c[1:-1], 0.45 * seg[1:], rtol=1e-12)
    # a stop next to a blend leaves that blend 90 % of the segment (if it asked for that much)
    P2 = np.array([[0, 0, 0], [0.01, 0, 0], [0.02, 0.01, 0]], float)
    np.testing.assert_allclose(cap_blend_radii(P2, [0.0, 0.02, 0.0]), [0.0, 0.009, 0.0])


def test_radii_already_within_the_margin_are_kept(rng):
    P = np.cumsum(rng.uniform(0.01, 0.05, (30, 3)), axis=0)
    r = rng.uniform(0, 0.002, 30)
    r[0] = r[-1] = 0
    np.testing.assert_array_equal(cap_blend_radii(P, r), r)


def test_random_radii_always_end_within_the_margin(rng):
    for _ in range(50):
        P = np.cumsum(rng.uniform(-0.02, 0.02, (12, 3)), axis=0)
        r = rng.uniform(0, 0.03, 12)
        c = cap_blend_radii(P, r)
        assert len(blend_margin_violations(P, c)) == 0
        assert np.all(c <= r) and np.all(c >= 0)


def test_bad_input():
    P = np.zeros((3, 3))
    with pytest.raises(ValueError, match="fraction"):
        cap_blend_radii(P, [0, 0, 0], fraction=1.5)
    with pytest.raises(ValueError, match=">= 0"):
        cap_blend_radii(P, [0, -1, 0])
    with pytest.raises(ValueError, match="radii for"):
        cap_blend_radii(P, [0, 0])
