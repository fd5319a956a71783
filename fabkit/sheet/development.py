"""Flat length of a thick sheet across a crease: K-factor, bend allowance and the per-crease correction
that takes a development of the design surface to one of the neutral surface.

    K (DIN 6935, as commonly quoted) = 0.325 + 0.25 log10(R_i / t), clipped to [0.3, 0.5]
    BA = alpha (R_i + n),  n = K t            (neutral surface at n from the inside face)
    flat = A + B - 2 (R_i + d) tan(alpha / 2) + BA

A and B are the legs measured on the design surface to its virtual sharp, d the distance of the
design surface from the crease's inside face: the top face is the inside of a valley (d = 0) and the
outside of a mountain (d = t); the mid-surface is d = t/2 either way. A grooved crease folds in its
ligament (groove on the inside): n = (t - t_l) + K_l t_l with K_l for the ligament's own radius.
A development of the sharp-creased design surface already has A + B; the neutral-surface one
differs by `crease_correction` = BA - 2 (R_i + d) tan(alpha / 2) per crease.
"""
from __future__ import annotations

import math

from fabkit.errors import InputError
from fabkit.sheet.spec import SheetSpec

__all__ = ["DESIGN_SURFACES", "front_face_offset", "back_face_offset", "k_factor", "din6935_k_factor", "neutral_offset", "bend_allowance",
           "design_offset", "crease_correction", "flat_length"]

DESIGN_SURFACES = ("top", "mid", "bottom")


def din6935_k_factor(inside_radius: float, thickness: float) -> float:
    """K = 0.325 + 0.25 log10(R_i / t), clipped to [0.3, 0.5] (0.3 for a sharp fold)."""
    if inside_radius <= 0:
        return 0.3
    return min(0.5, max(0.3, 0.325 + 0.25 * math.log10(inside_radius / thickness)))


def k_factor(spec: SheetSpec) -> float:
    """The material's K-factor for the bending section (a number, or DIN 6935 at R_i / t_b)."""
    kf = spec.material.k_factor
    if isinstance(kf, float):
        return kf
    return din6935_k_factor(spec.inside_radius, spec.bending_thickness)


def neutral_offset(spec: SheetSpec) -> float:
    """Distance n [m] of the neutral surface from the crease's inside face."""
    if spec.prep.kind == "grooved":
        return spec.thickness - spec.prep.ligament + k_factor(spec) * spec.prep.ligament
    return k_factor(spec) * spec.thickness


def bend_allowance(spec: SheetSpec, alpha: float) -> float:
    """BA = |alpha| (R_i + n) [m]."""
    return abs(alpha) * (spec.inside_radius + neutral_offset(spec))


def design_offset(spec: SheetSpec, alpha: float, design_surface: str = "top") -> float:
    """d [m]: the design surface's distance from the inside face of a crease folded by `alpha`
    (valley positive: the top face is inside)."""
    if design_surface not in DESIGN_SURFACES:
        raise InputError(f"unknown design surface {design_surface!r} (choose {', '.join(DESIGN_SURFACES)})",
                         source="--design-surface")
    if design_surface == "mid":
        return spec.thickness / 2
    top_inside = alpha >= 0
    return 0.0 if top_inside == (design_surface == "top") else spec.thickness


def front_face_offset(spec: SheetSpec, design_surface: str = "top") -> float:
    """How far [m] the sheet's top (front) face lies in front of the design surface, along the
    front normal: 0 for the top face as the design surface, t/2 for the mid-surface, t for the
    bottom face. The cup grips the front face, so this is the TCP standoff the sheet adds."""
    if design_surface not in DESIGN_SURFACES:
        raise InputError(f"unknown design surface {design_surface!r} (choose {', '.join(DESIGN_SURFACES)})",
                         source="--design-surface")
    return {"top": 0.0, "mid": 0.5, "bottom": 1.0}[design_surface] * spec.thickness


def back_face_offset(spec: SheetSpec, design_surface: str = "top") -> float:
    """How far [m] the sheet's back face lies behind the design surface, against the front normal:
    t for the top face as the design surface, t/2 for the mid-surface, 0 for the bottom face. A cup
    gripping from the back touches the back face, so this is the TCP standoff the sheet adds there."""
    return spec.thickness - front_face_offset(spec, design_surface)


def crease_correction(spec: SheetSpec, alpha: float, design_surface: str = "top") -> float:
    """Flat length [m] the neutral surface adds across one crease (negative: it is shorter)."""
    if spec.rigid or alpha == 0.0:
        return 0.0
    d = design_offset(spec, alpha, design_surface)
    return bend_allowance(spec, alpha) - 2 * (spec.inside_radius + d) * math.tan(abs(alpha) / 2)


def flat_length(spec: SheetSpec, leg_a: float, leg_b: float, alpha: float, design_surface: str = "top") -> float:
    """Blank length [m] of a single fold with legs A, B to the virtual sharp on the design surface."""
    return leg_a + leg_b + crease_correction(spec, alpha, design_surface)
