"""One arm of a cell with several arms, as a one-arm cell: what each arm's planner, check and
controller stand-in see.

`arm_cell(cell, name)` is `cell` with `robot` set to that arm's mount (base pose, model, home) and
no further arms: the same tool, fixture, clamp, obstacles, limits, file and sha256. The panel frame
maps into that arm's base frame (`Cell.panel_to_base`). Arm "a" is the `[robot]` table.
"""
from __future__ import annotations

from dataclasses import replace

from fabkit.errors import InputError

__all__ = ["arm_names", "arm_cell"]


def arm_names(cell) -> tuple[str, ...]:
    """The names of the cell's arms: "a" (the `[robot]` arm), then the `[[arms]]` names."""
    return tuple(n for n, _ in cell.arms)


def arm_cell(cell, name: str):
    """`cell` seen by arm `name` alone (module docstring); `InputError` for an arm it does not have."""
    for n, mount in cell.arms:
        if n == name:
            return cell if n == "a" and not cell.extra_arms else replace(cell, robot=mount, extra_arms=())
    raise InputError(f"the cell {cell.name!r} has no arm {name!r} (arms: {', '.join(arm_names(cell))})",
                     source=cell.source or None)
