"""How far apart parts are nested, and how far from the sheet edge, for a sheet and a cutting process.

Fabricators' rules for laser and waterjet cutting of thin sheet (sources in docs/production.md,
"Part spacing"): the gap between two parts' outlines is the kerf plus a web of sheet left between
the two cuts, and that web must hold the skeleton together while the parts are cut:

- the web is at least 1-2 mm beyond the kerf (the upper end, 2 mm, is taken), and at least the
  sheet thickness, 1.5 t preferred (taken) — so `spacing = max(2 mm, 1.5 t)`;
- the kerf is the process's: laser about 0.1-0.4 mm (0.2 taken), abrasive waterjet 0.5-1.5 mm
  (1.0 taken);
- the outlines keep 5 mm from the sheet's edge (a sheared mill edge is not a cut edge), and never
  less than half the gap between parts.

`--spacing`, `--kerf` and `--edge-margin` override each value.
"""
from __future__ import annotations

from dataclasses import dataclass

from fabkit.errors import InputError

__all__ = ["CutSpacing", "cut_spacing", "PROCESSES", "KERF_MM", "MIN_WEB_MM", "WEB_PER_THICKNESS",
           "EDGE_MARGIN_MM", "DEFAULT_THICKNESS_MM"]

#: cutting processes with a sourced kerf [mm]
KERF_MM = {"laser": 0.2, "waterjet": 1.0}
PROCESSES = tuple(KERF_MM)
#: [mm] the least web of sheet between two parts' kerfs ("kerf + 1-2 mm")
MIN_WEB_MM = 2.0
#: the web between two cuts in sheet thickness ("at least t, 1-1.5 t preferred")
WEB_PER_THICKNESS = 1.5
#: [mm] part outlines to the sheet's edge
EDGE_MARGIN_MM = 5.0
#: [mm] the sheet a run is costed as when no material is named (1 mm 5052-H32)
DEFAULT_THICKNESS_MM = 1.0


@dataclass(frozen=True)
class CutSpacing:
    """Nesting distances [mm] for `thickness` mm sheet cut by `process`: `spacing` is the web
    between neighbouring parts' kerfs (gap between outlines = spacing + kerf), `edge` the distance
    from every outline to the sheet's edge."""

    thickness: float
    process: str
    spacing: float
    kerf: float
    edge: float

    @property
    def gap(self) -> float:
        return self.spacing + self.kerf


def cut_spacing(thickness: float = DEFAULT_THICKNESS_MM, process: str = "laser", *, spacing: float | None = None,
                kerf: float | None = None, edge: float | None = None) -> CutSpacing:
    """The sourced nesting distances for `thickness` mm sheet cut by `process` (module docstring);
    `spacing`, `kerf` or `edge` given replace the rule's value (the edge rule then uses their gap)."""
    if process not in KERF_MM:
        raise InputError(f"unknown cutting process {process!r} ({', '.join(PROCESSES)})", source="--cut")
    if not (0.0 < thickness <= 20.0):
        raise InputError(f"sheet thickness must be in (0, 20] mm, got {thickness:g} mm", source="--thickness")
    for name, v in (("spacing", spacing), ("kerf", kerf), ("edge margin", edge)):
        if v is not None and not v >= 0.0:
            raise InputError(f"{name} must not be negative, got {v:g} mm",
                             source={"spacing": "--spacing", "kerf": "--kerf"}.get(name, "--edge-margin"))
    web = max(MIN_WEB_MM, WEB_PER_THICKNESS * thickness) if spacing is None else float(spacing)
    k = KERF_MM[process] if kerf is None else float(kerf)
    e = max(EDGE_MARGIN_MM, 0.5 * (web + k)) if edge is None else float(edge)
    return CutSpacing(thickness=float(thickness), process=process, spacing=web, kerf=k, edge=e)
