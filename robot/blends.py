"""Blend radii that the controller will not skip: neighbouring radii <= a fraction of their segment.

A UR controller skips (or faults on) a blended move whose blend overlaps the next one's: the two
radii at the ends of a segment must add up to less than the segment. `robot.motion.blend_radii`
keeps them at most equal to the segment length, which leaves no margin; this caps them to
`fraction` (default 90 %) of the segment, shrinking only the radii that need it.
"""
from __future__ import annotations

import numpy as np

__all__ = ["BLEND_FRACTION", "blend_margin_violations", "cap_blend_radii"]

#: Largest share of a segment the two blends at its ends may take together.
BLEND_FRACTION = 0.9


def _segments(points: np.ndarray) -> np.ndarray:
    P = np.asarray(points, dtype=np.float64)
    return np.linalg.norm(np.diff(P, axis=0), axis=1)


def blend_margin_violations(points, radii, fraction: float = BLEND_FRACTION) -> np.ndarray:
    """Segment indices i (i -> i+1) where r_i + r_{i+1} > fraction * |p_{i+1} - p_i| (TCP points, m)."""
    r = np.asarray(radii, dtype=np.float64)
    return np.flatnonzero(r[:-1] + r[1:] > fraction * _segments(points) * (1 + 1e-12))


def cap_blend_radii(points, radii, fraction: float = BLEND_FRACTION) -> np.ndarray:
    """Radii (n,) with r_i + r_{i+1} <= fraction * segment i for every segment, each radius as large
    as possible up to its given value.

    Each radius is capped at `fraction / 2` of its shorter adjacent segment (so neighbours never
    compete), and then raised again where the neighbour is smaller, up to its given value: a
    zero-radius stop next to a blend leaves that blend `fraction` of the segment.
    """
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction must be in (0, 1], got {fraction}")
    r0 = np.asarray(radii, dtype=np.float64)
    if np.any(r0 < 0) or not np.all(np.isfinite(r0)):
        raise ValueError("blend radii must be finite and >= 0")
    n = len(r0)
    if n < 2:
        return r0.copy()
    seg = _segments(points)
    if len(seg) != n - 1:
        raise ValueError(f"{n} radii for {len(seg) + 1} points")
    half = fraction * seg / 2
    cap = np.full(n, np.inf)
    cap[:-1] = np.minimum(cap[:-1], half)
    cap[1:] = np.minimum(cap[1:], half)
    r = np.minimum(r0, cap)
    # second pass: a radius may use what its neighbours leave of each adjacent segment
    room = np.full(n, np.inf)
    room[:-1] = np.minimum(room[:-1], fraction * seg - r[1:])
    room[1:] = np.minimum(room[1:], fraction * seg - r[:-1])
    grown = np.minimum(r0, np.maximum(r, room))
    # growing both ends of one segment at once could overshoot: keep the grown value only where
    # the segment still holds with the neighbours' first-pass values
    ok = np.ones(n, bool)
    ok[:-1] &= grown[:-1] + r[1:] <= fraction * seg * (1 + 1e-12)
    ok[1:] &= grown[1:] + r[:-1] <= fraction * seg * (1 + 1e-12)
    out = np.where(ok, grown, r)
    bad = blend_margin_violations(points, out, fraction)
    while len(bad):  # both neighbours grew into one segment: undo the later one
        out[bad + 1] = r[bad + 1]
        bad = blend_margin_violations(points, out, fraction)
    return out
