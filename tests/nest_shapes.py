"""Test parts for the nesting tests: bowed, sheared quadrilateral-like outlines [mm]."""
import math

import numpy as np
from shapely.geometry import Polygon


def bowed_parts(n: int, seed: int, width, height, skew, bow, top_points: int) -> list[Polygon]:
    """`n` parts: a straight bottom of a width drawn from `width` (lo, hi), a top edge sheared by a
    draw from `skew` at a height from `height`, bowed up by a draw from `bow`, through `top_points`
    points (draws in that order per part, from `numpy.random.default_rng(seed)`)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        w, h, sk = rng.uniform(*width), rng.uniform(*height), rng.uniform(*skew)
        b = rng.uniform(*bow)
        top = [(w + sk - t * w, h + b * math.sin(math.pi * t)) for t in np.linspace(0, 1, top_points)]
        out.append(Polygon([(0, 0), (w, 0), *top]))
    return out
