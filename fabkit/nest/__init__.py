"""Nesting flat patterns on stock sheets, and the cut files of each sheet.

`nest_parts(parts, options)` places polygons (mm) on rectangular sheets with a gap between parts
(`spacing + kerf`) and a margin to the sheet edge (`edge`), by default those of 1 mm sheet cut by
laser (`fabkit.nest.spacing.cut_spacing`: fabricators' rules), rotation free or (`grain`) held so
each part's grain axis runs along the sheet's x or y. Three engines:

- `rows` (default): each part turned to its least shelf cell, best-fit onto shelves (on the floor,
  or two low parts sharing a tall shelf) and slid exactly to the gap against the parts already
  there, so sheared sides nest; then the last sheet's parts dropped into the holes of the others
  (`fabkit.nest.fill`: lowest, then leftmost, in x and y) and the last sheet nested across for a
  longer offcut (`fabkit.nest.rows`; deterministic);
- `packingsolver`: irregular nesting by sparrow (Gardeyn & Wauters, through the `spyrrow`
  package): strip packing with collision detection on the true outlines. Sheets are filled by
  packing the remaining parts into a strip of the sheet's height and keeping the parts that lie
  wholly inside the whole sheet lengths; parts across a sheet end go into the next strip.
- `shelf`: the baseline — each part turned to its minimum-area bounding rectangle and placed by
  first-fit decreasing height on shelves.

Every result is verified with shapely (`Nesting.verify`): each part exactly once, no two parts
closer than the gap, every part inside its sheet's margin.
"""
from fabkit.nest.engines import NestOptions, Nesting, Placement, nest_parts
from fabkit.nest.panels import nest_panels, panel_parts
from fabkit.nest.sheets import write_sheets  # noqa: E402

__all__ = ["NestOptions", "Nesting", "Placement", "nest_parts", "nest_panels", "panel_parts", "write_sheets"]
