"""Springback of a crease on release, and the overbend that makes it spring back to the design angle.

Angles are fold angles (0 = flat; magnitudes here, the caller keeps the M/V sign), radians.

Straight crease (Gardiner's closed form for elastic-perfectly-plastic pure bending):
    X = sigma_flow * rho_m / (E * t_b),   rho_m = R_i + t_b / 2,   K = 4 X^3 - 3 X + 1
    alpha_released = K_cal * alpha_held,  K_cal = 1 - c * (1 - K)     (c: the material's calibration)
t_b is the bending thickness (the ligament of a grooved crease). X >= 0.5: no permanent set (K = 0).

Curved crease (first-order model, sheet-metal reference §2.6): folding a crease of flat-pattern
geodesic curvature kappa_g to alpha bends both panels (width b along the rulings) elastically; they
push the crease open with the moment per unit length
    m_u(alpha) = D * b * kappa_g^2 * tan(alpha/2) * sec^2(alpha/2),   D = E t^3 / (12 (1 - nu^2)).
On release the crease's moment drops from +m_p along the elastic unloading line of stiffness
k = m_p / (alpha_held (1 - K_cal)) (the stiffness the straight-crease formula implies), bounded by
reverse yield at -m_p; the released angle is where it balances m_u:
    max(m_p - k (alpha_held - alpha), -m_p) + m_u(alpha) = 0.
With kappa_g = 0 this is the straight-crease result; if m_u exceeds m_p the crease re-yields open until
m_u(alpha) = m_p, and no overbend can reach a larger angle (`SpringbackError`).
"""
from __future__ import annotations

import math


from fabkit.errors import ToleranceError
from fabkit.sheet.spec import SheetSpec

__all__ = ["springback_ratio", "panel_unfolding_moment", "crease_plastic_moment_per_length", "released_angle",
           "programmed_angle", "SpringbackError", "plate_stiffness", "MAX_PROGRAMMED_ANGLE"]

#: Largest fold angle a program may ask for [rad] (179 deg: folded flat is not a program).
MAX_PROGRAMMED_ANGLE = math.radians(179.0)


class SpringbackError(ToleranceError):
    """No programmed angle makes the crease spring back to the design angle."""


def springback_ratio(spec: SheetSpec, calibrated: bool = True) -> float:
    """K_cal = alpha_released / alpha_held of a straight crease (module docstring); 1 for rigid."""
    if spec.rigid:
        return 1.0
    m = spec.material
    tb = spec.bending_thickness
    X = m.flow_stress * (spec.inside_radius + tb / 2) / (m.youngs_modulus * tb)
    K = 0.0 if X >= 0.5 else 4 * X ** 3 - 3 * X + 1
    if not calibrated:
        return K
    return max(0.0, 1.0 - m.calibration * (1.0 - K))


def plate_stiffness(spec: SheetSpec) -> float:
    """D = E t^3 / (12 (1 - nu^2)) of the full sheet [N m]."""
    m = spec.material
    return m.youngs_modulus * spec.thickness ** 3 / (12 * (1 - m.poisson_ratio ** 2))


def crease_plastic_moment_per_length(spec: SheetSpec, stress: float | None = None) -> float:
    """m_p = sigma t_b^2 / 4 per unit crease length [N m / m], times the uncut fraction of a perforated
    crease; sigma defaults to the material's flow stress."""
    if spec.rigid:
        return 0.0
    s = spec.material.flow_stress if stress is None else stress
    m = s * spec.bending_thickness ** 2 / 4
    if spec.prep.kind == "perforated":
        m *= spec.prep.uncut_fraction
    return m


def panel_unfolding_moment(spec: SheetSpec, alpha: float, kappa_g: float, panel_width: float) -> float:
    """m_u(alpha) [N m / m]: the elastic panels' opening moment on a curved crease (module docstring)."""
    if spec.rigid or kappa_g == 0.0 or panel_width <= 0.0:
        return 0.0
    h = abs(alpha) / 2
    return plate_stiffness(spec) * panel_width * kappa_g ** 2 * math.tan(h) / math.cos(h) ** 2


def released_angle(spec: SheetSpec, held: float, kappa_g: float = 0.0, panel_width: float = 0.0) -> float:
    """The fold angle [rad] a crease held at `held` springs back to (sign kept; module docstring)."""
    a = abs(float(held))
    if spec.rigid or a == 0.0:
        return float(held)
    from scipy.optimize import brentq  # on use: importing scipy.optimize costs ~0.3 s

    sign = 1.0 if held > 0 else -1.0
    K = springback_ratio(spec)
    mp = crease_plastic_moment_per_length(spec)
    mu = lambda x: panel_unfolding_moment(spec, x, kappa_g, panel_width)  # noqa: E731
    if mu(a) == 0.0:
        return sign * K * a
    if K >= 1.0:  # no elastic unloading: only re-yield can open the crease
        if mu(a) <= mp:
            return float(held)
        return sign * brentq(lambda x: mu(x) - mp, 0.0, a, xtol=1e-12)
    k = mp / (a * (1.0 - K))
    g = lambda x: max(mp - k * (a - x), -mp) + mu(x)  # noqa: E731
    if g(0.0) >= 0.0:
        return 0.0
    return sign * brentq(g, 0.0, a, xtol=1e-12)


def programmed_angle(spec: SheetSpec, design: float, kappa_g: float = 0.0, panel_width: float = 0.0,
                     crease: str = "crease") -> float:
    """The held (overbent) fold angle [rad] that springs back to `design` (sign kept).

    The balance of `released_angle` solved for the held angle a at released angle d: with
    r = m_u(d) / m_p <= 1 (the crease stays on its elastic unloading line),
        a = d / (1 - (1 - K_cal) (1 + r))
    (a = d / K_cal on a straight crease). r > 1: the panels re-open the crease past d whatever the
    overbend. Rigid material: `design` exactly. Raises `SpringbackError` naming `crease` when no
    held angle up to 179 deg springs back to the design angle."""
    d = abs(float(design))
    if spec.rigid or d == 0.0:
        return float(design)
    sign = 1.0 if design > 0 else -1.0
    K = springback_ratio(spec)
    if K <= 0.0:
        raise SpringbackError(f"{crease}: {spec.material.name} at this thickness and radius stays elastic "
                              f"(no permanent set): it springs back flat; fold around a smaller radius or groove it")
    mp = crease_plastic_moment_per_length(spec)
    r = panel_unfolding_moment(spec, d, kappa_g, panel_width) / mp
    denominator = 1.0 - (1.0 - K) * (1.0 + r)
    held = d / denominator if (r <= 1.0 and denominator > 0.0) else math.inf
    if held > MAX_PROGRAMMED_ANGLE:
        reach = released_angle(spec, MAX_PROGRAMMED_ANGLE, kappa_g, panel_width)
        cause = ("the elastic panels re-open the crease; hold the panel boundary or use a thicker ligament"
                 if r > 0 else "the springback is too large")
        raise SpringbackError(f"{crease}: {spec.material.name} {spec.prep.describe()} springs back to at most "
                              f"{math.degrees(reach):.1f} deg, short of the design {math.degrees(d):.1f} deg: {cause}")
    return sign * held
