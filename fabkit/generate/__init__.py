"""Procedural input meshes (paper §2.1 Fig. 3, §3.1): presets and the mesh operations behind them.

- `reflect_panel`: an exactly developable curved-crease panel by the reflection method (ground truth).
- `trifold_panel`: the tri-fold panel of Fig. 3 (steps a–f), a relax input.
- `pleated_vault`: a vault pleated by alternating mountain/valley curved creases (multi-panel input).
- polyhedra (`box`, `cube`, `prism`, `tetrahedron`, `octahedron`, `grid`), Conway operators
  (`ambo`, `truncate`, `chamfer`, `bevel`), `catmull_clark`, and topology edits (`delete_faces`,
  `inset_faces`, `extrude_border_edges`, `dissolve_edges`, `dissolve_vertices`, `edge_loop`,
  `remove_edge_loops`, `compact`).
"""
from fabkit.generate.conway import ambo, bevel, chamfer, truncate, vertex_rings
from fabkit.generate.pleated import pleated_vault
from fabkit.generate.polyhedra import box, cube, grid, octahedron, prism, signed_volume, tetrahedron
from fabkit.generate.reflect import MirrorPlane, grid_faces, reflect_panel
from fabkit.generate.subdivide import (catmull_clark, catmull_clark_operator, catmull_clark_points,
                                       catmull_clark_quads, crease_edges_of)
from fabkit.generate.topology import (compact, delete_faces, dissolve_edges, dissolve_vertices, edge_loop,
                                      extrude_border_edges, inset_faces, remove_edge_loops)
from fabkit.generate.trifold import strip_columns, trifold_network, trifold_panel

__all__ = ["MirrorPlane", "grid_faces", "reflect_panel", "trifold_panel", "pleated_vault", "trifold_network", "strip_columns",
           "box", "cube", "grid", "octahedron", "prism", "signed_volume", "tetrahedron",
           "ambo", "bevel", "chamfer", "truncate", "vertex_rings",
           "catmull_clark", "catmull_clark_operator", "catmull_clark_points", "catmull_clark_quads",
           "crease_edges_of",
           "compact", "delete_faces", "dissolve_edges", "dissolve_vertices", "edge_loop", "extrude_border_edges",
           "inset_faces", "remove_edge_loops"]
