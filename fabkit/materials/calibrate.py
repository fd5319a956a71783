"""Calibrate a material's springback factor from measured test folds.

A calibration file (TOML) describes straight test folds of one sheet and what they measured:

    material = "5052-H32"         # a packaged name or a material .toml file
    thickness_mm = 1.6
    inside_radius_mm = 1.6        # optional: default the material's minimum for the crease
    crease = "plain"              # optional: plain | grooved | perforated
    ligament_mm = 0.4             # grooved only (optional: the material's default)
    name = "5052-H32-shop"        # optional: name of the calibrated material (default: the same)
    [[folds]]
    programmed_deg = 90.0         # fold angle the sheet was held at (0 = flat)
    measured_deg = 87.0           # fold angle measured after release

The model's springback of fold i is a_i = alpha_i (1 - K) (uncalibrated K), the measured one
b_i = alpha_i - measured_i; the factor is the least-squares c = sum a_i b_i / sum a_i^2, so that
c * a_i fits b_i. The straight-crease model only: calibrate on straight test folds.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from fabkit.errors import InputError
from fabkit.materials import Material, get_material, material_toml

__all__ = ["Calibration", "calibrate", "load_calibration"]

_KEYS = {"material", "thickness_mm", "inside_radius_mm", "crease", "ligament_mm", "name", "folds"}


@dataclass(frozen=True)
class Calibration:
    """Result: the calibrated `material`, its `factor`, the folds used (programmed, measured) [rad],
    the rms residual [rad] of the fit, and the uncalibrated K of the test sheet."""

    material: Material
    factor: float
    folds: tuple[tuple[float, float], ...]
    rms_residual: float
    k_uncalibrated: float

    def toml(self, source: str) -> str:
        header = (f"Calibrated by `fabkit materials --calibrate {Path(source).name}`: springback factor "
                  f"{self.factor:.4g} from {len(self.folds)} test fold(s), rms residual "
                  f"{math.degrees(self.rms_residual):.3g} deg.\nTypical values, not for design.")
        return material_toml(self.material, header=header)

    def summary(self) -> dict:
        return {"material": self.material.name, "factor": self.factor, "folds": len(self.folds),
                "rms_residual_deg": math.degrees(self.rms_residual), "k_uncalibrated": self.k_uncalibrated}


def _num(d: dict, key: str, source: str, required: bool = True, lo: float = 0.0, hi: float = 180.0):
    if key not in d:
        if required:
            raise InputError(f"{key}: missing", source=source)
        return None
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
        raise InputError(f"{key}: must be a number in [{lo:g}, {hi:g}], got {v!r}", source=source)
    return float(v)


def calibrate(data: dict, source: str) -> Calibration:
    """Fit the springback factor from a parsed calibration file (module docstring)."""
    from fabkit.sheet import sheet_spec, springback_ratio

    extra = sorted(set(data) - _KEYS)
    if extra:
        raise InputError(f"{extra[0]}: unknown field", source=source)
    if not isinstance(data.get("material"), str):
        raise InputError("material: missing (a material name or .toml file)", source=source)
    try:
        base = get_material(data["material"])
    except InputError as exc:
        raise InputError(f"material: {exc.message}", source=source) from None
    if base.rigid:
        raise InputError(f"material: {base.name} is rigid and has no springback to calibrate", source=source)
    t = _num(data, "thickness_mm", source, hi=50.0) * 1e-3
    r = _num(data, "inside_radius_mm", source, required=False, hi=1000.0)
    lig = _num(data, "ligament_mm", source, required=False, hi=50.0)
    crease = data.get("crease", "plain")
    try:
        spec = sheet_spec(base, t, crease if isinstance(crease, str) else repr(crease),
                          ligament=None if lig is None else lig * 1e-3, inside_radius=None if r is None else r * 1e-3)
    except InputError as exc:
        raise InputError(exc.message, source=source) from None
    folds = data.get("folds")
    if not isinstance(folds, list) or not folds or not all(isinstance(f, dict) for f in folds):
        raise InputError("folds: needs at least one [[folds]] table with programmed_deg and measured_deg",
                         source=source)
    K = springback_ratio(spec, calibrated=False)
    if K >= 1.0 or K <= 0.0:
        raise InputError(f"the model predicts {'no' if K >= 1 else 'total'} springback for this sheet: "
                         "nothing to calibrate", source=source)
    pairs = []
    for i, f in enumerate(folds):
        extra = sorted(set(f) - {"programmed_deg", "measured_deg"})
        if extra:
            raise InputError(f"folds[{i}].{extra[0]}: unknown field", source=source)
        p = _num(f, "programmed_deg", f"{source}: folds[{i}]", lo=1.0, hi=179.0)
        m = _num(f, "measured_deg", f"{source}: folds[{i}]", lo=0.0, hi=179.0)
        if m > p:
            raise InputError(f"folds[{i}]: measured {m:g} deg is more folded than programmed {p:g} deg "
                             "(springback opens a fold)", source=source)
        pairs.append((math.radians(p), math.radians(m)))
    a = [p * (1 - K) for p, _ in pairs]
    b = [p - m for p, m in pairs]
    c = sum(x * y for x, y in zip(a, b)) / sum(x * x for x in a)
    if not 0 < c <= 20:
        raise InputError(f"the fitted factor {c:.3g} is outside (0, 20]: check the measurements", source=source)
    rms = math.sqrt(sum((c * x - y) ** 2 for x, y in zip(a, b)) / len(a))
    name = data.get("name", base.name)
    if not isinstance(name, str):
        raise InputError("name: must be a string", source=source)
    note = (f"fitted to {len(pairs)} test fold(s) of {t * 1000:g} mm at R_i = {spec.inside_radius * 1000:g} mm, "
            f"{spec.prep.describe()} ({Path(source).name})")
    return Calibration(base.with_calibration(c, note, name), c, tuple(pairs), rms, K)


def load_calibration(path: str | Path) -> Calibration:
    """Read a calibration file and fit (`InputError` naming the file and field)."""
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", source=str(path)) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"not valid TOML: {exc}", source=str(path)) from None
    return calibrate(data, str(path))
