"""A vacuum pad of one or more equal cups: holding force, and the moment its lips resist before one
lifts off the sheet (the tilt capacity).

Ring-lip model (derived here; sheet-metal reference §7 gives the single-cup case F D / 4): each
cup's lip is a ring of diameter D pressed on the sheet by the vacuum, a uniform line load
q = F_u / (pi D) with F_u = dp pi D^2 / 4 / S the usable holding force (safety factor S). The pad
is rigid and the lips are its compliant part, so a rotation of the sheet relative to the pad about
a line in the sheet plane adds a line load proportional to the distance y from that line. The
moment about the line is M = k I with I = sum over the lips of the integral of y^2 along the lip,
  I = sum_i (pi D y_i^2 + pi R^3)        (y_i: cup centre's distance from the line, R = D / 2),
and the seal opens where the added load first cancels q, at the lip point farthest from the line:
  M_capacity = q I / y_max,   y_max = max_i (y_i + R).
About a line through a single cup's centre this is F_u D / 4 (the reference's ring-lip estimate);
about a crease at lever arm d from the pad it tends to F_u d (the cups' holding forces times their
lever arms) for d >> D. The pad's orientation on the face is set by the tool's yaw at planning,
so capacities are for the worst orientation of the pad about its axis unless an angle is given.
Not modelled: lip compliance that differs between cups, a pad that bends, friction, sheet that
bulges into a cup (reference §7), the compression side's limit (a lip pushed into the sheet is
taken as holding).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fabkit.sheet.loads import VacuumCup

__all__ = ["CupPad", "single_cup_pad"]

_ORIENTATIONS = 720   # pad orientations tried for the worst case (0.25 deg apart)


@dataclass(frozen=True, eq=False)
class CupPad:
    """Equal cups of lip `diameter` [m] at `centres` (n, 2) [m] in the tool's xy plane (TCP frame),
    working `vacuum` [Pa below ambient], safety factor `safety`."""

    centres: np.ndarray
    diameter: float
    vacuum: float = 60e3
    safety: float = 2.5

    def __post_init__(self):
        c = np.asarray(self.centres, np.float64).reshape(-1, 2)
        if len(c) == 0 or not np.all(np.isfinite(c)) or not self.diameter > 0:
            raise ValueError("a pad needs at least one cup and a positive cup diameter")
        object.__setattr__(self, "centres", c)

    @property
    def cup(self) -> VacuumCup:
        return VacuumCup(diameter=self.diameter, vacuum=self.vacuum, safety=self.safety)

    @property
    def count(self) -> int:
        return len(self.centres)

    @property
    def usable_force(self) -> float:
        """Usable normal holding force of all cups [N] (each dp A / S)."""
        return self.count * self.cup.usable_force

    @property
    def footprint_radius(self) -> float:
        """Radius [m] of the smallest disc about the TCP axis that covers every lip."""
        return float(np.linalg.norm(self.centres, axis=1).max() + self.diameter / 2)

    def _capacity(self, offsets: np.ndarray) -> np.ndarray:
        """Usable moment [N m] about lines at signed distances `offsets` (k, n) from each cup centre."""
        R = self.diameter / 2
        q = self.cup.usable_force / (math.pi * self.diameter)
        inertia = (math.pi * self.diameter * offsets ** 2 + math.pi * R ** 3).sum(axis=-1)
        reach = (np.abs(offsets) + R).max(axis=-1)
        return q * inertia / reach

    def moment_capacity(self, lever: float = 0.0, angle: float | None = None) -> float:
        """Usable moment [N m] about a line in the sheet plane at distance `lever` [m] from the pad's
        centre (0: the pad's own tilt; a crease's lever arm: the moment of resistance against
        folding it), with the line at `angle` [rad] to the tool's x axis, or the worst angle."""
        angles = (np.arange(_ORIENTATIONS) * math.pi / _ORIENTATIONS if angle is None
                  else np.array([float(angle)]))
        normal = np.column_stack([-np.sin(angles), np.cos(angles)])          # (k, 2) across the line
        offsets = float(lever) + normal @ self.centres.T                      # (k, n)
        return float(self._capacity(offsets).min())

    @property
    def usable_tilt(self) -> float:
        """The pad's own usable tilting moment [N m] (about a line through its centre, worst angle)."""
        return self.moment_capacity(0.0)

    def summary(self) -> dict:
        return {"cups": self.count, "cup_diameter_mm": self.diameter * 1000, "vacuum_kpa": self.vacuum / 1000,
                "safety": self.safety, "centres_mm": (self.centres * 1000).tolist(),
                "footprint_radius_mm": self.footprint_radius * 1000, "usable_force_n": self.usable_force,
                "usable_tilt_nm": self.usable_tilt}


def single_cup_pad(cup: VacuumCup) -> CupPad:
    """A pad of one cup on the tool axis."""
    return CupPad(np.zeros((1, 2)), cup.diameter, cup.vacuum, cup.safety)
