"""Which face each hold has at a waypoint, and where an arm takes or lets go of a face.

Read from a `holds` record (PATH.json's, or CHECK.json's copy of it: `clamped_faces`, and per arm
and per jig the face held on the move into every waypoint, `robot.holds_record`), for any number
of arms. The pictures (`sim.hold_colours`) and report.html (`fabkit.report.holds`) both use it.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Hold", "GripChange", "held_faces", "grip_changes"]


@dataclass(frozen=True)
class Hold:
    """One hold on one face: `role` "clamp" | "arm" | "jig", `name` ("a", "wing_pad", ""), `face`."""

    role: str
    name: str
    face: int

    @property
    def label(self) -> str:
        return "clamp" if self.role == "clamp" else f"{self.role} {self.name}"


@dataclass(frozen=True)
class GripChange:
    """At `waypoint` arm `arm` starts holding `face` (`grips` True) or lets go of it."""

    waypoint: int
    arm: str
    face: int
    grips: bool

    @property
    def text(self) -> str:
        return f"waypoint {self.waypoint}: arm {self.arm} {'grips' if self.grips else 'releases'} face {self.face}"


def held_faces(record: dict | None, waypoint: int) -> list[Hold]:
    """The holds at `waypoint` (the faces held on the move into it and on arrival)."""
    if not record:
        return []
    out = [Hold("clamp", "", int(f)) for f in record.get("clamped_faces", [])]
    for role, key in (("arm", "arms"), ("jig", "jigs")):
        for name, row in record.get(key, {}).items():
            if 0 <= waypoint < len(row) and row[waypoint] is not None:
                out.append(Hold(role, str(name), int(row[waypoint])))
    return out


def grip_changes(record: dict | None) -> list[GripChange]:
    """Every change of an arm's held face (a grip, a release, a regrip), in order. Row entry i is
    the face held on the move into waypoint i, and the gripper switches after arriving, so a change
    between entries k-1 and k happens at waypoint k-1 (the `grip` or `release` waypoint)."""
    out = []
    for arm, row in (record or {}).get("arms", {}).items():
        prev = None
        for k, f in enumerate(row):
            if f != prev:
                at = max(k - 1, 0)
                if prev is not None:
                    out.append(GripChange(at, str(arm), int(prev), False))
                if f is not None:
                    out.append(GripChange(at, str(arm), int(f), True))
            prev = f
    return sorted(out, key=lambda c: (c.waypoint, c.arm, c.grips))
