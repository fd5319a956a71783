"""Fold sequences for the holds, sequencing and panel-collision tests (built once per session)."""
from __future__ import annotations

import functools
import tempfile
from pathlib import Path

from refold_panels import letter_fold_pair, reflect_pair

from fabkit.refold import refold

DEG = 3.141592653589793 / 180.0


@functools.lru_cache(maxsize=None)
def trifold_pair():
    """(FLAT, TARGET) of the demo's tri-fold: generate trifold -> relax -> unfold (the real pipeline)."""
    from fabkit.cli import main
    from fabkit.io.obj import load_obj

    with tempfile.TemporaryDirectory(prefix="fabkit_holds_") as tmp:
        d = Path(tmp)
        src, relaxed, flat = d / "tri.obj", d / "relaxed.obj", d / "flat.obj"
        assert main(["generate", "trifold", "-o", str(src), "-q"]) == 0
        assert main(["relax", str(src), "-o", str(relaxed), "-q"]) == 0
        assert main(["unfold", str(relaxed), "-o", str(flat), "-q"]) == 0
        return load_obj(flat), load_obj(relaxed)


@functools.lru_cache(maxsize=None)
def trifold_sequence(frames: int = 12):
    """The tri-fold refolded with its middle strip's middle-row face clamped (the old demo's clamp)."""
    import numpy as np

    flat, target = trifold_pair()
    mid = np.flatnonzero((np.asarray(flat.face_data["middle"]) != 0) & (np.asarray(flat.face_data["strip"]) == 1))
    return refold(flat, target, frames=frames, fixed_face=int(mid[0]))


@functools.lru_cache(maxsize=None)
def reflect_two_crease_pair():
    return reflect_pair(2, columns=8, rows=2)


@functools.lru_cache(maxsize=None)
def letter_pair(angle_deg: float = 120.0):
    return letter_fold_pair(angle_deg * DEG)
