"""Models of the real sheet: springback and overbend, K-factor development, fold moments, vacuum grip,
panel mass, minimum bend radius, and springback-compensated fold states.

Formulas, sources and limits: docs/sheet.md. Inputs are a `SheetSpec` (material from
`fabkit.materials`, thickness, crease preparation, inside radius); SI units throughout.
"""
from fabkit.sheet.development import (DESIGN_SURFACES, back_face_offset, bend_allowance, crease_correction,
                                      flat_length, front_face_offset, k_factor, neutral_offset)
from fabkit.sheet.loads import FoldMoment, PanelMass, VacuumCup, fold_moment, panel_mass
from fabkit.sheet.spec import (BendRadiusError, SheetSpec, check_bend_radius, minimum_inside_radius, sheet_of,
                              sheet_spec)
from fabkit.sheet.springback import (SpringbackError, crease_plastic_moment_per_length, panel_unfolding_moment,
                                     programmed_angle, released_angle, springback_ratio)

__all__ = ["SheetSpec", "sheet_spec", "sheet_of", "minimum_inside_radius", "check_bend_radius", "BendRadiusError",
           "springback_ratio", "released_angle", "programmed_angle", "SpringbackError",
           "panel_unfolding_moment", "crease_plastic_moment_per_length", "k_factor", "neutral_offset",
           "bend_allowance", "crease_correction", "flat_length", "front_face_offset",
           "back_face_offset", "DESIGN_SURFACES", "fold_moment", "FoldMoment",
           "VacuumCup", "panel_mass", "PanelMass"]
