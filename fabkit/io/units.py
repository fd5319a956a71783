"""Length units at the file boundary: what `--units` accepts, and the note for an implausible size.

Inside fabkit every length is in metres. A file's unit is taken from the file when it says
(FOLD `frame_unit`, a `.3dm` model unit system, an OBJ `# fabkit unit <u>` line), from `--units`
when given, else assumed to be metres; a panel whose size in the assumed unit is implausible for a
sheet-metal panel gets a one-line note naming the unit its size suggests.
"""
from __future__ import annotations

__all__ = ["UNITS", "metres_per", "scale_to_metres", "unit_note", "PLAUSIBLE_SIZE_M"]

#: `--units` choices -> metres per unit
UNITS: dict[str, float] = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "in": 0.0254}

#: bounding-box diagonals (m) a folded sheet panel plausibly has; outside, a note suggests a unit
PLAUSIBLE_SIZE_M = (0.01, 20.0)


def metres_per(unit: str) -> float:
    """Metres per `unit` (one of `UNITS`); `ValueError` for anything else."""
    try:
        return UNITS[unit]
    except KeyError:
        raise ValueError(f"unknown unit {unit!r}: use one of {', '.join(UNITS)}") from None


def scale_to_metres(V, unit: str):
    """Coordinates in `unit` -> metres (exact division by a power of ten for mm and cm)."""
    import numpy as np

    V = np.asarray(V, dtype=np.float64)
    if unit == "m":
        return V.copy()
    if unit == "mm":
        return V / 1000.0
    if unit == "cm":
        return V / 100.0
    return V * metres_per(unit)


def unit_note(size_m: float, unit: str, how: str) -> str | None:
    """A one-line note when a panel of bounding-box diagonal `size_m` (read as `unit`, `how` =
    'assumed' / 'from the file' / 'from --units') is implausibly large or small, else None."""
    lo, hi = PLAUSIBLE_SIZE_M
    if lo <= size_m <= hi or size_m == 0:
        return None
    size_in_unit = size_m / metres_per(unit) if unit in UNITS else size_m
    for other in ("mm", "cm", "in", "m"):
        if other == unit:
            continue
        as_other = size_in_unit * metres_per(other)
        if lo <= as_other <= hi:
            return (f"the panel is {size_m:.4g} m across with its coordinates read as {unit} ({how}); "
                    f"if they are {other} it is {as_other:.4g} m: pass --units {other}")
    return f"the panel is {size_m:.4g} m across with its coordinates read as {unit} ({how}): check the unit"
