"""Cut files for a development: DXF (ezdxf) and SVG, in millimetres, with cut/mountain/valley/label layers;
the label layer says which face of the sheet is up.

`crease_assignment(mesh3d)` finds the creases and their mountain/valley sense on the folded panel,
`cut_pattern(mesh, uv, assignment, panel_id)` builds the drawing in millimetres, and
`write_dxf` / `write_svg` write it.
"""
from fabkit.cutfiles.creases import CreaseAssignment, chain_edges, crease_assignment
from fabkit.cutfiles.dxf import dxf_document, write_dxf
from fabkit.cutfiles.pattern import LAYERS, CutPattern, Label, cut_pattern, face_up
from fabkit.cutfiles.svg import svg_text, write_svg

__all__ = ["CreaseAssignment", "crease_assignment", "chain_edges", "CutPattern", "Label", "cut_pattern", "face_up", "LAYERS",
           "dxf_document", "write_dxf", "svg_text", "write_svg"]
