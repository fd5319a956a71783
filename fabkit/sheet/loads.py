"""What folding asks of the arm and the gripper: fold moment along a crease, vacuum-cup capacity,
panel mass and centre of gravity.

Fold moment (pure bending of a rectangular section, sheet-metal reference §6):
    m_p = sigma t_b^2 / 4 per unit length,  M = m_p L
given as a range: `low` with the yield stress, `high` in plane strain (x 2/sqrt(3)) with the flow
stress (strain hardening). A grooved crease bends its ligament (t_b = t_l); a perforated crease
keeps its uncut fraction. L is the crease's arc length (an upper bound of the resultant couple).

Vacuum cup (Schmalz): theoretical holding force F = dp * pi D^2 / 4, usable F / S; tilting
capacity of a ring lip ~ F D / 4 (a derived estimate, check against vendor moment data).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fabkit.sheet.spec import SheetSpec

__all__ = ["FoldMoment", "fold_moment", "VacuumCup", "PanelMass", "panel_mass", "PLANE_STRAIN", "GRAVITY"]

PLANE_STRAIN = 2 / math.sqrt(3)
GRAVITY = 9.80665


@dataclass(frozen=True)
class FoldMoment:
    """Moment [N m] to fold one crease of `length` [m]: `low` (yield stress) to `high` (plane strain,
    flow stress); `per_length` the high value per metre [N m / m]."""

    crease: str
    length: float
    low: float
    high: float

    @property
    def per_length(self) -> float:
        return self.high / self.length if self.length else 0.0


def fold_moment(spec: SheetSpec, length: float, crease: str = "crease") -> FoldMoment:
    """Plastic fold moment of a crease of arc length `length` [m] (module docstring)."""
    if spec.rigid:
        return FoldMoment(crease, float(length), 0.0, 0.0)
    tb = spec.bending_thickness
    frac = spec.prep.uncut_fraction if spec.prep.kind == "perforated" else 1.0
    m = spec.material
    low = m.yield_stress * tb ** 2 / 4 * frac * length
    high = PLANE_STRAIN * m.flow_stress * tb ** 2 / 4 * frac * length
    return FoldMoment(crease, float(length), float(low), float(high))


@dataclass(frozen=True)
class VacuumCup:
    """A flat suction cup: lip `diameter` [m], working vacuum `vacuum` [Pa below ambient], safety
    factor `safety` (>= 2 in general, 2.5 when swivelling parts; Schmalz), dry-metal friction `mu`."""

    diameter: float
    vacuum: float = 60e3
    safety: float = 2.5
    mu: float = 0.5

    @property
    def holding_force(self) -> float:
        """Theoretical normal holding force dp * A [N]."""
        return self.vacuum * math.pi * self.diameter ** 2 / 4

    @property
    def usable_force(self) -> float:
        """Holding force divided by the safety factor [N]."""
        return self.holding_force / self.safety

    @property
    def lateral_force(self) -> float:
        """Usable force along the sheet (friction) [N]."""
        return self.mu * self.usable_force

    @property
    def tilt_capacity(self) -> float:
        """Theoretical tilting moment F D / 4 [N m] (ring-lip estimate, S = 1)."""
        return self.holding_force * self.diameter / 4

    @property
    def usable_tilt(self) -> float:
        """Tilting moment divided by the safety factor [N m]."""
        return self.tilt_capacity / self.safety

    def summary(self) -> dict:
        return {"diameter_mm": self.diameter * 1000, "vacuum_kpa": self.vacuum / 1000, "safety": self.safety,
                "holding_force_n": self.holding_force, "usable_force_n": self.usable_force,
                "tilt_capacity_nm": self.tilt_capacity, "usable_tilt_nm": self.usable_tilt}


@dataclass(frozen=True)
class PanelMass:
    """Panel `mass` [kg], `area` [m^2] and centre of gravity `cog` (3,) [m] in the frame of the
    positions it was computed from."""

    mass: float
    area: float
    cog: np.ndarray


def panel_mass(spec: SheetSpec, vertices, triangles) -> PanelMass:
    """Mass rho t A and area-weighted centroid of a triangulated panel (the design surface stands
    for the mid-surface: exact to first order in t / curvature radius)."""
    V = np.asarray(vertices, np.float64)
    T = np.asarray(triangles, np.int64)
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    A = float(areas.sum())
    cog = ((a + b + c) / 3 * areas[:, None]).sum(0) / A if A > 0 else V.mean(0)
    mass = 0.0 if spec.rigid else spec.material.density * spec.thickness * A
    return PanelMass(mass=float(mass), area=A, cog=cog)
