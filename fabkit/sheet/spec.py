"""`SheetSpec`: the sheet a run folds (material, thickness, crease preparation, inside bend radius),
and the minimum-radius rule that refuses folds tighter than the material allows."""
from __future__ import annotations

import math
from dataclasses import dataclass

from fabkit.errors import InputError
from fabkit.materials import CreasePrep, Material, crease_prep

__all__ = ["SheetSpec", "sheet_spec", "sheet_of", "minimum_inside_radius", "check_bend_radius", "BendRadiusError"]


class BendRadiusError(InputError):
    """A crease is folded tighter than the material's minimum inside radius (names the crease)."""


@dataclass(frozen=True)
class SheetSpec:
    """A sheet: `material`, `thickness` t [m], crease `prep`, `inside_radius` R_i [m] of the creases.

    For a grooved crease the fold happens in the ligament: the bending thickness is the ligament
    and R_i is the ligament's inside radius (0 by default: the groove's faces close on the fold)."""

    material: Material
    thickness: float
    prep: CreasePrep
    inside_radius: float

    @property
    def rigid(self) -> bool:
        return self.material.rigid

    @property
    def bending_thickness(self) -> float:
        """Thickness [m] of the section that bends: the ligament of a grooved crease, else t."""
        return self.prep.ligament if self.prep.kind == "grooved" else self.thickness

    def summary(self) -> dict:
        return {"material": self.material.name, "thickness_mm": self.thickness * 1000,
                "crease_preparation": self.prep.kind, "crease": self.prep.describe(),
                "ligament_mm": None if self.prep.ligament is None else self.prep.ligament * 1000,
                "uncut_fraction": self.prep.uncut_fraction, "inside_radius_mm": self.inside_radius * 1000}


def minimum_inside_radius(material: Material, thickness: float, prep: CreasePrep | None = None) -> float:
    """Smallest inside radius [m] a crease of this preparation may be folded to.

    Plain and perforated creases (the bridges are full thickness): the material's table for 90 deg
    cold bends, the column of the next thicker listed thickness, times t (and at least the
    material's floor). Grooved creases: 0 (the ligament is bent sharp; only materials that allow
    grooving have the option). Rigid material: 0. Thicker than the table: `InputError`."""
    if material.rigid:
        return 0.0
    if prep is not None and prep.kind == "grooved":
        return 0.0
    for column, multiple in material.min_radius:
        if thickness <= column * (1 + 1e-9):
            return max(multiple * thickness, material.min_radius_floor)
    raise InputError(f"{thickness * 1000:g} mm is thicker than {material.name}'s bend-radius table "
                     f"(up to {material.min_radius[-1][0] * 1000:g} mm)", source="--thickness")


def sheet_spec(material: Material, thickness: float | None, prep: str = "plain", *, ligament: float | None = None,
               uncut_fraction: float | None = None, inside_radius: float | None = None) -> SheetSpec:
    """Validated `SheetSpec`; the inside radius defaults to the material's minimum for `prep`.

    A rigid material needs no thickness (0 is used)."""
    if material.rigid:
        return SheetSpec(material, float(thickness or 0.0), CreasePrep("plain"), 0.0)
    if thickness is None:
        raise InputError(f"{material.name} needs a sheet thickness", source="--thickness")
    if not (math.isfinite(thickness) and thickness > 0):
        raise InputError(f"must be > 0, got {thickness}", source="--thickness")
    p = crease_prep(material, prep, ligament=ligament, uncut_fraction=uncut_fraction, thickness=thickness)
    r = minimum_inside_radius(material, thickness, p) if inside_radius is None else float(inside_radius)
    if not (math.isfinite(r) and r >= 0):
        raise InputError(f"must be >= 0, got {r}", source="--bend-radius")
    return SheetSpec(material, float(thickness), p, r)


def _length(value, name: str, allow_zero: bool = False) -> float | None:
    """A length given as metres (a number) or as text with its unit ('1mm'), or None."""
    from fabkit.materials import parse_length

    if value is None:
        return None
    if isinstance(value, str):
        return parse_length(value, name, allow_zero=allow_zero)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"expected metres or a length with its unit, got {value!r}", source=name)
    return float(value)


def sheet_of(material="none", thickness=None, crease: str = "plain", *, ligament=None, bend_radius=None,
             uncut_fraction: float | None = None) -> SheetSpec:
    """The sheet of an API call: `material` a `Material`, a packaged name or a .toml path (default
    none: rigid); lengths in metres or as text with their unit ("1mm"). As the commands'
    --material, --thickness, --crease, --ligament and --bend-radius (the same refusals)."""
    from fabkit.materials import get_material

    m = material if isinstance(material, Material) else get_material(material)
    t = _length(thickness, "--thickness")
    lig = _length(ligament, "--ligament")
    r = _length(bend_radius, "--bend-radius", allow_zero=True)
    if m.rigid and (t is not None or crease != "plain" or lig is not None or r is not None):
        raise InputError("--thickness, --crease, --ligament and --bend-radius need a --material other than none",
                         source="--material")
    return sheet_spec(m, t, crease, ligament=lig, uncut_fraction=uncut_fraction, inside_radius=r)


def check_bend_radius(spec: SheetSpec, crease: str = "crease", inside_radius: float | None = None) -> None:
    """Raise `BendRadiusError` naming `crease` when its inside radius is below the minimum."""
    r = spec.inside_radius if inside_radius is None else float(inside_radius)
    need = minimum_inside_radius(spec.material, spec.thickness, spec.prep)
    if r < need * (1 - 1e-9):
        raise BendRadiusError(
            f"{crease}: inside radius {r * 1000:g} mm is tighter than {spec.material.name}'s minimum "
            f"{need * 1000:g} mm for a {spec.prep.kind} crease at {spec.thickness * 1000:g} mm "
            f"(fold around a larger radius, or groove the crease if the material allows it)", source=crease)
