"""What holds the panel, as the pictures show it: colours for the held faces, a legend, grip changes.

From CHECK.json's `holds` record (the one `sim.check_holds` copies from PATH.json: `clamped_faces`,
per arm and per jig the face held on the move into every waypoint) this module says, for any
waypoint, which face each hold has (`held_faces`), in which colour it is drawn (`HoldColours`:
the clamp blue, each jig purple, each arm its own colour: green, cyan, ...), and where an arm takes or lets go
of a face (`grip_changes`). `draw_legend` writes the legend and a banner onto an RGB frame
(Pillow). Any number of arms: the record's `arms` keys, in order. Which face each hold has, and
the grip changes, are `fabkit.held_faces`'s (report.html reads the same).
"""
from __future__ import annotations

import numpy as np

from fabkit.held_faces import Hold, held_faces

__all__ = ["PLAIN_RGBA", "CLAMP_RGBA", "JIG_RGBA", "ARM_RGBAS", "hold_roles", "colour_of", "draw_legend"]

PLAIN_RGBA = (0.8, 0.82, 0.86, 1.0)       # a face nothing holds (the cell model's panel colour)
CLAMP_RGBA = (0.12, 0.32, 0.92, 1.0)      # blue
JIG_RGBA = (0.62, 0.16, 0.78, 1.0)        # purple
#: One colour per arm, in the record's order: green, cyan, gold, brown (not the tool's orange, not
#: the red of a collision pair).
ARM_RGBAS = ((0.1, 0.72, 0.2, 1.0), (0.0, 0.72, 0.85, 1.0), (0.95, 0.8, 0.0, 1.0), (0.55, 0.35, 0.15, 1.0))


def hold_roles(record: dict) -> list[tuple[str, tuple[float, ...]]]:
    """(label, rgba) of every hold the record has, in legend order: clamp, arms, jigs."""
    out = [("clamp", CLAMP_RGBA)] if record.get("clamped_faces") else []
    out += [(f"arm {a}", ARM_RGBAS[i % len(ARM_RGBAS)]) for i, a in enumerate(record.get("arms", {}))]
    out += [(f"jig {j}", JIG_RGBA) for j in record.get("jigs", {})]
    return out


def colour_of(record: dict, hold: Hold) -> tuple[float, ...]:
    return dict(hold_roles(record))[hold.label]


def _rgb255(rgba) -> tuple[int, int, int]:
    return tuple(int(round(255 * c)) for c in rgba[:3])


def draw_legend(frame: np.ndarray, record: dict | None, waypoint: int, banner: str = "") -> np.ndarray:
    """`frame` with a legend (top left: one swatch per hold, and the face each holds at `waypoint`)
    and `banner` (bottom: e.g. a grip change) drawn on it."""
    from PIL import Image, ImageDraw, ImageFont

    if not record:
        return frame
    img = Image.fromarray(frame)
    d = ImageDraw.Draw(img)
    h = frame.shape[0]
    size = max(8, min(16, h // 28))
    try:
        font = ImageFont.load_default(size=size)
    except TypeError:  # Pillow without FreeType: the fixed bitmap font
        font = ImageFont.load_default()
    now = {}
    for hold in held_faces(record, waypoint):
        now.setdefault(hold.label, []).append(hold.face)
    y = 4
    for label, rgba in hold_roles(record):
        faces = now.get(label)
        text = f"{label}: face {', '.join(map(str, faces))}" if faces else f"{label}: holds nothing"
        d.rectangle([4, y, 4 + size, y + size], fill=_rgb255(rgba), outline=(0, 0, 0))
        d.text((8 + size, y - 1), text, fill=(10, 10, 10), font=font)
        y += size + 4
    if banner:
        d.rectangle([0, h - size - 8, frame.shape[1], h], fill=(255, 250, 210))
        d.text((6, h - size - 6), banner, fill=(120, 40, 0), font=font)
    return np.asarray(img)
